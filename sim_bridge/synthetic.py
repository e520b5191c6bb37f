"""Open-loop synthetic data for the estimators' own checks and benchmark (no simulator needed).

The truth starts at trim and is driven by the trim input (plus any actuator fault): linear truth
with the scenario's truth.linear_matrices, nonlinear truth with RK4 (4 substeps per frame).
Measurements = H_z z + sensor faults + N(0, true sigma^2) (SPEC section 3). Fault values from
`sim_bridge.faults.channel_value` (the simulator's own profiles), in SI.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fdir_service.airframe.dynamics import rk4_step
from fdir_service.airframe.linearize import linear_model
from fdir_service.airframe.params import load_airframe
from fdir_service.estimation.layout import N_AIRFRAME
from fdir_service.estimation.measurement import MEASURED_STATE
from sim_bridge.faults import channel_value
from sim_bridge.scenario import ACTUATORS, Scenario


@dataclass
class SyntheticRun:
    """t (K,), z (K, 5) true airframe state, faults (K, nf) true faults, y (K, m), u (K, 2) input
    commanded (trim), mask (K, m) all True. Row k is the frame at t_k = (k + 1) dt."""

    t: np.ndarray
    z: np.ndarray
    faults: np.ndarray
    y: np.ndarray
    u: np.ndarray
    mask: np.ndarray


def generate(scenario: Scenario, rng: np.random.Generator, steps: int | None = None,
             u: np.ndarray | None = None) -> SyntheticRun:
    """One open-loop run of `scenario` (truth at trim, the scenario's faults).

    u (steps, 2): the commanded input of each frame (default: the trim input throughout).
    Bias faults only: typed faults (`sim_bridge.fault_types`) are flown by `sim_bridge.simulate`.
    """
    typed = [f.id for f in scenario.faults if f.fault_type != "bias"]
    if typed:
        raise ValueError(f"{scenario.id}: open-loop synthetic data knows bias faults only, not {typed}; "
                         "fly typed faults with sim_bridge.simulate")
    p = load_airframe()
    lm = linear_model(p, scenario.truth.linear_matrices, scenario.truth.airspeed_mps,
                      scenario.truth.altitude_m, scenario.dt_s)
    K = scenario.steps if steps is None else int(steps)
    dt = scenario.dt_s
    t = dt * np.arange(1, K + 1)
    nf = len(scenario.faults)
    faults = np.stack([channel_value(f, t) for f in scenario.faults], axis=1) if nf else np.zeros((K, 0))
    u_cmd = np.broadcast_to(lm.trim.u, (K, 2)).copy() if u is None else np.array(u, dtype=float)
    z = np.empty((K, N_AIRFRAME))
    zk = lm.trim.z.copy()
    for k in range(K):
        # the input applied over (t_k - dt, t_k], with the actuator faults in force during it
        ue = u_cmd[k].copy()
        for f in scenario.faults:
            if f.kind == "actuator":
                ue[ACTUATORS.index(f.target)] += channel_value(f, t[k] - dt)
        if scenario.truth.model == "linear":
            zk = lm.step(zk, ue)
        else:
            for _ in range(4):
                zk = rk4_step(zk, ue, dt / 4, p)
        z[k] = zk
    meas = scenario.sensors.measurements
    y = np.empty((K, len(meas)))
    for r, name in enumerate(meas):
        col, coef = MEASURED_STATE[name]
        y[:, r] = coef * z[:, col] + rng.normal(0.0, scenario.sensors.sigma[name], K)
    for j, f in enumerate(scenario.faults):
        if f.kind == "sensor":
            y[:, meas.index(f.target)] += faults[:, j]
    return SyntheticRun(t, z, faults, y, u_cmd, np.ones_like(y, dtype=bool))
