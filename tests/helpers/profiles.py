"""Autopilot profile files with one key spoiled, for the tests that a bad key is named."""

from __future__ import annotations

from pathlib import Path

import pytest

from fdir_service.autopilot_profile import select_autopilot
from fdir_service.errors import ConfigError
from fdir_service.service_config import load_service_config


def assert_bad_key_named(tmp_path: Path, text: str, old: str, new: str, key: str) -> None:
    """The profile `text` with its first `old` replaced by `new` fails at start with an error that
    starts with the file's path and names `key`."""
    assert old in text
    bad = tmp_path / "bad-profile.toml"
    bad.write_text(text.replace(old, new, 1))
    with pytest.raises(ConfigError) as err:
        select_autopilot(load_service_config(), str(bad))
    assert str(err.value).startswith(f"{bad}: ") and key in str(err.value)
