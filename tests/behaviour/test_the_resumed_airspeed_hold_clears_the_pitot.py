"""An engine that quits: for the second before the throttle reaches its stop the airspeed hold
still holds, the airspeed falls, and the pitot is declared beside the engine. When the throttle
leaves its stop the hold takes over again (3 s later). With parts.hold_resume = "cloud" the held
airspeed was then every particle's mean of u + W, the blocked and biased particles' winds
included: 42.5 m/s where the pitot read 40, and the pitot stayed declared for 29 s. With "held"
(the catalogue's) the hold returns to the airspeed it held before the let-go
(`pitot.PitotRow._kappa`, docs/faults.md, "The held airspeed after a let-go").

real-engine run 96 (campaign seed 0), the autopilot on the monitor's estimate as in the campaign,
to 72 s: the engine is out 29.0-38.0 s, the hold takes over again at 43 s."""

from __future__ import annotations

import dataclasses

import numpy as np

from sim_bridge.campaign import fly
from sim_bridge.scenario import load_scenario
from sim_bridge.type_yardstick import item_view, kind_of
from sim_bridge.yardstick import Hysteresis, declared
from tests.helpers.declarations import TRACED_BEFORE_STOP_52

AFTER_S = (48.0, 72.0)


def pitot_declared_after(hold_resume: str) -> np.ndarray:
    """The pitot declared, per frame of AFTER_S (bool)."""
    sc = load_scenario("real-engine")
    parts = dataclasses.replace(sc.estimator.settings, hold_resume=hold_resume, **TRACED_BEFORE_STOP_52)
    est = dataclasses.replace(sc.estimator, settings=parts)
    tr = fly(dataclasses.replace(sc, estimator=est, duration_s=AFTER_S[1]), "RJMRPF", 96, 0)
    P = np.array([o.fault_probability for o in tr.outputs])
    view = item_view(P, [kind_of(f) for f in est.faults], [f.id for f in est.faults])
    on = declared(tr.t, view.prob[:, view.names.index("pitot")], Hysteresis())
    return on[(tr.t >= AFTER_S[0]) & (tr.t <= AFTER_S[1])]


def test_returning_to_the_held_airspeed_the_pitot_clears():
    assert load_scenario("real-engine").estimator.settings.hold_resume == "held"
    assert not pitot_declared_after("held").any()


def test_with_every_particles_airspeed_the_pitot_stays_declared():
    assert pitot_declared_after("cloud").mean() > 0.9
