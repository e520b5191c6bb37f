"""An attitude sensor that drifts at 0.5 deg/s for 20 s, in moderate turbulence: the robust monitor
with drift entries (config/estimators/aerosonde-drift.toml: `th_dr`, type "drift", beside the
attitude's bias) declares it no later and follows the ramp as closely as the robust monitor with its
bias entry only (aerosonde-robust.toml), and reads its rate. The ramp is put on the recorded rows
after the flight (the autopilot flew on a healthy navigation), with the service's declare
hysteresis; six flights (one flight's rate read is 0.3-0.8 deg/s: the test takes their median)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from fdir_service.estimation.factory import build_filter
from fdir_service.estimator_config import load_estimator
from sim_bridge.campaign import _first_frame_start
from sim_bridge.scenario import load_scenario
from sim_bridge.simulate import run as simulate
from sim_bridge.yardstick import Hysteresis, declared

ONSET_S, END_S = 15.0, 35.0
RATE = np.deg2rad(0.5)                   # rad/s
SEEDS = (0, 1, 2, 3, 4, 5)


def estimator(drift: bool):
    """config/estimators/aerosonde-drift.toml (drift entries beside the barometer's and the
    attitude's bias, type hand-overs), else aerosonde-robust.toml (bias entries only)."""
    return load_estimator("aerosonde-drift" if drift else "aerosonde-robust")


@pytest.fixture(scope="module")
def flights():
    """Per seed (time (K,), rows y (K, m), mask, inputs, truth (K,) the ramp in rad)."""
    sc = dataclasses.replace(load_scenario("real-turbulence-faultfree"), estimator=estimator(True))
    out = []
    for seed in SEEDS:
        tr = simulate(sc, seed, seconds=40.0)
        rows = sc.estimator_rows()
        y, mask = tr.y[:, rows].copy(), tr.mask[:, rows] & (rows >= 0)
        truth = np.where((tr.t >= ONSET_S) & (tr.t < END_S), RATE * (tr.t - ONSET_S), 0.0)
        y[:, sc.estimator.measurements.index("theta")] += truth
        out.append((sc, tr, y, mask, truth))
    return out


def monitor(sc, tr, y, mask, drift: bool) -> dict:
    """Declaration delay (s), offset RMSE over the ramp from 3 s after onset (deg), the rate read
    while drift is the item's most probable type (deg/s, median), items declared elsewhere."""
    est = estimator(drift)
    sc = dataclasses.replace(sc, estimator=est)

    def new(x0=None):
        return build_filter("RJMRPF", est, np.random.default_rng(1), **({} if x0 is None else {"x0": x0}))

    filt = _first_frame_start(sc, new)(y[0], mask[0])
    outs = [filt.step(tr.t[k], y[k], mask[k], tr.u[k]) for k in range(len(tr.t))]
    ids = [f.id for f in est.faults]
    item = [ids.index("theta")] + ([ids.index("th_dr")] if drift else [])
    P = np.array([o.fault_probability for o in outs])
    on = (tr.t >= ONSET_S) & (tr.t < END_S)
    dec = declared(tr.t, np.minimum(P[:, item].sum(axis=1), 1.0), Hysteresis())
    offset = np.array([o.fault_estimate[item].sum() for o in outs])
    truth = np.where(on, RATE * (tr.t - ONSET_S), 0.0)
    late = on & (tr.t >= ONSET_S + 3.0)
    others = {ids[j]: declared(tr.t, P[:, j], Hysteresis()) & (tr.t > 2.0)
              for j in range(len(ids)) if j not in item}
    result = {"delay": tr.t[np.flatnonzero(dec & on)[0]] - ONSET_S if (dec & on).any() else np.inf,
              "rmse": np.rad2deg(np.sqrt(np.mean((offset[late] - truth[late]) ** 2))),
              "others": {f"{i}@{tr.t[np.flatnonzero(d)[0]]:.1f}s" for i, d in others.items() if d.any()}}
    if drift:
        j = ids.index("th_dr")
        read = late & (tr.t >= ONSET_S + 8.0) & (P[:, j] > P[:, item[0]])
        result["rate"] = np.rad2deg(np.median([outs[k].fault_value[j] for k in np.flatnonzero(read)]))
        result["p_drift"] = float(P[late, j].mean())
    return result


def test_a_drifting_attitude_is_declared_sooner_and_tracked_closer_with_a_drift_entry(flights):
    bias = [monitor(*f[:4], drift=False) for f in flights]
    drift = [monitor(*f[:4], drift=True) for f in flights]
    for seed, b, d in zip(SEEDS, bias, drift, strict=True):
        print(f"seed {seed}: bias only: delay {b['delay']:.2f} s, offset RMSE {b['rmse']:.2f} deg; "
              f"bias + drift: delay {d['delay']:.2f} s, RMSE {d['rmse']:.2f} deg, rate "
              f"{d['rate']:.2f} deg/s (truth 0.50), P(drift) {d['p_drift']:.2f}; also declared: "
              f"{sorted(b['others'])} / {sorted(d['others'])}")
    for d in drift:
        assert d["delay"] < 8.0
    # the ramp leaks into the altitude the attitude integrates: a barometer item is sometimes
    # declared beside it (bias only: 2 of 6 flights here): no more with the drift entries
    assert sum(len(d["others"]) for d in drift) <= sum(len(b["others"]) for b in bias)
    rate = np.median([d["rate"] for d in drift])
    print(f"median rate read over the flights {rate:.2f} deg/s")
    assert abs(rate - 0.5) < 0.3 * 0.5           # one flight's read is within 0.3-0.8 deg/s
    # the robust monitor's attitude parts (fold_after, theta's pi01 = 0.003, sentinel_clip;
    # aerosonde-drift has them too) brought the bias entry alone from a mean RMSE of 1.67 to
    # 0.73 deg (0.72 with its gain from within each hypothesis); the drift entry's is 0.51
    # (aerosonde-drift keeps the cloud's gain: with the other, 0.94)
    # (docs/faults.md, "The drift kind")
    assert np.mean([d["rmse"] for d in drift]) < 1.1 * np.mean([b["rmse"] for b in bias])
    assert np.mean([d["delay"] for d in drift]) <= np.mean([b["delay"] for b in bias]) + 0.5
