"""Regularisation with the Epanechnikov kernel (thesis [2.5.6.3], Alg. 2.7, eq. 2.60-2.64).

After resampling, x_i <- x_i + h D eps_i with D D^T = P (the weighted covariance of the cloud
before resampling) and eps_i ~ Epanechnikov kernel on the unit ball of R^n, density
prop. to 1 - |x|^2. Bandwidth h = k h_opt, h_opt = A N^(-1/(n+4)),
A = [8 c_n^-1 (n+4) (2 sqrt(pi))^n]^(1/(n+4)), c_n the unit-ball volume.

Sampler (SPEC section 5): eps = r u with u uniform on the unit sphere and r^2 ~ Beta(n/2, 2).
With g ~ N(0, I_n) (so u = g/|g| and |g|^2/2 ~ Gamma(n/2), independent of u) and
G ~ Gamma(2) = -log(U1 U2), r^2 = (|g|^2/2) / (|g|^2/2 + G) is Beta(n/2, 2), hence
eps = g / sqrt(|g|^2 + 2 G): n normals, two uniforms and one log per particle, no Beta draw.
E r^2 = n/(n+4), so Cov(eps) = I/(n+4).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg.lapack import dpotrf


def unit_ball_volume(n: int) -> float:
    """c_n = pi^(n/2) / Gamma(n/2 + 1)."""
    return math.pi ** (n / 2) / math.gamma(n / 2 + 1)


def h_opt(n: int, N: int) -> float:
    """Optimal Epanechnikov bandwidth for a Gaussian target (eq. 2.63-2.64, k = 1)."""
    A = (8.0 / unit_ball_volume(n) * (n + 4) * (2.0 * math.sqrt(math.pi)) ** n) ** (1.0 / (n + 4))
    return A * N ** (-1.0 / (n + 4))


def bandwidth(k: float, n: int, N: int) -> float:
    """h = k h_opt (the thesis uses k = 0.2: n = 7 -> 0.3115, n = 6 -> 0.2817 at N = 1000)."""
    return k * h_opt(n, N)


def epanechnikov(rng: np.random.Generator, n: int, N: int) -> np.ndarray:
    """N draws (n, N) from the Epanechnikov kernel on the unit ball of R^n (mean 0, Cov I/(n+4))."""
    g = rng.standard_normal((n, N))
    uv = rng.random((2, N))
    uv[0] *= uv[1]
    two_gamma2 = np.log(uv[0])
    two_gamma2 *= -2.0                                        # 2 G, G ~ Gamma(2)
    two_gamma2 += np.einsum("ij,ij->j", g, g)                 # |g|^2 + 2 G
    g /= np.sqrt(two_gamma2)
    return g


def covariance_factor(P: np.ndarray) -> np.ndarray:
    """D (n, n) with D D^T = P, lower-triangular Cholesky over the directions that carry variance.

    Rows/columns with zero variance (e.g. mode-0 fault entries of a JMRPF, pinned at 0) get zero
    columns; if the rest is not numerically positive definite, a symmetric eigen-factor
    V sqrt(max(lambda, 0)) is used instead.
    """
    n = P.shape[0]
    d = np.diag(P)
    live = d > 1e-300
    D = np.zeros((n, n))
    if not live.any():
        return D
    if live.all():
        L, info = dpotrf(P, lower=1, clean=1)    # LAPACK directly: numpy's wrapper costs more
        if info == 0:
            return L
    idx = np.flatnonzero(live)
    Pl = P[np.ix_(idx, idx)]
    Dl, info = dpotrf(Pl, lower=1, clean=1)
    if info != 0:
        lam, V = np.linalg.eigh(0.5 * (Pl + Pl.T))
        Dl = V * np.sqrt(np.maximum(lam, 0.0))
    D[np.ix_(idx, idx)] = Dl
    return D


def regularize(X: np.ndarray, P: np.ndarray, h: float, rng: np.random.Generator,
               shrink: bool = False) -> np.ndarray:
    """Jitter a resampled cloud X (n, N) in place: X += h D eps (Alg. 2.7); returns X.

    The jitter's covariance is h^2 P / (n + 4) (Cov eps = I / (n + 4)).
    shrink=True (Liu-West): first pull every particle towards the cloud mean by
    a = sqrt(1 - h^2 / (n + 4)) so that the jitter does not inflate the covariance (the spread
    stays P instead of (1 + h^2 / (n + 4)) P); used by the baseline RPF/RRPF, whose unobservable
    directions (ch4: p_d and both altitude faults moved together) would otherwise grow at every
    resample (SPEC section 5).
    """
    n, N = X.shape
    D = covariance_factor(P)
    if shrink:
        a = math.sqrt(max(1.0 - h * h / (n + 4), 0.0))
        mean = X.mean(axis=1, keepdims=True)
        X *= a
        X += (1.0 - a) * mean
    X += (h * D) @ epanechnikov(rng, n, N)
    return X
