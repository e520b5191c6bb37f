"""The "drift" sensor fault type: a fault that ramps (issue 17, item 5; docs/faults.md).

A drift entry is additive like a bias (its row reads h_r z + f), but in mode 1 it moves at its
own rate r (SI per second), a per-particle quantity that random-walks slowly:

    f+ = f + r dt,     r+ = r + rate_sigma sqrt(dt) eps,     eps ~ N(0, 1)

so a ramp is followed without the lag of a bias entry, whose random walk (sigma_f) must be wide
enough to chase it. The rates R (k, N) of the k drift entries are the state of one part,
`DriftJump`, which wraps the filter's jump slot (factory._typed) because the jump slot already
sees every event a rate must follow: the step's start (the ramp and the walk, applied before the
jump so its amplitudes and sentinels see them), mode changes (a new drift fault proposes a
rate, an exit or a hand-over to another type zeroes it), resampling (`resample_modes`: the
rates are permuted with the particles), `pin` (mode-0 rates are 0) and a fresh cloud
(`reinitialise`). Its answer to the user (`annotate`) is the rate, the mean over the mode-1
particles; the fault estimate stays the offset.

A new drift fault's rate (a sentinel, or a hand-over from another type of the item): for a share
WINDOW_SHARE of the particles, N(b, se^2) with b the least-squares slope of the row's offset
y_r - h_r z_bar over the last few seconds and se its standard error (`OffsetSlope`); for the rest
r = a / T, a the entry's offset from the fault-free value (the predicted amplitude A, less the
mode-0 drift under parts.mode0 = "drift"), T log-uniform on [T_MIN_S, T_MAX_S]: the ramp has been
running for T seconds when the offset it built is seen. No importance term: like the amplitude of
a thesis sentinel, the proposal is taken as the prior.

In mode 1 the offset and the rate are corrected by the constant-rate tracker's own gains
(`DriftCorrection`, `alpha_beta`), not by the cloud's Kalman gain, so a particle's wrong rate
shows in its likelihood instead of being hidden by its offset's correction.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from fdir_service.estimation.jump import JumpWrapper
from fdir_service.estimation.layout import N_AIRFRAME, FaultLayout
from fdir_service.estimation.measurement import state_gain

if TYPE_CHECKING:
    from fdir_service.estimation.base import StepOutput
    from fdir_service.estimation.frame import Frame

T_MIN_S = 1.0
"""Shortest age (s) a new drift fault's ramp is assumed to have when it is proposed."""
T_MAX_S = 30.0
"""Longest age (s): a ramp seen only after half a minute is slower than any walk tells apart."""
WINDOW_SHARE = 0.5
"""With an `OffsetSlope` window: the share of new rates drawn around its slope (the rest offset / T)."""


def drift_entries(layout: FaultLayout) -> np.ndarray:
    """(k,) indices of the layout's drift entries."""
    return np.array([j for j in range(layout.nf) if layout.type_of(j) == "drift"], dtype=int)


