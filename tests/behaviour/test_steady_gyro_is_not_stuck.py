"""A gyro that reads steady for a few frames in ordinary flight is not a stuck gyro: the catalogue
estimator, its pitch-rate noise learnt from the flight (parts.q_noise = "learned", not yet its default;
fdir_service/estimation/pitch_noise.py), raises nothing in the first 40 s of real-catalogue-faultfree
run 4 (campaign seed 0, the autopilot on the truth), where with the configured noise fixed the
gyro's stuck entry took the cloud in the steady pitch at 37 s and the gyro was declared
(stop 42's false alarms; docs/faults.md, "The pitch-rate noise the flight shows")."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from sim_bridge.campaign import fly
from sim_bridge.scenario import load_scenario
from sim_bridge.type_yardstick import item_view, kind_of
from sim_bridge.yardstick import Hysteresis, declared


def declared_items(q_noise: str) -> dict[str, float]:
    """{item: first declaration time (s)} over the first 40 s of the flight, by the service's rule."""
    sc = load_scenario("real-catalogue-faultfree")
    est = sc.estimator
    est = dataclasses.replace(est, settings=dataclasses.replace(est.settings, q_noise=q_noise))
    sc = dataclasses.replace(sc, estimator=est, navigation="truth", duration_s=40.0)
    tr = fly(sc, "RJMRPF", 4, 0)
    P = np.array([o.fault_probability for o in tr.outputs])
    view = item_view(P, [kind_of(f) for f in est.faults], [f.id for f in est.faults])
    found = {}
    for i, item in enumerate(view.names):
        k = np.flatnonzero(declared(tr.t, view.prob[:, i], Hysteresis()))
        if k.size:
            found[item] = float(tr.t[k[0]])
    return found


@pytest.mark.parametrize("q_noise", ["learned", "fixed"])
def test_a_steady_pitch_raises_nothing_once_the_pitch_noise_is_learnt(q_noise):
    found = declared_items(q_noise)
    if q_noise == "learned":
        assert found == {}
    else:                              # the contrast: the same flight with the configured noise
        assert set(found) == {"q"} and 37.0 < found["q"] < 38.0
