"""The catalogue estimator (config/estimators/aerosonde-catalogue.toml) in moderate turbulence, on a
flight that climbs at 3 m/s from 20 s: a sensor that sticks is declared stuck, not biased, and the
service names no other type for it first; a sensor
whose noise triples is declared noisy with k about right; the climb alone raises nothing. The
sensor faults are put on the recorded rows after the flight (the autopilot flew on a healthy
navigation), with the service's declare hysteresis."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from fdir_service.estimation.factory import build_filter
from fdir_service.estimator_config import load_estimator
from fdir_service.mavlink import new_mavlink
from fdir_service.runtime.frames import AssembledFrame
from fdir_service.runtime.publishing import Publisher
from fdir_service.service_config import load_service_config
from sim_bridge.campaign import _first_frame_start
from sim_bridge.scenario import AltitudeStep, load_scenario
from sim_bridge.simulate import run as simulate
from sim_bridge.type_yardstick import item_view, kind_of
from sim_bridge.yardstick import Hysteresis, declared

ONSET_S, END_S = 24.0, 36.0


@pytest.fixture(scope="module")
def climb():
    """(scenario, trajectory, estimator rows): 40 s in moderate turbulence, climbing from 20 s."""
    est = load_estimator("aerosonde-catalogue")
    sc = load_scenario("real-turbulence-faultfree")
    command = dataclasses.replace(sc.command, altitude_steps=(AltitudeStep(20.0, 560.0),),
                                  climb_rate_mps=3.0)
    sc = dataclasses.replace(sc, estimator=est, command=command)
    tr = simulate(sc, 3, seconds=40.0)
    rows = sc.estimator_rows()
    return sc, tr, tr.y[:, rows].copy(), tr.mask[:, rows] & (rows >= 0)


def outputs(sc, tr, y, mask, seed: int = 1) -> list:
    """The catalogue's step outputs (K,) on rows y, mask (K, m), its filter drawn from `seed`."""
    def new(x0=None):
        kw = {} if x0 is None else {"x0": x0}
        return build_filter("RJMRPF", sc.estimator, np.random.default_rng(seed), **kw)

    filt = _first_frame_start(sc, new)(y[0], mask[0])
    return [filt.step(tr.t[k], y[k], mask[k], tr.u[k]) for k in range(len(tr.t))]


def monitor(sc, tr, y, mask, seed: int = 1):
    """(declared (K, nf) bool by the service's hysteresis, fault_value (K, nf)) of the catalogue,
    its filter drawn from `seed`."""
    outs = outputs(sc, tr, y, mask, seed)
    P = np.array([o.fault_probability for o in outs])
    dec = np.stack([declared(tr.t, P[:, j], Hysteresis()) for j in range(P.shape[1])], axis=1)
    return dec, np.array([o.fault_value for o in outs])


def during(t: np.ndarray) -> np.ndarray:
    return (t >= ONSET_S) & (t < END_S)


def ids_declared(sc, dec: np.ndarray, when: np.ndarray) -> set[str]:
    return {f.id for j, f in enumerate(sc.estimator.faults) if dec[when, j].any()}


def test_the_climb_alone_raises_nothing(climb):
    sc, tr, y, mask = climb
    dec, _ = monitor(sc, tr, y, mask)
    assert ids_declared(sc, dec, tr.t > 2.0) == set()


def test_a_stuck_attitude_sensor_in_a_climb_is_declared_within_3_s_and_nothing_else(climb):
    """By item, as the service declares (P(theta) over its types, the declare hysteresis; the type it
    names is the next test's): declared within 3 s, standing through the fault, no other item."""
    sc, tr, y, mask = climb
    on = during(tr.t)
    y = stuck_attitude(sc, tr, y)
    P = np.array([o.fault_probability for o in outputs(sc, tr, y, mask)])
    view = item_view(P, [kind_of(f) for f in sc.estimator.faults], [f.id for f in sc.estimator.faults])
    dec = np.stack([declared(tr.t, view.prob[:, i], Hysteresis()) for i in range(len(view.targets))], axis=1)
    theta = view.targets.index("theta")
    assert tr.t[np.flatnonzero(dec[:, theta] & on)[0]] - ONSET_S < 3.0
    assert dec[on & (tr.t > ONSET_S + 3.0), theta].mean() > 0.9
    assert {view.targets[i] for i in np.flatnonzero(dec[on].any(axis=0))} == {"theta"}