class OffsetSlope:
    """The slope (SI / s) of each drift row's offset a = y_r - h_r z_bar (z_bar the cloud's mean
    airframe state) over the last `frames` frames, by least squares, and its standard error: the
    rate a new drift fault is proposed around (`DriftJump`, proposal "slope").

    rows (k,): the drift entries' measurement rows; H (m, n): the measurement matrix; frames: the
    window length (frames).
    """

    def __init__(self, rows: np.ndarray, H: np.ndarray, frames: int) -> None:
        self.rows = np.asarray(rows, dtype=int)
        self.h = np.asarray(H, dtype=float)[self.rows, :N_AIRFRAME]            # (k, 5)
        self.t = np.full(int(frames), np.nan)
        self.a = np.full((self.rows.size, int(frames)), np.nan)
        self.k = 0

    def observe(self, X: np.ndarray, w: np.ndarray, frame: Frame) -> None:
        """Store this frame's offsets (NaN where the row did not arrive); X (n, N), w (N,)."""
        present = frame.mask[self.rows]
        y = np.full(self.rows.size, np.nan)
        y[present] = frame.yv[frame.row_of[self.rows[present]]]
        i = self.k % self.t.size
        self.t[i] = frame.t
        self.a[:, i] = y - self._reference(X, w, frame)
        self.k += 1

    def _reference(self, X: np.ndarray, w: np.ndarray, frame: Frame) -> np.ndarray:
        """(k,) what each row's offset is taken against: h_r z_bar, the cloud's mean state's reading."""
        return self.h @ (X[:N_AIRFRAME] @ w)

    def slope(self) -> tuple[np.ndarray, np.ndarray]:
        """((k,) slopes, (k,) their standard errors); 0 and inf with fewer than 3 samples."""
        ok = np.isfinite(self.a) & np.isfinite(self.t)
        n = ok.sum(axis=1)
        t = np.where(ok, self.t, 0.0)
        a = np.where(ok, self.a, 0.0)
        nn = np.maximum(n, 1)
        dt = np.where(ok, t - (t.sum(axis=1) / nn)[:, None], 0.0)
        da = np.where(ok, a - (a.sum(axis=1) / nn)[:, None], 0.0)
        stt = (dt * dt).sum(axis=1)
        good = (n >= 3) & (stt > 0)
        b = np.divide((dt * da).sum(axis=1), stt, out=np.zeros(n.size), where=good)
        res = np.where(ok, da - b[:, None] * dt, 0.0)
        var = (res * res).sum(axis=1) / np.maximum(n - 2, 1)
        se = np.sqrt(np.divide(var, stt, out=np.full(n.size, np.inf), where=good))
        return b, se


class ClimbOffsetSlope(OffsetSlope):
    """An `OffsetSlope` whose altimeter rows take their offset against the climb the u, w and theta
    readings integrate to, a = y_r - integral of (u sin(theta) - w cos(theta)) dt, not against the
    cloud's altitude (parts.drift_window = "climb"): a barometer ramp bends the cloud's altitude
    towards it, and its slope against that altitude is only what the bending left. Fault-free this
    offset's change over 3-10 s spreads 1.4-1.6 m (the barometer's own noise) and the readings'
    climb is 0.016 m/s off on average (real-drift, docs/faults.md, "Stays ambiguous"). Other rows
    are as `OffsetSlope`'s.

    Two guards (stop 50): the attitude in the climb is the reading less the cloud's mean additive
    offset of its item (`attitude_entries`: bias, stuck, drift; a stuck reading's entry is the
    offset that holds it, so the cloud's attitude is used then), so an attitude ramp the cloud has
    taken does not climb; and an altimeter offset that steps by more than `STEP_SIGMAS` of its
    row's noise from the mean of its last `STEP_FRAMES` offsets restarts that row's window, so a
    ramp's step back at its end is not read as a slope. Measured, not a default: real-drift 24
    false alarms against the offset window's 21 (31 without the guards, stop 48), real-engine 9
    against 5 (docs/faults.md, "Stays ambiguous").

    velocity (3,): the rows of u, w and theta among the measurement rows; attitude_entries: the
    fault entries (indices into the faults) whose offset adds to the theta row; row_sigma (k,):
    the drift rows' noise (SI)."""

    STEP_SIGMAS = 5.0
    STEP_FRAMES = 5

    def __init__(self, rows: np.ndarray, H: np.ndarray, frames: int, velocity: tuple[int, int, int],
                 dt: float, attitude_entries: np.ndarray | None = None,
                 row_sigma: np.ndarray | None = None) -> None:
        super().__init__(rows, H, frames)
        self.altimeter = self.h[:, 0] != 0.0
        self.velocity = tuple(int(r) for r in velocity)
        self.dt = float(dt)
        entries = [] if attitude_entries is None else attitude_entries
        self.attitude = N_AIRFRAME + np.asarray(entries, dtype=int)
        self.step = (None if row_sigma is None
                     else self.STEP_SIGMAS * np.where(self.altimeter, np.asarray(row_sigma, float), np.inf))
        """(k,) the offset step (SI) that restarts a row's window; None: never (inf: not an altimeter)."""
        self.climb = 0.0
        """m: the integral of the readings' climb rate since the first frame."""
        self.last_rate = 0.0

    def observe(self, X: np.ndarray, w: np.ndarray, frame: Frame) -> None:
        """As `OffsetSlope.observe`; a row whose new offset steps restarts its window first."""
        if self.step is None or self.k == 0:
            return super().observe(X, w, frame)
        i = self.k % self.t.size                                   # the slot this frame fills
        last = [(i - 1 - j) % self.t.size for j in range(min(self.STEP_FRAMES, self.k))]
        prior = self.a[:, last]
        seen = np.isfinite(prior).sum(axis=1)
        recent = np.where(seen > 0, np.where(np.isfinite(prior), prior, 0.0).sum(axis=1)
                          / np.maximum(seen, 1), np.nan)
        super().observe(X, w, frame)
        jumped = np.abs(self.a[:, i] - recent) > self.step
        if jumped.any():
            keep = self.a[jumped, i]
            self.a[jumped] = np.nan
            self.a[jumped, i] = keep

    def _climb_rate(self, frame: Frame, X: np.ndarray, w: np.ndarray) -> float:
        """u sin(theta) - w cos(theta) of this frame's readings (m/s), theta less the cloud's mean
        offset of its item; the last one where a reading is missing."""
        if all(frame.mask[r] for r in self.velocity):
            u, vw, th = (frame.yv[frame.row_of[r]] for r in self.velocity)
            if self.attitude.size:
                th = th - float(X[self.attitude].sum(axis=0) @ w)
            self.last_rate = float(u * np.sin(th) - vw * np.cos(th))
        return self.last_rate

    def _reference(self, X: np.ndarray, w: np.ndarray, frame: Frame) -> np.ndarray:
        """The altimeter rows' reference is the readings' climb (h[:, 0] = -1: the altitude -p_d);
        the other rows' the cloud's, as `OffsetSlope`'s."""
        self.climb += self.dt * self._climb_rate(frame, X, w)
        cloud = super()._reference(X, w, frame)
        return np.where(self.altimeter, -self.h[:, 0] * self.climb, cloud)


