"""One frame as the filter's parts see it: the rows that arrived, their values and the input."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from fdir_service.estimation.measurement import MeasurementModel


@dataclass
class Frame:
    """One frame as the parts see it: t (s), mask (m,) bool, u (2,), mm the measurement model of
    the rows that arrived and yv (m_rows,) their values (SI)."""

    t: float
    mask: np.ndarray
    u: np.ndarray
    mm: MeasurementModel
    yv: np.ndarray

    @classmethod
    def of(cls, t: float, y: np.ndarray, mask: np.ndarray, u: np.ndarray, meas: MeasurementModel) -> Frame:
        mask = np.asarray(mask, dtype=bool)
        return cls(t, mask, np.asarray(u, dtype=float), meas.reduced(mask), np.asarray(y, dtype=float)[mask])

    @cached_property
    def row_of(self) -> np.ndarray:
        """(m,) each full row's index among the rows that arrived (meaningful where mask is True)."""
        return np.cumsum(self.mask) - 1
