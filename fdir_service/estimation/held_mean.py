"""A stuck sensor's held reading learnt as the mean of its readings since it stuck (parts.held_value
= "mean"; docs/faults.md, "A held value learnt from the readings").

A stuck entry's held reading c = H_r x (h_r z + f, plus the row's other entries, small fault-free
values under parts.mode0 = "drift") is set by its sentinel's draw from one noisy reading, and
`fault_types.TypedCorrection` never moves it (a held value that followed the readings would follow
the state). So a stuck particle mispredicts every later reading by its draw's error, about one
noise sigma: half a nat a frame, which let a drift, whose level is corrected, fit a stuck reading
better in its first seconds. Here each held entry's c is instead the mean of the readings since the
entry stuck, the posterior mean of a constant under a flat prior:

    c_n = c_n-1 + (y_n - c_n-1) / n           n = 1, 2, ... the readings since it stuck

The gain 1/n shrinks as the hypothesis ages: an old one holds its value and cannot follow a moving
state. Its row is still weighed by N(y; c, sigma_r^2) (`TypedCorrection`), as a bias's and a
drift's rows are weighed without a term for what their corrected levels learnt; a young stuck
hypothesis weighed by the wider predictive of a constant learnt from n readings, sigma_r^2
(1 + 1/n), named the attitude stuck first in 2 of 8 climbs, against 3 of 8 without (and a drift
first in 3 against 0; docs/faults.md).

While a particle's sensor is held, its reading says nothing of that sensor's other entries: on
the frames its row arrives, the Kalman correction leaves them as they were (a drift in mode 1
beside it is still moved by its own tracker, `drift_type.DriftCorrection`, outside this part). It
used to correct a second type of the item that stood in mode 1 beside the stuck one (two
sentinels of one item in one step), and the held value, learnt from what was left, hid it. In
real-stuck run 89, 47 of the 50 stuck particles that took the cloud 0.8 s after the onset carried
a drift entry 1.7 deg off its fault-free value; that value learnt it, and the attitude was
declared three times after the fault. Now none does (the restore acted on 54 of the flight's
2500 frames).

`HeldCount` (a jump wrapper) keeps n per particle: 0 when the entry enters mode 1 (a sentinel or
a hand-over), permuted on resampling. `HeldMeanCorrection` (a correction wrapper, outside
`TypedCorrection`) moves c and keeps the siblings. Blocked pitots are not held (their reading
follows the altitude) and are left alone.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from fdir_service.estimation.jump import JumpWrapper
from fdir_service.estimation.layout import N_AIRFRAME

if TYPE_CHECKING:
    from fdir_service.estimation.frame import Frame


class HeldCount(JumpWrapper):
    """A jump part plus n (k, N), the readings each held stuck entry has averaged since it stuck
    (0 in mode 0). Every attribute it does not define is the inner jump's.

    inner: the jump; faults (k,): the held stuck entries; N: particles.
    """

    def __init__(self, inner, faults: np.ndarray, N: int) -> None:
        super().__init__(inner)
        self.faults = np.asarray(faults, dtype=int)
        self.n = np.zeros((self.faults.size, int(N)))

    def jump(self, X: np.ndarray, modes: np.ndarray, w: np.ndarray, frame: Frame,
             rng: np.random.Generator) -> np.ndarray | None:
        """The inner jump; a held entry that (re-)entered mode 1, or left it, restarts its count."""
        on = modes[self.faults]
        lw = self.inner.jump(X, modes, w, frame, rng)
        self.n *= modes[self.faults] & on
        return lw

    def resample_modes(self, modes: np.ndarray, idx: np.ndarray) -> np.ndarray:
        """The inner's resampled modes; the counts follow their particles (idx (N,))."""
        self.n = np.take(self.n, idx, axis=1)
        return self.inner.resample_modes(modes, idx)

    def reinitialise(self, modes: np.ndarray) -> None:
        """A fresh cloud: the inner's, and every count restarts."""
        self.inner.reinitialise(modes)
        self.n = np.zeros_like(self.n)


class HeldMeanCorrection:
    """A correction part that learns each mode-1 held entry's reading as the mean of its readings
    (module docstring): after the inner correction, f += (y_r - H_r x) / (n + 1) per particle, and
    the other entries of its row keep their values from before the inner correction.

    inner: the correction; count: the `HeldCount`; rows (k,): the held entries' rows; siblings
    (k, nf) bool: the other fault entries of each one's row.
    """

    def __init__(self, inner, count: HeldCount, rows: np.ndarray, siblings: np.ndarray) -> None:
        self.inner = inner
        self.count = count
        self.rows = np.asarray(rows, dtype=int)
        self.entries = N_AIRFRAME + count.faults
        self.siblings = np.asarray(siblings, dtype=float)
        self._kept: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}

    def _kept_entries(self, present: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(the state rows of the fault entries some present held row keeps (s,), siblings (p, s)
        of the present rows over them), cached per pattern of present rows (k,) bool."""
        key = present.tobytes()
        hit = self._kept.get(key)
        if hit is None:
            sib = self.siblings[present]
            cols = np.flatnonzero(sib.any(axis=0))
            hit = self._kept[key] = (N_AIRFRAME + cols, np.ascontiguousarray(sib[:, cols].T))
        return hit

    def update(self, X: np.ndarray, w: np.ndarray, modes: np.ndarray, frame: Frame) -> np.ndarray:
        """The inner correction of X (n, N) in place, then the held means; returns its (N,) log-weights."""
        present = frame.mask[self.rows]
        if not present.any():
            return self.inner.update(X, w, modes, frame)
        ri = frame.row_of[self.rows[present]]
        H, y = frame.mm.H[ri], frame.yv[ri, None]
        on = modes[self.count.faults[present]]
        n = self.count.n[present]
        kept, sib = self._kept_entries(present)
        F = X[kept]                                  # a copy (fancy index): only the siblings' rows
        ll = self.inner.update(X, w, modes, frame)
        X[kept] = np.where((sib @ on) > 0, F, X[kept])
        X[self.entries[present]] += np.where(on, (y - H @ X) / (n + 1.0), 0.0)
        self.count.n[present] = n + on
        return ll