class DriftAnchor:
    """A drift that ends re-anchors the state (as a stuck sensor's return does,
    `fault_types.TypeSwitch.anchor`): half the particles whose drift entry leaves mode 1 with no
    other type of its item taking over, and whose reading has come back (it no longer carries half
    the drift's offset), move their airframe state so that the row predicts this frame's reading,
    x += g_r d, g_r = h_r^T / |h_r|^2, d the row's innovation with the drift's offset taken out.
    During a ramp the reading still carries the offset, and an exit does not move the state.
    While the ramp ran, the state took part of it (the altitude the autopilot then flew); without
    this, the returning barometer disagreed with that state and was declared again (most false
    alarms after a barometer ramp).

    rows (k,): the drift entries' rows; H (m, n): the measurement matrix; siblings (k, nf) bool:
    the other entries of each drift entry's item.
    """

    def __init__(self, rows: np.ndarray, H: np.ndarray, siblings: np.ndarray) -> None:
        self.rows = np.asarray(rows, dtype=int)
        self.G = state_gain(np.asarray(H, dtype=float), self.rows)             # (5, k)
        self.siblings = np.asarray(siblings, dtype=float)

    def innovation(self, X: np.ndarray, frame: Frame) -> np.ndarray:
        """(k, N) y_r - H_r x before the jump (0 where the row did not arrive)."""
        present = frame.mask[self.rows]
        e = np.zeros((self.rows.size, X.shape[1]))
        if present.any():
            ri = frame.row_of[self.rows[present]]
            e[present] = frame.yv[ri, None] - frame.mm.H[ri] @ X
        return e

    def apply(self, X: np.ndarray, dist: np.ndarray, offset: np.ndarray, left: np.ndarray,
              modes: np.ndarray, rng: np.random.Generator) -> None:
        """X[:5] += G d (in place) for half the particles that left (k, N) with their item free and
        whose reading has come back: |d| < |offset| / 2, offset (k, N) the drift they dropped."""
        if not left.any():
            return
        taken = (self.siblings @ modes) > 0                                   # (k, N)
        back = np.abs(dist) < 0.5 * np.abs(offset)
        go = left & ~taken & back & (rng.random(left.shape) < 0.5)
        X[:N_AIRFRAME] += self.G @ np.where(go, dist, 0.0)