def stuck_attitude(sc, tr, y) -> np.ndarray:
    """Rows y with the attitude sensor stuck (its last reading, 0.01 rad of noise) during the fault."""
    j = sc.estimator.measurements.index("theta")
    on = during(tr.t)
    y = y.copy()
    y[on, j] = y[np.flatnonzero(on)[0] - 1, j] + 0.01 * np.random.default_rng(0).standard_normal(on.sum())
    return y


def service_texts(sc, tr, y, mask, outs, p_type: float) -> list[tuple[float, str]]:
    """(frame time s, STATUSTEXT) of each declaration change the service's publisher makes of
    the step outputs outs, its `[publish.declare] p_type` set."""
    cfg = load_service_config().publish
    cfg = dataclasses.replace(cfg, declare=dataclasses.replace(cfg.declare, p_type=p_type))
    pub = Publisher(cfg, sc.estimator.faults, new_mavlink(1, 191), adaptive=False)
    frames = (AssembledFrame(k, int(round(tr.t[k] * 1e6)), y[k], mask[k], tr.u[k]) for k in range(len(outs)))
    return [(e.time_s, e.statustext)
            for fr, o in zip(frames, outs, strict=True) for e in pub.publish(fr, o)[1]]


def test_a_stuck_attitude_sensor_is_named_stuck_after_at_most_a_short_drift(climb):
    """A young stuck reading is also a young ramp or an offset: the service says "type unclear"
    until a type holds 0.8 of P(theta). The held value was once its sentinel's draw from one noisy
    reading while a drift's level is corrected, so a drift often took the first second (named first
    in 2 of these 8 filters on one BLAS thread, 6 of 7 on two, on an AMD EPYC with AVX2: the floating
    point's last bits send the clouds apart). Since parts.held_value = "mean" (`held_mean.py`) the
    held value is the mean of the readings since the sensor stuck: a drift was named first in none
    of the 8 on either path, stuck first in 3 (one thread) and 5 (two), the rest "type unclear"
    first; stuck named 1.2-2.4 s after the onset (median 1.9 s on one thread, 1.25 s on two).
    Since the catalogue learns its pitch-rate noise and integrates the frame's mean a_z (stop 44) a
    drift is named first in 2 of the 8 (seeds 2 and 5, for 0.85 and 0.95 s), stuck named 1.25-2.3 s
    after the onset. Asserted with room for other paths: declared within 3.5 s, stuck named within
    5 s (median under 3 s), a drift named first in at most 2 of 8 and then for under 2 s, nothing
    but stuck after it."""
    sc, tr, y, mask = climb
    y = stuck_attitude(sc, tr, y)
    named_s, drift_first = [], 0
    for seed in range(1, 9):
        texts = [(t, s) for t, s in service_texts(sc, tr, y, mask, outputs(sc, tr, y, mask, seed), 0.8)
                 if s.startswith("FDIR theta ") and t > ONSET_S]
        assert texts and texts[0][0] < ONSET_S + 3.5, (seed, texts)
        named = [t for t, s in texts if s.startswith("FDIR theta stuck at")]
        assert named and named[0] < ONSET_S + 5.0, (seed, texts)
        before = [s for t, s in texts if t < named[0]]
        assert all(s.startswith(("FDIR theta drift", "FDIR theta fault, type unclear")) for s in before), \
            (seed, texts)
        assert named[0] - texts[0][0] < 2.0 or not any("drift" in s for s in before), (seed, texts)
        after = [s for t, s in texts if t > named[0]]
        assert all(s.startswith(("FDIR theta stuck", "FDIR theta cleared")) for s in after), (seed, texts)
        named_s.append(named[0] - ONSET_S)
        drift_first += texts[0][1].startswith("FDIR theta drift")
    assert np.median(named_s) < 3.0, np.round(named_s, 2)
    assert drift_first <= 2


