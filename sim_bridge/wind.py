"""Deterministic wind of a world: steady NED wind with power-law shear and 1-cosine gusts.

The wind is the air's velocity over the ground, NED (m/s). In body axes of the wings-level,
northbound aircraft at pitch theta (x forward, z down):
    u_w = n cos(theta) - d sin(theta),   w_w = n sin(theta) + d cos(theta).
Shear (power law): wind(h) = wind_ref (h / h_ref)^exponent for h > 0.
Gust (MIL-F-8785C discrete gust, "1 - cosine"): over the flight path x = V (t - start) flown since
its start, v(x) = V_m / 2 (1 - cos(pi x / d_m)) for 0 <= x <= 2 d_m (up to V_m at x = d_m and
back), 0 elsewhere.
"""

from __future__ import annotations

import math

import numpy as np

from sim_bridge.world_config import Gust, WindConfig


def gust_ned(gust: Gust, t: float, airspeed_mps: float) -> tuple[float, float]:
    """(north, down) m/s of one 1-cosine gust at time t (s) for an aircraft flying at airspeed_mps."""
    x = airspeed_mps * (t - gust.start_s)
    if not 0.0 <= x <= 2.0 * gust.length_m:
        return 0.0, 0.0
    shape = 0.5 * (1.0 - math.cos(math.pi * x / gust.length_m))
    return gust.north_mps * shape, gust.down_mps * shape


def wind_ned(cfg: WindConfig, t: float, altitude_m: float, airspeed_mps: float) -> tuple[float, float]:
    """(north, down) wind (m/s) at time t (s) and altitude (m): sheared steady wind plus gusts."""
    scale = 1.0
    if cfg.shear_exponent > 0.0:
        scale = (max(altitude_m, 1.0) / cfg.reference_altitude_m) ** cfg.shear_exponent
    n, d = cfg.north_mps * scale, cfg.down_mps * scale
    for g in cfg.gusts:
        gn, gd = gust_ned(g, t, airspeed_mps)
        n, d = n + gn, d + gd
    return n, d


def ned_to_body(north: float, down: float, theta: float) -> np.ndarray:
    """(u_w, w_w) body-axis components (2,) of an NED (north, down) vector at pitch theta (rad)."""
    c, s = math.cos(theta), math.sin(theta)
    return np.array([north * c - down * s, north * s + down * c])
