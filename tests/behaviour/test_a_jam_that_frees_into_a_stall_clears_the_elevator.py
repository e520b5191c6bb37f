"""A jammed elevator that frees with its command on the stop pitches the aircraft past the stall
(40 deg of angle of attack). There the lift no longer reads the angle of attack, and a moment read
from it is ~1400 deg/s^2 off: an elevator fault of some type explained the gap and stood for
seconds after the jam. With parts.moment_alpha = "stall_blend" (the catalogue's) the moment takes
the velocity's angle of attack and airspeed past the stall, and the pitch rate the tail's noise
(`kinematic.PitchMoment`, docs/faults.md, "Past the stall").

real-actuators run 76 (campaign seed 0), the autopilot on the monitor's estimate as in the
campaign, to 114 s: the second jam holds the elevator 101.4-107.3 s; the yardstick's grace ends
3 s later."""

from __future__ import annotations

import dataclasses

import numpy as np

from sim_bridge.campaign import fly
from sim_bridge.scenario import load_scenario
from sim_bridge.type_yardstick import item_view, kind_of
from sim_bridge.yardstick import Hysteresis, declared

JAM_END_S, GRACE_END_S = 107.3, 110.3


def elevator_cleared(moment_alpha: str) -> float:
    """When the elevator's declaration of the second jam clears (s)."""
    sc = load_scenario("real-actuators")
    est = dataclasses.replace(sc.estimator,
                              settings=dataclasses.replace(sc.estimator.settings, moment_alpha=moment_alpha))
    tr = fly(dataclasses.replace(sc, estimator=est, duration_s=114.0), "RJMRPF", 76, 0)
    P = np.array([o.fault_probability for o in tr.outputs])
    view = item_view(P, [kind_of(f) for f in est.faults], [f.id for f in est.faults])
    on = declared(tr.t, view.prob[:, view.names.index("de")], Hysteresis())
    during = np.flatnonzero(tr.t >= JAM_END_S)
    assert on[during[0]]                                  # declared as the jam ends
    return float(tr.t[during[np.argmin(on[during])]]) if not on[during].all() else float("inf")


def test_the_catalogues_stall_blend_clears_the_elevator_within_the_grace():
    assert load_scenario("real-actuators").estimator.settings.moment_alpha == "stall_blend"
    assert elevator_cleared("stall_blend") < GRACE_END_S


def test_with_the_lift_read_alone_the_elevator_stands_past_the_grace():
    assert elevator_cleared("lift") > GRACE_END_S + 1.0
