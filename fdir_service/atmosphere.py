"""Standard-atmosphere barometric formula (SPEC section 3, thesis Table B.1), troposphere only.

p(h) = P0 (1 + L0 h / T0) ^ (-g M / (R L0)) and its inverse; h in m above mean sea level, p in Pa.
Both functions are numpy-vectorised (scalars in, floats out; arrays in, arrays out).
"""

from __future__ import annotations

import numpy as np

P0_PA = 101325.0        # sea-level static pressure, Pa
T0_K = 288.15           # sea-level temperature, K
L0_K_PER_M = -0.0065    # temperature lapse rate, K/m
G0 = 9.80665            # standard gravity, m/s^2
R_GAS = 8.3144598       # universal gas constant, J/(mol K)
M_AIR = 0.0289644       # molar mass of dry air, kg/mol

_EXPONENT = -G0 * M_AIR / (R_GAS * L0_K_PER_M)   # ~5.2559


def pressure_from_altitude(h_m: float | np.ndarray) -> float | np.ndarray:
    """Static pressure (Pa) at altitude h_m (m above mean sea level)."""
    if type(h_m) is float and h_m < 44000.0:   # the simulator's per-frame call: same arithmetic
        return P0_PA * (1.0 + L0_K_PER_M * h_m / T0_K) ** _EXPONENT
    h = np.asarray(h_m, dtype=float)
    p = P0_PA * (1.0 + L0_K_PER_M * h / T0_K) ** _EXPONENT
    return float(p) if p.ndim == 0 else p


def altitude_from_pressure(p_pa: float | np.ndarray) -> float | np.ndarray:
    """Pressure altitude (m above mean sea level) of a static pressure p_pa (Pa)."""
    if type(p_pa) is float and p_pa > 0.0:     # the simulator's per-frame call: same arithmetic
        return T0_K / L0_K_PER_M * ((p_pa / P0_PA) ** (1.0 / _EXPONENT) - 1.0)
    p = np.asarray(p_pa, dtype=float)
    h = T0_K / L0_K_PER_M * ((p / P0_PA) ** (1.0 / _EXPONENT) - 1.0)
    return float(h) if h.ndim == 0 else h
