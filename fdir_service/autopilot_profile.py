"""Autopilot profiles (`config/autopilots/<name>.toml`, `fdir run --autopilot`): which stock
messages of an autopilot feed each estimator row and input, and how.

A profile holds `[autopilot]` (its `heartbeat_autopilot`: the MAV_AUTOPILOT value of the
autopilot's HEARTBEAT, used by `--autopilot auto`), `[measurements.<row>]` and `[inputs.<name>]`
tables exactly like the service file's (plus derived rows: `derive`, `sources`, see
`runtime.derived`, and `stamp`), and `[parameters]`: the autopilot parameter values assumed until
the autopilot's PARAM_VALUE says otherwise, and `[parameter_requests]`: which further parameters
the service asks the autopilot for (`names`, `channel`; `runtime.params`). Applied, it replaces
the service file's `[measurements]` and `[inputs]`; everything else (link, frames, publishing,
health) stays the service file's. Errors name the profile file and the key.

Choices: "none" (the service file's own mapping), "auto" (the service file's mapping is replaced
once the autopilot's first HEARTBEAT names an autopilot with a profile in `AUTO_PROFILES`; no
frames before that HEARTBEAT), or a profile name or path ("ardupilot", "px4").
"""

from __future__ import annotations

import dataclasses
import tomllib
from collections.abc import Mapping
from pathlib import Path

from fdir_service.errors import ConfigError
from fdir_service.paths import config_path
from fdir_service.service_config import ServiceConfig, parse_mappings
from fdir_service.tomltable import Check, TomlTable

CHOICES = ("none", "auto", "ardupilot", "px4")
"""The `--autopilot` values documented in `fdir run --help` (a profile path is accepted too)."""
AUTO_PROFILES = ("ardupilot", "px4")
"""The profiles `--autopilot auto` can pick (by their `heartbeat_autopilot`)."""


def profile_path(name_or_path: str) -> Path:
    """`ardupilot` -> config/autopilots/ardupilot.toml; a path as it is."""
    return config_path("autopilots", name_or_path)


def _profile_text(name: str, texts: Mapping[str, str] | None) -> tuple[str, str]:
    """(TOML text, source) of a profile: from `texts` (a recording) if there, else from its file."""
    if texts is not None and name in texts:
        return texts[name], f"<recorded autopilot profile {name}>"
    path = profile_path(name)
    try:
        return path.read_text(), str(path)
    except FileNotFoundError:
        raise ConfigError(f"--autopilot {name}: no profile {path}; expected one of "
                          f"{', '.join(CHOICES)} or a profile file") from None


def apply_profile(config: ServiceConfig, name: str, texts: Mapping[str, str] | None = None) -> ServiceConfig:
    """`config` with the mapping of profile `name` (read from `texts` if given, else its file)."""
    text, source = _profile_text(name, texts)
    try:
        return _apply(config, name, text)
    except ConfigError as exc:
        raise ConfigError(f"{source}: {exc}") from None


def heartbeat_autopilot(config: ServiceConfig) -> int | None:
    """The MAV_AUTOPILOT value the applied profile declares, or None (no profile)."""
    if config.autopilot in ("none", "auto"):
        return None
    doc = tomllib.loads(dict(config.profile_texts)[config.autopilot])
    return int(doc.get("autopilot", {}).get("heartbeat_autopilot", -1))


def _apply(config: ServiceConfig, name: str, text: str) -> ServiceConfig:
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"not valid TOML: {exc}") from None
    root = TomlTable(doc, "")
    ap = root.sub("autopilot", required=True)
    ap.take("name", "string", check=Check(lambda v: v.strip() != "", "the autopilot's name"))
    ap.take("heartbeat_autopilot", "integer",
            check=Check(lambda v: 0 <= v <= 255, "a MAV_AUTOPILOT value 0..255 (ArduPilot: 3, PX4: 12)"))
    ap.take("description", "string", "")
    ap.finish()
    measurements, inputs = parse_mappings(root, config.estimator)
    pt = root.sub("parameters")
    params = tuple((k, pt.take(k, "number")) for k in pt.keys())
    pt.finish()
    names, channel = _parameter_requests(root.sub("parameter_requests"))
    root.finish()
    return dataclasses.replace(config, measurements=measurements, inputs=inputs, parameters=params,
                               parameter_requests=names, parameter_channel_requests=channel,
                               autopilot=name, auto_profiles=(),
                               profile_texts=((name, text),))


def _pattern_ok(pattern: str, placeholders: tuple[str, ...]) -> bool:
    """Whether a parameter name pattern holds at most one of `placeholders` and, with the widest
    number in place, fits PARAM_REQUEST_READ's 16 characters."""
    used = [p for p in ("{n}", "{i}") if p in pattern]
    if len(used) > 1 or any(p not in placeholders for p in used) or "{" in pattern.replace(
            used[0] if used else "{}", ""):
        return False
    wide = pattern.replace("{n}", "16").replace("{i}", "7")
    return 0 < len(wide) <= 16 and wide.isascii()


def _parameter_requests(pr: TomlTable) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """`[parameter_requests]`: (names, channel) patterns (`runtime.params`)."""
    names = pr.take("names", "strings", (), check=Check(
        lambda v: all(_pattern_ok(x, ("{n}", "{i}")) for x in v),
        "parameter names of up to 16 characters, optionally with one {n} (outputs 1..16) or {i} "
        "(control surfaces 0..7)"))
    channel = pr.take("channel", "strings", (), check=Check(
        lambda v: all("{n}" in x and _pattern_ok(x, ("{n}",)) for x in v),
        "parameter names of up to 16 characters with {n} (the input's output channel)"))
    pr.finish()
    return tuple(names), tuple(channel)


def select_autopilot(config: ServiceConfig, choice: str,
                     texts: Mapping[str, str] | None = None) -> ServiceConfig:
    """The config for `--autopilot choice` ("none", "auto" or a profile); `texts`: recorded profiles."""
    if choice == "none":
        return config
    if choice != "auto":
        return apply_profile(config, choice, texts)
    applied = [apply_profile(config, name, texts) for name in AUTO_PROFILES]
    auto = tuple((heartbeat_autopilot(c), c) for c in applied)
    return dataclasses.replace(config, autopilot="auto", auto_profiles=auto,
                               profile_texts=tuple(c.profile_texts[0] for c in applied))
