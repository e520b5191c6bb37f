"""Nonlinear longitudinal Aerosonde equations of motion (SPEC section 2, thesis [3.2]-[3.5]).

Vectorised over leading axes: z has shape (..., 5) = [p_d, u, w, theta, q] and u has shape
(..., 2) = [delta_e rad, delta_t 0..1]; the result has the shape of z. No wind, so Va = |(u, w)|.
"""

from __future__ import annotations

import numpy as np

from fdir_service.airframe.params import AirframeParams

STATE_NAMES = ("p_d", "u", "w", "theta", "q")
INPUT_NAMES = ("delta_e", "delta_t")


def lift_drag(alpha: np.ndarray, p: AirframeParams) -> tuple[np.ndarray, np.ndarray]:
    """C_L and C_D at angle of attack alpha (rad): stall-blended lift, quadratic drag."""
    e_minus = np.exp(np.clip(-p.M * (alpha - p.alpha0), -700.0, 700.0))
    e_plus = np.exp(np.clip(p.M * (alpha + p.alpha0), -700.0, 700.0))
    sigma = (1.0 + e_minus + e_plus) / ((1.0 + e_minus) * (1.0 + e_plus))
    cl_lin = p.C_L0 + p.C_La * alpha
    sa = np.sin(alpha)
    cl = (1.0 - sigma) * cl_lin + sigma * (2.0 * np.sign(alpha) * sa * sa * np.cos(alpha))
    cd = p.C_Dp + cl_lin**2 / (np.pi * p.e * p.AR)
    return cl, cd


def derivatives(z: np.ndarray, u: np.ndarray, p: AirframeParams) -> np.ndarray:
    """dz/dt for state z (..., 5) and input u (..., 2); SI units."""
    z = np.asarray(z, dtype=float)
    u = np.asarray(u, dtype=float)
    ub, wb, th, q = z[..., 1], z[..., 2], z[..., 3], z[..., 4]
    de, dt = u[..., 0], u[..., 1]
    va = np.sqrt(ub * ub + wb * wb)
    va_safe = np.maximum(va, 1e-3)
    alpha = np.arctan2(wb, ub)
    ca, sa = np.cos(alpha), np.sin(alpha)
    cl, cd = lift_drag(alpha, p)
    # Body-axis force coefficients (SPEC section 2).
    cx = -cd * ca + cl * sa
    cxq = -p.C_Dq * ca + p.C_Lq * sa
    cxde = -p.C_Dde * ca + p.C_Lde * sa
    cz = -cd * sa - cl * ca
    czq = -p.C_Dq * sa - p.C_Lq * ca
    czde = -p.C_Dde * sa - p.C_Lde * ca
    qbar_m = p.rho * va * va * p.S / (2.0 * p.m)
    qc = p.c * q / (2.0 * va_safe)
    thrust = p.rho * p.S_prop * p.C_prop / (2.0 * p.m) * ((p.k_motor * dt) ** 2 - va * va)
    sth, cth = np.sin(th), np.cos(th)
    out = np.empty(np.broadcast_shapes(z.shape, u.shape[:-1] + (5,)))
    out[..., 0] = -sth * ub + cth * wb
    out[..., 1] = -q * wb - p.g * sth + qbar_m * (cx + cxq * qc + cxde * de) + thrust
    out[..., 2] = q * ub + p.g * cth + qbar_m * (cz + czq * qc + czde * de)
    out[..., 3] = q
    out[..., 4] = (
        p.rho * va * va * p.S * p.c / (2.0 * p.Jy)
        * (p.C_m0 + p.C_ma * alpha + p.C_mq * qc + p.C_mde * de)
    )
    return out


def rk4_step(z: np.ndarray, u: np.ndarray, dt: float, p: AirframeParams) -> np.ndarray:
    """One classical Runge-Kutta step of length dt (s) with the input held (zero-order hold)."""
    k1 = derivatives(z, u, p)
    k2 = derivatives(z + 0.5 * dt * k1, u, p)
    k3 = derivatives(z + 0.5 * dt * k2, u, p)
    k4 = derivatives(z + dt * k3, u, p)
    return z + (dt / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
