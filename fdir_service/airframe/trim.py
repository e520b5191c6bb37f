"""Trim of the longitudinal airframe for straight, wings-level flight (thesis [3.5.1])."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import root

from fdir_service.airframe.dynamics import derivatives
from fdir_service.airframe.params import AirframeParams


@dataclass(frozen=True)
class Trim:
    """A trim point: state z* (5,), input u* (2,), and the residual |f(z*, u*)| (max-abs, SI)."""

    airspeed: float
    altitude: float
    gamma: float
    alpha: float
    z: np.ndarray
    u: np.ndarray
    residual: float

    def as_dict(self) -> dict[str, float]:
        """Trim in readable units (m, m/s, deg, throttle fraction)."""
        return {
            "airspeed_mps": self.airspeed,
            "altitude_m": self.altitude,
            "gamma_deg": float(np.degrees(self.gamma)),
            "alpha_deg": float(np.degrees(self.alpha)),
            "u_mps": float(self.z[1]),
            "w_mps": float(self.z[2]),
            "theta_deg": float(np.degrees(self.z[3])),
            "delta_e_deg": float(np.degrees(self.u[0])),
            "delta_t": float(self.u[1]),
            "residual": self.residual,
        }


def trim(
    p: AirframeParams, airspeed: float = 40.0, altitude: float = 500.0, gamma: float = 0.0
) -> Trim:
    """Solve f(z*, u*) = 0 for (alpha, delta_e, delta_t) at airspeed (m/s), flight-path angle gamma (rad)."""

    def state(alpha: float) -> np.ndarray:
        return np.array(
            [-altitude, airspeed * np.cos(alpha), airspeed * np.sin(alpha), alpha + gamma, 0.0]
        )

    def residual(x: np.ndarray) -> np.ndarray:
        alpha, de, dt = x
        f = derivatives(state(alpha), np.array([de, dt]), p)
        # Steady climb at gamma: u', w', q' vanish (p_d' = -Va sin gamma is the climb itself).
        return f[[1, 2, 4]]

    sol = root(residual, x0=np.array([0.05, -0.08, 0.5]), method="hybr", tol=1e-13)
    if np.max(np.abs(residual(sol.x))) > 1e-9:
        raise RuntimeError(f"trim did not converge: {sol.message}")
    alpha, de, dt = (float(v) for v in sol.x)
    z = state(alpha)
    u = np.array([de, dt])
    res = float(np.max(np.abs(residual(sol.x))))
    return Trim(airspeed, altitude, gamma, alpha, z, u, res)
