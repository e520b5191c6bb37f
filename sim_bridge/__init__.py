"""sim-bridge: the Aerosonde world (airframe truth, sensors, faults, autopilot) and campaigns."""

import fdir_service as _fdir_service  # noqa: E402,F401 - first: it pins numpy's kernels (fdir_service/__init__.py)
