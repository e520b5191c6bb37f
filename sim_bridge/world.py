"""The true airframe of a scenario (SPEC sections 2 and 7).

Linear truth: the discrete model dz_{k+1} = F dz_k + B du_k about trim, with the thesis's printed
or the derived F, B (`scenario.truth.linear_matrices`). Nonlinear truth: one classical RK4 step of
`fdir_service.airframe.derivatives` per frame, input held over the frame (zero-order hold).
Both start at the trim of `scenario.truth` (airspeed, altitude, level flight). Actuator faults add
to the commanded input: u_applied = u_cmd + f_a (elevator in rad, throttle as a fraction).

Speed: the nonlinear truth steps with `rk4_step_scalar` (Python floats; equal to `rk4_step` to
~1e-15), and the trim / linear model of a (airframe, trim point, dt) is solved once per process.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from fdir_service.airframe import AirframeParams, trim
from fdir_service.airframe.dynamics import rk4_step_scalar
from fdir_service.airframe.linearize import linear_model
from sim_bridge.scenario import ACTUATORS, Scenario


@lru_cache(maxsize=32)
def _trim(params: AirframeParams, airspeed: float, altitude: float):
    return trim(params, airspeed, altitude)


@lru_cache(maxsize=32)
def _linear(params: AirframeParams, which: str, airspeed: float, altitude: float, dt: float):
    return linear_model(params, which, airspeed, altitude, dt)


def _cached(fn, *args):
    """fn(*args) once per process for hashable args (AirframeParams is frozen); else uncached."""
    try:
        return fn(*args)
    except TypeError:       # unhashable (a parameter set built with array fields)
        return fn.__wrapped__(*args)


class Truth:
    """The true state z (5,) = [p_d, u, w, theta, q] (SI), stepped once per frame of scenario.dt_s."""

    def __init__(self, scenario: Scenario, params: AirframeParams, rng: np.random.Generator) -> None:
        self.scenario = scenario
        self.params = params
        self.rng = rng            # reserved for disturbances (none in the thesis scenarios)
        self.dt = scenario.dt_s
        tc = scenario.truth
        self.kind = tc.model
        if tc.model == "linear":
            self.model = _cached(_linear, params, tc.linear_matrices, tc.airspeed_mps,
                                 tc.altitude_m, self.dt)
            self.trim = self.model.trim
        else:
            self.model = None
            self.trim = _cached(_trim, params, tc.airspeed_mps, tc.altitude_m)
        # Actuator-fault routing: u += A f, A (2, nf).
        self.A = np.zeros((2, len(scenario.faults)))
        self._act: list[tuple[int, int]] = []       # (input index, fault index) of actuator faults
        for j, ch in enumerate(scenario.faults):
            if ch.kind == "actuator":
                self.A[ACTUATORS.index(ch.target), j] = 1.0
                self._act.append((ACTUATORS.index(ch.target), j))
        self.reset()

    def reset(self) -> None:
        """Back to trim."""
        self.z = self.trim.z.copy()
        self.u_applied = self.trim.u.copy()

    def applied_input(self, u_cmd: np.ndarray, fault_values: np.ndarray) -> np.ndarray:
        """The input the airframe feels: u_cmd (2,) plus the actuator faults (SI)."""
        u = np.array(u_cmd, dtype=float)
        for i, j in self._act:
            u[i] += fault_values[j]
        return u

    def step(self, u_cmd: np.ndarray, fault_values: np.ndarray) -> np.ndarray:
        """Advance one frame with u_cmd (2,) and the fault values (nf,) held; returns the new z."""
        u = self.applied_input(u_cmd, fault_values)
        if self.model is not None:
            self.z = self.model.step(self.z, u)
        else:
            self.z = np.array(rk4_step_scalar(self.z.tolist(), u.tolist(), self.dt, self.params))
        self.u_applied = u
        return self.z