def test_a_barometer_whose_noise_triples_is_declared_noisy_with_its_k(climb):
    """Eight filters and noise draws on the same climb: one draw's delay says little (12 draws at
    360c8f4: 0.25-2.25 s, median 0.9 s; the first was 1.25 s before the pitot's hold, 2.25 s after,
    the others within 0.35 s of before), so the delay is judged at the median."""
    sc, tr, y0, mask = climb
    j = sc.estimator.measurements.index("baro_alt")
    on = during(tr.t)
    true_sigma = sc.sensors.sigma["baro_alt"]
    k_true = 3.0 * true_sigma / sc.estimator.sigma[j]       # k is against the assumed noise
    noisy = [f.id for f in sc.estimator.faults].index("baro_nz")
    delays, k_est = [], []
    for seed in range(1, 9):
        y = y0.copy()
        y[on, j] += np.sqrt(8.0) * true_sigma * np.random.default_rng(seed - 1).standard_normal(on.sum())
        dec, value = monitor(sc, tr, y, mask, seed)
        hits = np.flatnonzero(dec[:, noisy] & on)
        assert hits.size and tr.t[hits[0]] - ONSET_S < 3.0, f"seed {seed}: not declared within 3 s"
        assert ids_declared(sc, dec, on) <= {"baro_nz"}, f"seed {seed}: {ids_declared(sc, dec, on)}"
        delays.append(tr.t[hits[0]] - ONSET_S)
        k_est.append(np.median(value[on & (tr.t > ONSET_S + 3.0), noisy]))
    assert np.median(delays) < 2.0, f"delays {np.round(delays, 2)}"
    assert abs(np.median(k_est) - k_true) < 0.5, f"k {np.round(k_est, 2)} against {k_true:.2f}"


def test_an_attitude_ramp_is_named_a_drift_and_seldom_anything_else(climb):
    """A 0.5 deg/s attitude ramp (either sign, 8 filter seeds) is declared within 9 s; it is named
    a drift within 10 s in at least 12 of the 16, and another type in at most 1. With the drift
    handing over to the bias and the stuck entries at 0.01 a step, as often as they hand over to
    it, the pair kept about half of P(theta) and the drift was named on 3 of 8 (docs/faults.md,
    "Hand-overs out of a drift"). Until stop 48 this test flew seeds 1-4 and asked for no other
    type at all. On seeds 1-8 the catalogue of stop 47 named a drift in 15 of the 16 (one "type
    unclear" throughout) and 2 of those drifts were handed on (-0.5 deg/s, seeds 5 and 6: a drift
    at +0.02 deg/s, then stuck; a drift, then an offset); stop 48's (the moment's fault-free wind)
    named a drift in all 16, and 1 was handed on (-0.5 deg/s, seed 1: +0.01 deg/s, then stuck at
    34.9 s). A young ramp whose rate is proposed
    near zero reads as a held value; which seeds it hits moves with any change of the cloud's
    random stream."""
    sc, tr, y, mask = climb
    j = sc.estimator.measurements.index("theta")
    on = during(tr.t)
    named, other = 0, 0
    for rate, seed in [(r, s) for r in (0.5, -0.5) for s in range(1, 9)]:
        ramp = y.copy()
        ramp[on, j] += np.radians(rate) * (tr.t[on] - ONSET_S)
        texts = [(t, s) for t, s in service_texts(sc, tr, ramp, mask, outputs(sc, tr, ramp, mask, seed), 0.8)
                 if s.startswith("FDIR theta ") and "cleared" not in s]
        assert texts and texts[0][0] < ONSET_S + 9.0, (rate, seed, texts)
        kinds = [(t, s) for t, s in texts if "type unclear" not in s]
        other += any(not s.startswith("FDIR theta drift") for _, s in kinds)
        named += any(s.startswith("FDIR theta drift") and t < ONSET_S + 10.0 for t, s in kinds)
    assert named >= 12 and other <= 1, (named, other)