RATE_LOG_WEIGHT_FLOOR = -20.0
"""The lowest log-weight a new rate takes (a rate its proposal could not have drawn)."""


def rate_log_weight(r: np.ndarray, offset: np.ndarray, log_prior: np.ndarray,
                    window: tuple[np.ndarray, np.ndarray] | None) -> np.ndarray:
    """log p(r) - log q(r) (c,) of c new drift rates r (SI / s), at most 0: the Occam factor of a
    rate the data proposed. q is `DriftJump._propose`'s mixture: offset / T with T log-uniform on
    [T_MIN_S, T_MAX_S] (density 1 / (|r| log(T_MAX_S / T_MIN_S)) for |offset| / T_MAX_S <= |r| <=
    |offset| / T_MIN_S of the offset's sign), and with a window (its slopes b and stds s, (c,)
    each) WINDOW_SHARE of N(b, s^2). p is uniform on +-rate_max (log_prior (c,) = -log(2 rate_max)).
    A stuck barometer in a steady climb is a drift at minus the climb rate: the data fit both, but
    a drift had to find that rate among all it might have had, and without this factor it was
    named first in 44 of real-stuck's 100 stuck barometers (docs/faults.md, "Stays ambiguous").
    Capped at 0, as the amplitude's draws are clipped (`sentinels.PriorSentinels`): a rate the
    proposal seldom draws gains nothing by it. Measured, not a default: with it the stuck
    barometer is named right in 72 of 100 (51), but a young ramp is as specific, and real-drift's
    drift is named right in 0.58 (0.91) with 39 false alarms (21) (docs/faults.md, stop 50)."""
    mag = np.abs(r)
    inside = (np.sign(r) == np.sign(offset)) & (mag >= np.abs(offset) / T_MAX_S) \
        & (mag <= np.abs(offset) / T_MIN_S) & (mag > 0)
    q = np.where(inside, 1.0 / (np.where(mag > 0, mag, 1.0) * np.log(T_MAX_S / T_MIN_S)), 0.0)
    if window is not None:
        b, s = window
        z = (r - b) / s
        q = (1.0 - WINDOW_SHARE) * q + WINDOW_SHARE * np.exp(-0.5 * z * z) / (np.sqrt(2.0 * np.pi) * s)
    term = np.where(q > 0, log_prior - np.log(np.where(q > 0, q, 1.0)), RATE_LOG_WEIGHT_FLOOR)
    return np.clip(term, RATE_LOG_WEIGHT_FLOOR, 0.0)


