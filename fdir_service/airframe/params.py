"""Airframe parameters, loaded and validated from `config/airframes/<name>.toml` (SPEC section 2)."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from pathlib import Path

from fdir_service.errors import ConfigError
from fdir_service.paths import airframe_path
from fdir_service.tomltable import load_toml


@dataclass(frozen=True)
class AirframeParams:
    """Aerosonde longitudinal parameters, SI units (kg, m, rad)."""

    m: float = 25.0
    Jx: float = 0.8244
    Jy: float = 1.135
    Jz: float = 1.759
    Jxz: float = 0.1204
    S: float = 0.55
    b: float = 2.8956
    c: float = 0.18994
    S_prop: float = 0.2027
    e: float = 0.9
    k_motor: float = 80.0
    k_Tp: float = 0.0
    k_Omega: float = 0.0
    C_prop: float = 1.0
    rho: float = 1.168
    g: float = 9.81
    C_L0: float = 0.28
    C_D0: float = 0.03
    C_m0: float = -0.02338
    C_La: float = 3.45
    C_Da: float = 0.30
    C_ma: float = -0.38
    C_Lq: float = 0.0
    C_Dq: float = 0.0
    C_mq: float = -3.6
    C_Lde: float = -0.36
    C_Dde: float = 0.0
    C_mde: float = -0.5
    C_Dp: float = 0.0437
    M: float = 50.0
    alpha0: float = 0.4712
    epsilon: float = 0.1592

    @property
    def AR(self) -> float:
        """Aspect ratio b^2 / S."""
        return self.b**2 / self.S


_POSITIVE = {"m", "Jy", "S", "b", "c", "S_prop", "e", "rho", "g", "k_motor"}


def load_airframe(path: str | Path | None = None) -> AirframeParams:
    """Read an airframe TOML (sections are only grouping); unknown keys and bad values fail."""
    path = airframe_path(path) if path is not None else airframe_path("aerosonde")
    doc = load_toml(path, "airframe file")
    known = {f.name for f in fields(AirframeParams)}
    values: dict[str, float] = {}
    for section, table in doc.items():
        if not isinstance(table, dict):
            raise ConfigError(f"{path}: [{section}] must be a table of parameters")
        for key, val in table.items():
            where = f"{path}: {section}.{key}"
            if key not in known:
                raise ConfigError(f"{where}: unknown airframe parameter")
            if isinstance(val, bool) or not isinstance(val, int | float) or not math.isfinite(val):
                raise ConfigError(f"{where}: expected a finite number, got {val!r}")
            if key in _POSITIVE and val <= 0:
                raise ConfigError(f"{where}: expected a positive number, got {val!r}")
            values[key] = float(val)
    return AirframeParams(**values)
