"""Kalman correction of every particle: the "R" (robustified) variants (thesis Alg. 5.1-5.2, eq. 5.3-5.9).

From the weighted predicted cloud: x_bar = sum w x_i, y_bar = sum w h(x_i), P_xy, S = P_yy + R,
K = P_xy S^-1. Weights are multiplied by N(y - h(x_i); 0, S) and every particle moves
x_i <- x_i + K (y - h(x_i)). With the linear measurement model h(x) = H x, P_xy = P H^T and
P_yy = H P H^T with P the weighted (n, n) covariance of the cloud, computed once.
"""

from __future__ import annotations

import numpy as np


def weighted_mean_cov(X: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Weighted mean (n,) and covariance (n, n) of a state-major cloud X (n, N), weights w (N,)."""
    mean = X @ w
    dX = X - mean[:, None]
    cov = (dX * w) @ dX.T
    return mean, cov


def kalman_gain(P: np.ndarray, H: np.ndarray, R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Gain K (n, m) and inverse innovation covariance S^-1 (m, m) from the cloud covariance P (n, n).

    Alg. 5.1 with h(x) = H x: P_xy = P H^T, S = H P H^T + R, K = P_xy S^-1. S is m x m (m <= 6):
    its explicit inverse is cheaper than a factorisation call and is reused by the weights.
    """
    PHt = P @ H.T
    S = H @ PHt + R
    S_inv = np.linalg.inv(S)
    return PHt @ S_inv, S_inv


def correct(X: np.ndarray, innovation: np.ndarray, K: np.ndarray) -> None:
    """Move every particle by the Kalman correction in place: X += K (y - H X) (eq. 5.3)."""
    X += K @ innovation


def gaussian_loglik(innovation: np.ndarray, S_inv: np.ndarray) -> np.ndarray:
    """log N(e_i; 0, S) up to a constant, for innovations (m, N) and S^-1: -0.5 e_i^T S^-1 e_i (N,)."""
    return -0.5 * np.einsum("ij,ij->j", innovation, S_inv @ innovation)