class DriftJump(JumpWrapper):
    """A jump part (`jump.MarkovJump`) plus the per-particle rates of the drift entries (module
    docstring). Every attribute it does not define is the inner jump's (`sentinels`,
    `last_amplitude`, `transition`, ...).

    inner: the jump; faults (k,): the drift entries; dt: the frame period (s); rate_sigma (k,):
    the rates' random-walk std (SI / s per sqrt(s)); N: particles.
    """

    def __init__(self, inner, faults: np.ndarray, dt: float, rate_sigma: np.ndarray, N: int,
                 window: OffsetSlope | None = None, anchor: DriftAnchor | None = None,
                 rate_max: np.ndarray | None = None) -> None:
        super().__init__(inner)
        k = np.asarray(faults).size
        r_max = np.full(k, np.nan) if rate_max is None else np.asarray(rate_max, dtype=float)
        self.rate_log_prior = np.where(r_max > 0, -np.log(2.0 * np.where(r_max > 0, r_max, 1.0)), np.nan)
        """(k,) log of a new rate's prior density, uniform on +-rate_max (faults.rate_max, SI / s);
        NaN: no prior, the proposal is taken as one (`rate_log_weight`)."""
        self.anchor = anchor
        self.window = window
        """None: a new rate is offset / T (module docstring); else N(slope, se^2) of the window."""
        self.faults = np.asarray(faults, dtype=int)
        self.dt = float(dt)
        self.walk = np.asarray(rate_sigma, dtype=float)[:, None] * np.sqrt(self.dt)    # (k, 1)
        self.R = np.zeros((self.faults.size, int(N)))
        """(k, N) each drift entry's rate per particle (SI / s); 0 in mode 0."""
        self.rate_if_faulty = np.zeros(self.faults.size)
        """(k,) the weighted mean rate over each entry's mode-1 particles (0 where none is)."""

    def jump(self, X: np.ndarray, modes: np.ndarray, w: np.ndarray, frame: Frame,
             rng: np.random.Generator) -> np.ndarray | None:
        """Ramp the mode-1 drift entries of X (n, N) and walk their rates, then the inner jump
        (in place); new drift faults get a proposed rate, exits and hand-overs lose theirs."""
        js = N_AIRFRAME + self.faults
        on = modes[self.faults]
        if self.window is not None:
            self.window.observe(X, w, frame)
        X[js] += self.R * self.dt
        self.R += self.walk * rng.standard_normal(self.R.shape) * on
        if self.anchor is not None:
            F0 = X[js]
            e = self.anchor.innovation(X, frame)
        lw = self.inner.jump(X, modes, w, frame, rng)
        after = modes[self.faults]
        if self.anchor is not None:
            offset = F0 - X[js]
            self.anchor.apply(X, e + offset, offset, on & ~after, modes, rng)
        new = after & ~on
        self.R *= after
        if new.any():
            offset = self._offset(X[js], new)
            window = self._window_slope(new) if self.window is not None else None
            self.R[new] = self._propose(offset, window, rng)
            lw = self._weigh_rates(lw, offset, window, new, X.shape[1])
        return lw

    def _offset(self, F: np.ndarray, new: np.ndarray) -> np.ndarray:
        """(c,) the new drift faults' offsets from their fault-free value (new (k, N) bool)."""
        drift = getattr(self.inner, "drift", None)
        centre = drift.value[self.faults] if drift is not None else np.zeros(self.faults.size)
        return (F - centre[:, None])[new]

    def _propose(self, offset: np.ndarray, window: tuple[np.ndarray, np.ndarray] | None,
                 rng: np.random.Generator) -> np.ndarray:
        """(c,) rates of the c new drift faults: offset / T, T log-uniform; with a window (its
        `_window_slope`), for WINDOW_SHARE of them N(b, s^2) about its slope b."""
        T = np.exp(rng.uniform(np.log(T_MIN_S), np.log(T_MAX_S), offset.size))
        r = offset / T
        if window is None:
            return r
        b, s = window
        slope = b + s * rng.standard_normal(b.size)
        return np.where(rng.random(b.size) < WINDOW_SHARE, slope, r)

    def _window_slope(self, new: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(c,) the window's slope and proposal std for each new drift fault (new (k, N) bool)."""
        b, se = self.window.slope()
        rows = np.nonzero(new)[0]
        return b[rows], np.minimum(se[rows], np.abs(b[rows]) + 1e-12)

    def _weigh_rates(self, lw: np.ndarray | None, offset: np.ndarray,
                     window: tuple[np.ndarray, np.ndarray] | None, new: np.ndarray,
                     N: int) -> np.ndarray | None:
        """lw (N,) (None: zeros) plus each new drift fault's `rate_log_weight` where its entry has
        a prior (faults.rate_max); lw unchanged where none has."""
        rows, cols = np.nonzero(new)
        log_p = self.rate_log_prior[rows]
        has = np.isfinite(log_p)
        if not has.any():
            return lw
        term = rate_log_weight(self.R[new], offset, log_p, window)
        out = np.zeros(N) if lw is None else lw
        np.add.at(out, cols[has], term[has])
        return out

    def pin(self, X: np.ndarray, modes: np.ndarray) -> None:
        """The inner pin; mode-0 rates to 0 (in place)."""
        self.inner.pin(X, modes)
        self.R *= modes[self.faults]

    def reinitialise(self, modes: np.ndarray) -> None:
        """A fresh cloud (modes (nf, N)): each mode-1 particle takes the last mean rate."""
        self.inner.reinitialise(modes)
        self.R = self.rate_if_faulty[:, None] * modes[self.faults]

    def resample_modes(self, modes: np.ndarray, idx: np.ndarray) -> np.ndarray:
        """The inner's resampled modes; the rates follow their particles (idx (N,))."""
        self.R = np.take(self.R, idx, axis=1)
        return self.inner.resample_modes(modes, idx)

    def fault_probability(self, X: np.ndarray, modes: np.ndarray, w: np.ndarray) -> np.ndarray:
        """The inner's P(mode 1) (nf,); keeps each drift entry's mean rate over its mode-1 particles."""
        p = self.inner.fault_probability(X, modes, w)
        wm = modes[self.faults] * w                                     # (k, N)
        s = wm.sum(axis=1)
        self.rate_if_faulty = np.divide((wm * self.R).sum(axis=1), s, out=np.zeros_like(s),
                                        where=s > 1e-12)
        return p

    def annotate(self, out: StepOutput) -> None:
        """The inner's annotations; a drift entry's fault_value is its rate (SI / s)."""
        self.inner.annotate(out)
        value = out.fault_value if out.fault_value is not None else out.fault_estimate.copy()
        value[self.faults] = self.rate_if_faulty
        out.fault_value = value


def alpha_beta(rate_sigma: np.ndarray, row_sigma: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Steady-state gains (alpha, beta) (k,) of the constant-rate tracker f+ = f + r dt, r+ = r + w,
    w ~ N(0, rate_sigma^2 dt), observed as y = f + v, v ~ N(0, row_sigma^2) (Kalata's tracking
    index lam = sigma_a dt^2 / row_sigma with sigma_a = rate_sigma / sqrt(dt) the per-step rate
    change over dt): f += alpha e, r += beta e / dt for an innovation e."""
    lam = np.asarray(rate_sigma, dtype=float) * dt ** 1.5 / np.asarray(row_sigma, dtype=float)
    root = np.sqrt(lam * lam + 8.0 * lam)
    alpha = -(lam * lam + 8.0 * lam - (lam + 4.0) * root) / 8.0
    beta = (lam * lam + 4.0 * lam - lam * root) / 4.0
    return alpha, beta


class DriftCorrection:
    """A correction part that corrects the drift rates as well as their offsets: the inner
    correction moves each particle's offset f (the cloud's Kalman gain, eq. 5.3-5.9); each mode-1
    particle's rate moves by beta e / dt, e = y_r - h_r x its innovation on the entry's row before
    the correction, beta the steady-state gain of the constant-rate tracker (`alpha_beta`). A
    particle whose offsets keep lagging the data learns a faster rate; without this the rates
    were only selected by the weights, which the offsets' own correction leaves nearly blind
    (0.1 deg/s learnt of a 0.5 deg/s attitude ramp after 5 s).

    inner: the correction; rates: the `DriftJump` whose R (k, N) it moves; rows (k,): each drift
    entry's measurement row; row_sigma (k,): their noise (SI).
    """

    def __init__(self, inner, rates: DriftJump, rows: np.ndarray, row_sigma: np.ndarray) -> None:
        self.inner = inner
        self.rates = rates
        self.rows = np.asarray(rows, dtype=int)
        self.entries = N_AIRFRAME + rates.faults
        alpha, beta = alpha_beta(rates.walk[:, 0] / np.sqrt(rates.dt), row_sigma, rates.dt)
        self.alpha = alpha
        self.gain = beta / rates.dt                                      # (k,) 1/s

    def update(self, X: np.ndarray, w: np.ndarray, modes: np.ndarray, frame: Frame) -> np.ndarray:
        present = frame.mask[self.rows]
        if not present.any():
            return self.inner.update(X, w, modes, frame)
        ri = frame.row_of[self.rows[present]]
        e = frame.yv[ri, None] - frame.mm.H[ri] @ X                      # (k', N)
        on = modes[self.rates.faults[present]]
        self.rates.R[present] += self.gain[present, None] * e * on
        F0 = X[self.entries[present]]
        ll = self.inner.update(X, w, modes, frame)
        js = self.entries[present]
        X[js] = np.where(on, F0 + self.alpha[present, None] * e, X[js])
        return ll
