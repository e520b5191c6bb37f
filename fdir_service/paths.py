"""Where the project's configuration lives (override with the FDIR_CONFIG_DIR variable)."""

from __future__ import annotations

import os
from pathlib import Path


def config_dir() -> Path:
    """The `config/` folder: $FDIR_CONFIG_DIR, else the one beside the package (editable install)."""
    env = os.environ.get("FDIR_CONFIG_DIR")
    if env:
        return Path(env)
    return Path(__file__).resolve().parent.parent / "config"


def scenario_path(name_or_path: str | os.PathLike[str]) -> Path:
    """Resolve a scenario id (`ch4`) or a path to a scenario TOML file."""
    p = Path(name_or_path)
    if p.suffix == ".toml" or p.exists():
        return p
    return config_dir() / "scenarios" / f"{name_or_path}.toml"
