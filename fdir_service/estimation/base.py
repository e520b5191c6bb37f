"""The contract every filter honours: one `step` per frame, one `StepOutput` back.

Shapes: n = extended-state size (5 airframe states + one entry per fault channel, in the
scenario's fault order), m = number of measurement rows, nf = number of fault channels.
Units are SI (m, m/s, rad, rad/s) throughout; conversion to degrees happens only in reports.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np


@dataclass
class StepOutput:
    """What a filter says about one frame.

    t: frame time (s); x_mean (n,), x_cov (n, n) or None: extended-state estimate and covariance
    (None when the filter was asked not to output it, e.g. `ParticleFilter.output_covariance`);
    fault_ids (nf,); fault_estimate (nf,) SI; fault_probability (nf,) = P(mode 1);
    n_eff: effective sample size (N for KF-type filters); resampled: whether this step resampled;
    pfa, pmd (nf,) and transition (nf, 2, 2) only for adaptive filters (None otherwise);
    fault_types (nf,): each fault's type (`estimator_config.SENSOR_FAULT_TYPES` /
    `ACTUATOR_FAULT_TYPES`; empty: all "bias"); fault_value (nf,) SI or None (= fault_estimate):
    what a user reads per type: a bias's offset, a stuck sensor's held reading, a jammed
    actuator's held position, a noisy sensor's noise multiplier k, an effectiveness's gain g, a
    drift's rate (SI per second), an engine's share of the commanded thrust.
    """

    t: float
    x_mean: np.ndarray
    x_cov: np.ndarray | None
    fault_ids: tuple[str, ...]
    fault_estimate: np.ndarray
    fault_probability: np.ndarray
    n_eff: float
    resampled: bool
    pfa: np.ndarray | None = None
    pmd: np.ndarray | None = None
    transition: np.ndarray | None = None
    fault_types: tuple[str, ...] = ()
    fault_value: np.ndarray | None = None

    def type_of(self, j: int) -> str:
        """Fault j's type ("bias" when the filter reports none)."""
        return self.fault_types[j] if self.fault_types else "bias"

    def value_of(self, j: int) -> float:
        """Fault j's user-facing value (SI, or unitless for k and g): `fault_value` else the estimate."""
        v = self.fault_value if self.fault_value is not None else self.fault_estimate
        return float(v[j])

    @property
    def state(self) -> np.ndarray:
        """Airframe-state estimate z_hat (5,) = [p_d, u, w, theta, q]: what the autopilot flies on."""
        return self.x_mean[:5]


class Filter(Protocol):
    """A fault-estimating filter. Built by `fdir_service.estimation.factory.build_filter`."""

    name: str
    fault_ids: tuple[str, ...]

    def step(self, t: float, y: np.ndarray, mask: np.ndarray, u: np.ndarray) -> StepOutput:
        """Advance one frame.

        t: frame time (s, from the message timestamps); y (m,) measurements in SI (entries
        where mask is False are ignored and may be NaN); mask (m,) bool, True where the row
        arrived; u (2,) = [delta_e rad, delta_t] applied since the previous frame.
        """
        ...

    def top_particles(self, k: int = 20) -> tuple[np.ndarray, np.ndarray]:
        """The k most weighted particles (k, n) and their weights (k,); a KF returns its mean."""
        ...
