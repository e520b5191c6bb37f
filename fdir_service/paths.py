"""Where the project's configuration lives (override with the FDIR_CONFIG_DIR variable).

`config/` holds one folder per kind of file: `airframes/`, `estimators/`, `service/`,
`autopilots/` (autopilot profiles) and `experiments/` (the lab's). A name (`aerosonde`) resolves
to `<kind>/<name>.toml`; a path (with a `.toml` suffix, or an existing file) is taken as it is.
"""

from __future__ import annotations

import os
from pathlib import Path


def config_dir() -> Path:
    """The `config/` folder: $FDIR_CONFIG_DIR, else the one beside the package (editable install)."""
    env = os.environ.get("FDIR_CONFIG_DIR")
    if env:
        return Path(env)
    return Path(__file__).resolve().parent.parent / "config"


def config_path(kind: str, name_or_path: str | os.PathLike[str]) -> Path:
    """A config file of `kind` ("airframes", "estimators", "service", "autopilots", "experiments") by
    name or path."""
    p = Path(name_or_path)
    if p.suffix == ".toml" or p.is_file():      # a folder of the same name (a report's --out) is not it
        return p
    return config_dir() / kind / f"{name_or_path}.toml"


def airframe_path(name_or_path: str | os.PathLike[str]) -> Path:
    """An airframe file: `aerosonde` -> config/airframes/aerosonde.toml."""
    return config_path("airframes", name_or_path)


def estimator_path(name_or_path: str | os.PathLike[str]) -> Path:
    """An estimator file: `aerosonde` -> config/estimators/aerosonde.toml."""
    return config_path("estimators", name_or_path)


def service_path(name_or_path: str | os.PathLike[str] = "default") -> Path:
    """A service file: `default` -> config/service/default.toml."""
    return config_path("service", name_or_path)
