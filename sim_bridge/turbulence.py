"""Dryden turbulence (MIL-F-8785C / MIL-HDBK-1797, low-altitude model) on the longitudinal axes.

Spectra (one-sided, Omega in rad/s of time, V the airspeed, L the scale lengths, b the span):
    H_u(s) = sigma_u sqrt(2 L_u / (pi V)) / (1 + (L_u / V) s)
    H_w(s) = sigma_w sqrt(L_w / (pi V)) (1 + sqrt(3) (L_w / V) s) / (1 + (L_w / V) s)^2
    H_q(s) = (s / V) / (1 + (4 b / (pi V)) s) H_w(s)        (the pitch-rate gust, from w_g)
Intensity and scale lengths below 1000 ft (h in ft, clamped to 10..1000 ft; the handbook's
transition to its medium-altitude table above 1000 ft is not modelled: the 1000-ft values hold):
    sigma_w = 0.1 W20,  sigma_u = sigma_w / (0.177 + 0.000823 h)^0.4,
    L_w = h,  L_u = h / (0.177 + 0.000823 h)^1.2,
W20 the wind at 20 ft (6 m): light 15 kt, moderate 30 kt, severe 45 kt.

The shaping filters are discretised exactly (Van Loan): the state covariance and the
autocorrelation of the samples equal the continuous process's at the sample times, whatever dt.
Draws come from the generator handed in (the truth's own stream: every filter of a run meets the
same gusts), 4 normals per step.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import cholesky, expm

FT = 0.3048
NOISE_INTENSITY = math.pi
"""Two-sided spectral density of the driving white noise that makes sigma^2 = int_0^inf |H|^2."""


def low_altitude(wind_6m_mps: float, altitude_m: float) -> tuple[float, float, float, float]:
    """(sigma_u, sigma_w) m/s and (L_u, L_w) m of the low-altitude model at altitude_m."""
    h = min(max(altitude_m / FT, 10.0), 1000.0)
    k = 0.177 + 0.000823 * h
    sigma_w = 0.1 * wind_6m_mps
    return sigma_w / k**0.4, sigma_w, h / k**1.2 * FT, h * FT


def autocorrelation_u(tau: np.ndarray, sigma: float, L: float, V: float) -> np.ndarray:
    """R_u(tau) = sigma^2 exp(-V |tau| / L)."""
    return sigma**2 * np.exp(-V * np.abs(tau) / L)


def autocorrelation_w(tau: np.ndarray, sigma: float, L: float, V: float) -> np.ndarray:
    """R_w(tau) = sigma^2 (1 - V |tau| / (2 L)) exp(-V |tau| / L)."""
    x = V * np.abs(tau) / L
    return sigma**2 * (1.0 - 0.5 * x) * np.exp(-x)


def discretise(A: np.ndarray, B: np.ndarray, dt: float, intensity: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact discretisation of dx = A x dt + B dW (white noise of `intensity`): (Phi, Qd) by Van Loan."""
    n = A.shape[0]
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n] = -A
    M[:n, n:] = intensity * B @ B.T
    M[n:, n:] = A.T
    E = expm(M * dt)
    Phi = E[n:, n:].T
    Qd = Phi @ E[:n, n:]
    return Phi, 0.5 * (Qd + Qd.T)


def shaping_filters(sigma_u: float, sigma_w: float, L_u: float, L_w: float, V: float, span: float
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Continuous (A (4, 4), B (4, 2), C (3, 4)) of the u, w and q gust filters: state
    [x_u, x_w1, x_w2, z_q], noise [eta_u, eta_w], output [u_g, w_g, q_g]."""
    Tu, Tw, Tq = L_u / V, L_w / V, 4.0 * span / (math.pi * V)
    ku = sigma_u * math.sqrt(2.0 * Tu / math.pi)
    kw = sigma_w * math.sqrt(Tw / math.pi)
    A = np.zeros((4, 4))
    B = np.zeros((4, 2))
    C = np.zeros((3, 4))
    A[0, 0], B[0, 0], C[0, 0] = -1.0 / Tu, 1.0, ku / Tu
    # w: kw (1 + sqrt3 Tw s) / (Tw s + 1)^2 in controllable canonical form
    A[1, 1], A[1, 2] = 0.0, 1.0
    A[2, 1], A[2, 2] = -1.0 / Tw**2, -2.0 / Tw
    B[2, 1] = 1.0
    cw = np.array([kw / Tw**2, kw * math.sqrt(3.0) / Tw])
    C[1, 1:3] = cw
    # q: (s / V) / (1 + Tq s) w_g = (w_g - z) / (V Tq), z' = (w_g - z) / Tq
    A[3, 1:3] = cw / Tq
    A[3, 3] = -1.0 / Tq
    C[2, 1:3] = cw / (V * Tq)
    C[2, 3] = -1.0 / (V * Tq)
    return A, B, C


class Dryden:
    """Samples (u_g, w_g, q_g) (m/s, m/s, rad/s, body axes) every dt (s), from the stationary state.

    wind_6m_mps: W20 (m/s); altitude_m, airspeed_mps: where the spectra are evaluated; span_m: b.
    """

    def __init__(self, wind_6m_mps: float, altitude_m: float, airspeed_mps: float, span_m: float,
                 dt: float, rng: np.random.Generator) -> None:
        self.sigma_u, self.sigma_w, self.L_u, self.L_w = low_altitude(wind_6m_mps, altitude_m)
        self.V = airspeed_mps
        A, B, self.C = shaping_filters(self.sigma_u, self.sigma_w, self.L_u, self.L_w, airspeed_mps, span_m)
        self.Phi, Qd = discretise(A, B, dt, NOISE_INTENSITY)
        self._G = cholesky(Qd + 1e-30 * np.eye(4), lower=True)
        P = _stationary(self.Phi, Qd)
        self.rng = rng
        self.x = cholesky(P + 1e-30 * np.eye(4), lower=True) @ rng.standard_normal(4)

    def step(self) -> np.ndarray:
        """The next sample (3,) [u_g, w_g, q_g]."""
        self.x = self.Phi @ self.x + self._G @ self.rng.standard_normal(4)
        return self.C @ self.x


def _stationary(Phi: np.ndarray, Qd: np.ndarray) -> np.ndarray:
    """P = Phi P Phi^T + Qd (the discrete Lyapunov equation)."""
    from scipy.linalg import solve_discrete_lyapunov

    return solve_discrete_lyapunov(Phi, Qd)
