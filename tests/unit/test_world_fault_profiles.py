"""Fault profiles give the specified values at their key times (scenario.py ProfileComponent)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim_bridge.faults import channel_value, fault_vector
from sim_bridge.scenario import FaultChannel, ProfileComponent, load_scenario

DEG = math.pi / 180.0


def _ch(*comps, target="theta"):
    return FaultChannel("f", target, "sensor", "rad", tuple(comps))


def test_step():
    ch = _ch(ProfileComponent("step", 10.0, 20.0, 2.5))
    for t, v in [(0.0, 0.0), (9.95, 0.0), (10.0, 2.5), (15.0, 2.5), (19.95, 2.5), (20.0, 0.0), (30.0, 0.0)]:
        assert channel_value(ch, t) == pytest.approx(v, abs=1e-15), t


def test_step_edges_on_frame_times():
    # t = k * dt lands on 10 s and 20 s up to rounding; the edges must fall on the intended side.
    ch = _ch(ProfileComponent("step", 10.0, 20.0, 1.0))
    t = np.arange(1000) * 0.05
    v = channel_value(ch, t)
    on = np.flatnonzero(v)
    assert (on[0], on[-1], on.size) == (200, 399, 200)


def test_exponential_is_amplitude_exp_t_minus_end():
    # The thesis's 10 e^(t-40) deg on 30-40 s.
    ch = _ch(ProfileComponent("exponential", 30.0, 40.0, 10.0 * DEG, tau_s=1.0))
    assert channel_value(ch, 29.95) == 0.0
    assert channel_value(ch, 30.0) == pytest.approx(10.0 * DEG * math.exp(-10.0))
    assert channel_value(ch, 39.0) == pytest.approx(10.0 * DEG * math.exp(-1.0))
    assert channel_value(ch, 39.95) == pytest.approx(10.0 * DEG * math.exp(-0.05))
    assert channel_value(ch, 40.0) == 0.0
    ch2 = _ch(ProfileComponent("exponential", 30.0, 40.0, 1.0, tau_s=2.0))
    assert channel_value(ch2, 38.0) == pytest.approx(math.exp(-1.0))


def test_ramp():
    ch = _ch(ProfileComponent("ramp", 30.0, 40.0, 10.0 * DEG))
    assert channel_value(ch, 29.9) == 0.0
    assert channel_value(ch, 30.0) == pytest.approx(0.0, abs=1e-12)
    assert channel_value(ch, 35.0) == pytest.approx(5.0 * DEG)
    assert channel_value(ch, 39.95) == pytest.approx(9.95 * DEG)
    assert channel_value(ch, 40.0) == 0.0


def test_intermittent():
    ch = _ch(ProfileComponent("intermittent", 10.0, 20.0, 3.0, on_s=1.0, off_s=2.0))
    expect = {9.9: 0.0, 10.0: 3.0, 10.95: 3.0, 11.0: 0.0, 12.95: 0.0, 13.0: 3.0, 13.5: 3.0, 14.0: 0.0,
              19.0: 3.0, 19.95: 3.0, 20.0: 0.0, 22.0: 0.0}
    for t, v in expect.items():
        assert channel_value(ch, t) == v, t
    # On a 20 Hz grid the on-fraction is on / (on + off) = 1/3 ... within the 10 s window: 4 bursts.
    t = np.arange(1000) * 0.05
    assert np.count_nonzero(channel_value(ch, t)) == 4 * 20


def test_sum_of_components():
    ch = _ch(ProfileComponent("step", 10.0, 30.0, 1.0), ProfileComponent("ramp", 20.0, 40.0, 4.0))
    assert channel_value(ch, 15.0) == pytest.approx(1.0)
    assert channel_value(ch, 25.0) == pytest.approx(1.0 + 1.0)
    assert channel_value(ch, 35.0) == pytest.approx(3.0)
    t = np.array([[15.0, 25.0], [35.0, 45.0]])
    assert channel_value(ch, t) == pytest.approx(np.array([[1.0, 2.0], [3.0, 0.0]]))


@pytest.mark.parametrize("sid,t,expect", [
    ("ch4", 5.0, [0.0, 0.0]), ("ch4", 15.0, [50.0, 0.0]), ("ch4", 25.0, [50.0, 30.0]),
    ("ch4", 35.0, [0.0, 30.0]), ("ch4", 45.0, [0.0, 0.0]),
    ("ch5a", 15.0, [5.0 * DEG]), ("ch5a", 25.0, [0.0]), ("ch5a", 39.95, [10.0 * DEG * math.exp(-0.05)]),
    ("ch5b", 15.0, [50.0 * DEG]), ("ch5b", 39.95, [100.0 * DEG * math.exp(-0.05)]),
    ("ch5c", 15.0, [10.0 * DEG, 0.0]), ("ch5c", 25.0, [10.0 * DEG, 10.0 * DEG]),
    ("ch5c", 35.0, [0.0, 10.0 * DEG]), ("ch5c", 40.0, [0.0, 0.0]),
    ("ch6", 10.0, [10.0 * DEG]), ("ch6", 35.0, [5.0 * DEG]), ("ch6", 20.0, [0.0]),
])
def test_scenario_fault_vector(sid, t, expect):
    assert fault_vector(load_scenario(sid), t) == pytest.approx(np.array(expect), abs=1e-12)
