"""The real-sky parts of an experiment's `[world]`: wind, turbulence, airframe dispersion (lab only).

Every one is off by default, so the thesis experiments are unchanged. Keys (docs/real-world.md):

    [world]
    engine = "internal"            # "internal" (the airframe file's equations) | "jsbsim"
    [world.wind]                   # the air's velocity over the ground, NED (m/s)
    north_mps = 0.0                # at reference_altitude_m (a headwind for the northbound aircraft
    down_mps = 0.0                 #   is negative north_mps)
    shear_exponent = 0.0           # power law: wind(h) = wind_ref (h / reference_altitude_m)^exponent
    reference_altitude_m = 500.0
    [[world.wind.gusts]]           # discrete 1-cosine gusts (MIL-F-8785C): rise over length_m of
    start_s = 30.0                 #   flight path to the amplitude, back to 0 over the next length_m
    length_m = 60.0
    north_mps = 0.0
    down_mps = 3.0
    [world.turbulence]             # Dryden (MIL-F-8785C low altitude) on u_g, w_g and q_g
    intensity = "moderate"         # "none" | "light" | "moderate" | "severe": wind at 6 m 15 / 30 / 45 kt
    wind_6m_mps = 15.4             # optional: the wind at 6 m (20 ft) itself
    [world.dispersion]             # each run's truth airframe, drawn uniformly within +- fraction
    mass = 0.10                    # keys: mass, C_m0, C_m_alpha, C_L_alpha, C_D_p, C_m_q, C_prop
    aircraft_seed = 7              # optional: the same dispersed aircraft in every run
"""

from __future__ import annotations

from dataclasses import dataclass, field

from fdir_service.errors import ConfigError
from fdir_service.tomltable import NON_NEGATIVE, POSITIVE, TomlTable

ENGINES = ("internal", "jsbsim")
INTENSITIES = {"none": 0.0, "light": 15.0, "moderate": 30.0, "severe": 45.0}
"""Turbulence intensity -> wind speed at 6 m (20 ft), knots (MIL-F-8785C / MIL-HDBK-1797)."""
KNOT = 0.514444
DISPERSED = {"mass": "m", "C_m0": "C_m0", "C_m_alpha": "C_ma", "C_L_alpha": "C_La", "C_D_p": "C_Dp",
             "C_m_q": "C_mq", "C_prop": "C_prop"}
"""Dispersion key -> `AirframeParams` field."""


@dataclass(frozen=True)
class Gust:
    """A 1-cosine gust: starts at start_s (s), rises over length_m of path to (north, down) m/s."""

    start_s: float
    length_m: float
    north_mps: float = 0.0
    down_mps: float = 0.0


@dataclass(frozen=True)
class WindConfig:
    """Steady wind (NED, m/s, at reference_altitude_m), power-law shear and discrete gusts."""

    north_mps: float = 0.0
    down_mps: float = 0.0
    shear_exponent: float = 0.0
    reference_altitude_m: float = 500.0
    gusts: tuple[Gust, ...] = ()

    @property
    def active(self) -> bool:
        return bool(self.north_mps or self.down_mps or self.gusts)


@dataclass(frozen=True)
class TurbulenceConfig:
    """Dryden turbulence with the wind at 6 m (m/s); 0: none."""

    wind_6m_mps: float = 0.0

    @property
    def active(self) -> bool:
        return self.wind_6m_mps > 0.0


@dataclass(frozen=True)
class DispersionConfig:
    """Each run's truth airframe: AirframeParams field -> +- fraction (uniform). aircraft_seed: None,
    a new airframe every run; an integer, one airframe (drawn from this seed) in every run: one
    aircraft flown many times, as `fdir identify` then monitoring it needs."""

    fractions: dict[str, float] = field(default_factory=dict)
    aircraft_seed: int | None = None

    @property
    def active(self) -> bool:
        return any(v > 0 for v in self.fractions.values())


@dataclass(frozen=True)
class RealSky:
    """What a world adds to the thesis's still air and exact airframe."""

    engine: str = "internal"
    wind: WindConfig = WindConfig()
    turbulence: TurbulenceConfig = TurbulenceConfig()
    dispersion: DispersionConfig = DispersionConfig()

    @property
    def moving_air(self) -> bool:
        return self.wind.active or self.turbulence.active


def _gust(t: TomlTable) -> Gust:
    g = Gust(start_s=t.take("start_s", "number", check=NON_NEGATIVE),
             length_m=t.take("length_m", "number", check=POSITIVE),
             north_mps=t.take("north_mps", "number", 0.0), down_mps=t.take("down_mps", "number", 0.0))
    t.finish()
    return g


def parse_wind(w: TomlTable) -> WindConfig:
    t = w.sub("wind")
    wind = WindConfig(north_mps=t.take("north_mps", "number", 0.0),
                      down_mps=t.take("down_mps", "number", 0.0),
                      shear_exponent=t.take("shear_exponent", "number", 0.0, check=NON_NEGATIVE),
                      reference_altitude_m=t.take("reference_altitude_m", "number", 500.0, check=POSITIVE),
                      gusts=tuple(_gust(g) for g in t.tables("gusts")))
    t.finish()
    return wind


def parse_turbulence(w: TomlTable) -> TurbulenceConfig:
    t = w.sub("turbulence")
    intensity = t.take("intensity", "string", "none", choices=tuple(INTENSITIES))
    w6 = t.take("wind_6m_mps", "number", INTENSITIES[intensity] * KNOT, check=NON_NEGATIVE)
    t.finish()
    return TurbulenceConfig(wind_6m_mps=w6)


def parse_dispersion(w: TomlTable) -> DispersionConfig:
    t = w.sub("dispersion")
    fr = {DISPERSED[k]: t.take(k, "number", 0.0, check=NON_NEGATIVE) for k in DISPERSED}
    seed = t.take("aircraft_seed", "integer", None, check=NON_NEGATIVE)
    t.finish()
    for k, v in fr.items():
        if v >= 1.0:
            raise ConfigError(f"{t.key(next(n for n, f in DISPERSED.items() if f == k))}: expected a "
                              f"fraction below 1, got {v}")
    return DispersionConfig({k: v for k, v in fr.items() if v > 0}, seed)


def parse_real_sky(w: TomlTable, model: str) -> RealSky:
    """The real-sky tables of `[world]`; ConfigError naming the key when one cannot apply."""
    sky = RealSky(engine=w.take("engine", "string", "internal", choices=ENGINES), wind=parse_wind(w),
                  turbulence=parse_turbulence(w), dispersion=parse_dispersion(w))
    if sky.engine == "jsbsim" and sky.dispersion.active:
        raise ConfigError(f"{w.key('dispersion')}: the JSBSim aircraft (config/jsbsim) is not dispersed; "
                          "expected no [world.dispersion] with engine = \"jsbsim\"")
    if model == "linear" and (sky.moving_air or sky.dispersion.active or sky.engine != "internal"):
        raise ConfigError(f"{w.key('model')}: wind, turbulence, dispersion and other engines need the "
                          "nonlinear truth (model = \"nonlinear\")")
    return sky
