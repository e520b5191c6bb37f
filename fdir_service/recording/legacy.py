"""Logs recorded before the estimator files existed (fdir-service <= 0.1 "scenario" logs).

Their "config" metadata holds the service TOML with `[service] scenario = ...` and the scenario
TOML text, whose `[estimator]`, `[sensors]`, `[[faults]]` and `[truth]` tables gave the filter
its settings, its assumed noise (true sigma x `filter_noise_factor`), its faults and its trim.
This module turns that pair into today's service document and estimator document, giving the
same filter bit for bit, so `fdir log info` and `fdir replay` work on old logs.
"""

from __future__ import annotations

import copy
import tomllib
from typing import Any

from fdir_service.errors import ConfigError

_OLD_DEFAULTS = dict(process_model="nonlinear", linear_matrices="printed", sigma_x_basis="step",
                     resample_threshold=0.5, bandwidth_k=0.2, resampler="multinomial",
                     mode0="forced_zero", pi01=0.01, pi10=0.01, saddlepoint_window=3,
                     sentinel_weighting="thesis", jitter="global", adaptive_transition="thesis",
                     actuator_sentinel="thesis")
"""The old scenario schema's defaults where today's estimator defaults differ."""
_FAULT_KEYS = ("id", "target", "unit", "sigma_f", "x0_sigma", "amplitude_max")


def _parts(est: dict[str, Any]) -> dict[str, Any]:
    parts = {k: v for k, v in est.items() if k not in ("filters", "proposed", "particles")}
    for k, v in _OLD_DEFAULTS.items():
        parts.setdefault(k, v)
    return parts


def estimator_from_scenario(scenario: dict[str, Any]) -> dict[str, Any]:
    """The estimator document equivalent to an old scenario document's estimator settings."""
    try:
        est, sensors = scenario["estimator"], scenario["sensors"]
        rows = list(sensors["measurements"])
        factor = sensors.get("filter_noise_factor", 1.5)
        truth, head = scenario.get("truth", {}), scenario["scenario"]
        return {
            "id": head["id"], "airframe": "aerosonde", "dt_s": head.get("dt_s", 0.05),
            "filter": est["proposed"], "particles": est.get("particles", 1000), "seed": 0,
            "operating_point": {"airspeed_mps": truth.get("airspeed_mps", 40.0),
                                "altitude_m": truth.get("altitude_m", 500.0)},
            "measurements": {"rows": rows,
                             "sigma": {r: sensors["sigma"][r] * factor for r in rows}},
            "parts": _parts(copy.deepcopy(est)),
            "faults": [{k: f[k] for k in _FAULT_KEYS if k in f} for f in scenario.get("faults", [])],
        }
    except (KeyError, TypeError) as exc:
        raise ConfigError(f"recorded scenario: not a scenario of the old schema ({exc!r} missing)") from None


def service_from_legacy(service_toml: str, scenario_toml: str) -> tuple[dict[str, Any], dict[str, Any]]:
    """(service document, estimator document) for an old log's recorded service and scenario TOML."""
    try:
        service, scenario = tomllib.loads(service_toml), tomllib.loads(scenario_toml)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"recorded config: not valid TOML: {exc}") from None
    estimator = estimator_from_scenario(scenario)
    head = service.setdefault("service", {})
    head.pop("scenario", None)
    head.setdefault("seed", 0)
    return service, estimator
