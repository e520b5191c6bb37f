"""A parsed TOML table read key by key with validation: the one reader behind every config file.

`TomlTable` wraps one table of a parsed document (`tomllib`) and its dotted position in it
(`"estimator.imm"`, `"faults[0].profile[1]"`). Each `take` consumes one key, checks its type (and
optionally its value) and returns it; `finish` then reports every key nobody consumed as unknown.
Every failure raises `ConfigError` whose message names the dotted key, what was expected and what
was got, e.g. `estimator.particles: expected an integer, got 1000.5`.

Value kinds (`Kind`): "number" (an int or a float, never a bool, finite; returned as a float),
"integer" (an int, never a bool), "string", "boolean", "numbers" (a list of numbers as above,
returned as a tuple of floats) and "strings" (a list of strings, returned as a tuple). A default is
returned as given, unchecked.
"""

from __future__ import annotations

import math
import re
import tomllib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from fdir_service.errors import ConfigError

Kind = Literal["number", "integer", "string", "boolean", "numbers", "strings"]

_EXPECT: dict[str, str] = {
    "number": "a finite number",
    "integer": "an integer",
    "string": "a string",
    "boolean": "true or false",
    "numbers": "a list of finite numbers",
    "strings": "a list of strings",
}


@dataclass(frozen=True)
class Check:
    """A condition on a value of the right kind, and its wording in the error: `expected <expect>`."""

    test: Callable[[Any], bool]
    expect: str

    def saying(self, expect: str) -> Check:
        """The same condition, worded `expect` in the error (e.g. "a positive rate")."""
        return Check(self.test, expect)


POSITIVE = Check(lambda v: v > 0, "a positive value")
NON_NEGATIVE = Check(lambda v: v >= 0, "a non-negative value")
UNIT_INTERVAL = Check(lambda v: 0.0 <= v <= 1.0, "a value in [0, 1]")
ALL_NON_NEGATIVE = Check(lambda v: all(x >= 0 for x in v), "non-negative numbers")
"""For kind "numbers": every element >= 0."""


def _is_number(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def _is_integer(v: Any) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _same(v: Any) -> Any:
    return v


_IS_KIND: dict[str, Callable[[Any], bool]] = {
    "number": _is_number,
    "integer": _is_integer,
    "string": lambda v: isinstance(v, str),
    "boolean": lambda v: isinstance(v, bool),
    "numbers": lambda v: isinstance(v, list) and all(_is_number(x) for x in v),
    "strings": lambda v: isinstance(v, list) and all(isinstance(x, str) for x in v),
}
"""Whether a parsed TOML value is of each kind."""
_CONVERT: dict[str, Callable[[Any], Any]] = {
    "number": float,
    "numbers": lambda v: tuple(float(x) for x in v),
    "strings": tuple,
}
"""How a value of the kind is returned (other kinds: as parsed)."""


def _check_choices(full: str, kind: str, val: Any, choices: tuple[str, ...]) -> None:
    """Raise unless the "string" val (or each of the "strings" val) is one of choices."""
    if kind != "strings":
        if val not in choices:
            raise ConfigError(f"{full}: expected one of {', '.join(choices)}, got {val!r}")
        return
    for v in val:
        if v not in choices:
            raise ConfigError(f"{full}: {v!r} is not one of {', '.join(choices)}")


class TomlTable:
    """One TOML table being consumed: every key must be taken, else `finish` reports it as unknown.

    `where` is the table's dotted key in the document ("" for the root).
    """

    def __init__(self, data: Any, where: str) -> None:
        if not isinstance(data, dict):
            raise ConfigError(f"{where}: expected a table, got {type(data).__name__}")
        self._data: dict[str, Any] = dict(data)
        self.where = where

    def key(self, name: str) -> str:
        """The dotted key of `name` in this table, for error messages."""
        return f"{self.where}.{name}" if self.where else name

    def peek(self, name: str) -> Any:
        """The raw value under `name` without taking it (None if absent)."""
        return self._data.get(name)

    def keys(self) -> list[str]:
        """The keys not consumed yet, in file order."""
        return list(self._data)

    def take(self, name: str, kind: Kind, default: Any = ..., *, choices: tuple[str, ...] = (),
             check: Check | None = None) -> Any:
        """Consume `name` and return its validated value.

        A missing key returns `default`, or raises if there is none (`...`). `choices` restricts a
        "string" (or each of "strings") to those values; `check` must hold for the converted value.
        """
        if name not in self._data:
            if default is ...:
                raise ConfigError(f"{self.key(name)}: missing, expected {_EXPECT[kind]}")
            return default
        if kind not in _IS_KIND:
            raise ValueError(f"unknown kind {kind!r}")
        val = self._data.pop(name)
        full = self.key(name)
        if not _IS_KIND[kind](val):
            raise ConfigError(f"{full}: expected {_EXPECT[kind]}, got {val!r}")
        val = _CONVERT.get(kind, _same)(val)
        if choices:
            _check_choices(full, kind, val, choices)
        if check is not None and not check.test(val):
            shown = list(val) if isinstance(val, tuple) else val   # a list as written in TOML
            raise ConfigError(f"{full}: expected {check.expect}, got {shown!r}")
        return val

    def sub(self, name: str, *, required: bool = False) -> TomlTable:
        """Consume the sub-table `name` (an empty one if absent and not `required`)."""
        if name not in self._data:
            if required:
                raise ConfigError(f"{self.key(name)}: missing table")
            return TomlTable({}, self.key(name))
        return TomlTable(self._data.pop(name), self.key(name))

    def tables(self, name: str) -> list[TomlTable]:
        """Consume the array of tables `name` (`[[name]]`; none if absent), one reader per element."""
        full = self.key(name)
        raw = self._data.pop(name, [])
        if not isinstance(raw, list):
            header = re.sub(r"\[\d+\]", "", full)
            raise ConfigError(f"{full}: expected an array of tables ([[{header}]]), got {raw!r}")
        return [TomlTable(item, f"{full}[{i}]") for i, item in enumerate(raw)]

    def rest(self) -> dict[str, Any]:
        """Consume every key not taken yet and return them as a plain table (for overrides)."""
        out, self._data = self._data, {}
        return out

    def finish(self) -> None:
        """Raise if any key was not consumed, naming them all."""
        if self._data:
            raise ConfigError("unknown key(s): " + ", ".join(self.key(k) for k in sorted(self._data)))


def load_toml(path: str | Path, what: str) -> dict[str, Any]:
    """Parse the TOML file at `path`; a missing file or bad TOML raises ConfigError naming the path
    and `what` it should be ("airframe file", "scenario file")."""
    try:
        with open(path, "rb") as fh:
            return tomllib.load(fh)
    except FileNotFoundError as exc:
        raise ConfigError(f"{path}: no such {what}") from exc
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: not valid TOML: {exc}") from exc
