"""Numerical linearisation at trim and zero-order-hold discretisation (thesis [3.5.2], SPEC section 2)."""

from __future__ import annotations

from dataclasses import dataclass

import control
import numpy as np

from fdir_service.airframe.dynamics import derivatives
from fdir_service.airframe.params import AirframeParams
from fdir_service.airframe.trim import Trim, trim

# The thesis's printed discrete model (eq. 4.25-4.26 / 5.30-5.31), 2-decimal rounding, 20 Hz.
PRINTED_F = np.array(
    [
        [1.0, 0.0, 0.05, -2.0, 0.0],
        [0.0, 0.98, 0.01, -0.48, -0.09],
        [0.0, -0.02, 0.88, -0.02, 1.85],
        [0.0, 0.0, 0.0, 1.0, 0.05],
        [0.0, 0.0, -0.04, 0.0, 0.93],
    ]
)
PRINTED_B = np.array(
    [[0.01, 0.0], [0.08, 1.59], [-1.70, -0.01], [-0.05, 0.0], [-2.09, 0.0]]
)


@dataclass(frozen=True)
class LinearModel:
    """Deviation model about trim: dz_{k+1} = F dz_k + B du_k, dz = z - z*, du = u - u*.

    A (5x5), Bc (5x2) are the continuous Jacobians (None for the printed model); F, B discrete at dt s.
    """

    trim: Trim
    dt: float
    F: np.ndarray
    B: np.ndarray
    A: np.ndarray | None = None
    Bc: np.ndarray | None = None
    source: str = "derived"

    def step(self, z: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Absolute-state step z (..., 5), u (..., 2) -> z_{k+1} (..., 5)."""
        dz = z - self.trim.z
        du = u - self.trim.u
        return self.trim.z + dz @ self.F.T + du @ self.B.T


def jacobians(p: AirframeParams, z0: np.ndarray, u0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Central-difference Jacobians A = df/dz (5x5), B = df/du (5x2) at (z0, u0)."""
    nz, nu = z0.size, u0.size
    A = np.empty((nz, nz))
    B = np.empty((nz, nu))
    for j in range(nz):
        h = 1e-6 * max(1.0, abs(z0[j]))
        dz = np.zeros(nz)
        dz[j] = h
        A[:, j] = (derivatives(z0 + dz, u0, p) - derivatives(z0 - dz, u0, p)) / (2 * h)
    for j in range(nu):
        h = 1e-6 * max(1.0, abs(u0[j]))
        du = np.zeros(nu)
        du[j] = h
        B[:, j] = (derivatives(z0, u0 + du, p) - derivatives(z0, u0 - du, p)) / (2 * h)
    return A, B


def linearize(
    p: AirframeParams, airspeed: float = 40.0, altitude: float = 500.0, dt: float = 0.05
) -> LinearModel:
    """Trim, Jacobians, then ZOH discretisation with python-control's c2d."""
    tr = trim(p, airspeed, altitude)
    A, Bc = jacobians(p, tr.z, tr.u)
    sysd = control.c2d(control.ss(A, Bc, np.eye(5), np.zeros((5, 2))), dt, method="zoh")
    return LinearModel(tr, dt, np.asarray(sysd.A), np.asarray(sysd.B), A, Bc, "derived")


def printed_model(p: AirframeParams, airspeed: float = 40.0, altitude: float = 500.0) -> LinearModel:
    """The thesis's printed F, B (20 Hz) about the trim of p."""
    return LinearModel(trim(p, airspeed, altitude), 0.05, PRINTED_F.copy(), PRINTED_B.copy(),
                       source="printed")


def linear_model(p: AirframeParams, which: str = "derived", airspeed: float = 40.0,
                 altitude: float = 500.0, dt: float = 0.05) -> LinearModel:
    """Select the derived or the thesis's printed discrete model ('derived' | 'printed')."""
    if which == "derived":
        return linearize(p, airspeed, altitude, dt)
    if which == "printed":
        if abs(dt - 0.05) > 1e-12:
            raise ValueError("the printed thesis model exists only at dt = 0.05 s")
        return printed_model(p, airspeed, altitude)
    raise ValueError(f"linear model must be 'derived' or 'printed', got {which!r}")
