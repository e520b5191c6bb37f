"""Jump parts: per-fault two-mode Markov chain of the jump-Markov filters (thesis Alg. 4.1, eq. 4.11-4.12).

Each particle carries a mode per fault (False = m(0) fault-free, True = m(1) faulty). With one
uniform v per particle and fault: mode 0 -> 1 if v < pi01, and the fault entry is set to the
predicted amplitude A (the particle becomes a "sentinel"); mode 1 -> 0 if v < pi10, and the fault
entry is set to 0. In "forced_zero" handling (JMRPF, thesis ch. 4) every mode-0 entry is 0; in
"reset_on_exit" (thesis 5.5.2) mode-0 entries evolve freely and are only zeroed on 1 -> 0.

Parts (one slot of a recipe, see recipes.py): `NoJump` (filters without modes) and `MarkovJump`
(a transition strategy: `FixedTransition` or `adaptive.AdaptiveTransition`, an amplitude
predictor, and an `ActuatorCarry` that moves an actuator sentinel's airframe state with its fault).
Each part also answers how modes are resampled, pinned and turned into fault probabilities.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from fdir_service.estimation.amplitude import AmplitudePredictor
from fdir_service.estimation.base import StepOutput
from fdir_service.estimation.gyro_unwind import NoUnwind
from fdir_service.estimation.kernels import (
    any_related,
    arm_folds,
    exit_folds,
    faint_exit_pi10,
    jump_entries,
    mode0_weights,
    share_means,
)
from fdir_service.estimation.layout import N_AIRFRAME
from fdir_service.estimation.measurement import state_gain

if TYPE_CHECKING:
    from fdir_service.estimation.frame import Frame

MODE0_HANDLING = ("forced_zero", "reset_on_exit")


def transition_matrices(pi01: np.ndarray, pi10: np.ndarray) -> np.ndarray:
    """(nf, 2, 2) matrices [[pi00, pi01], [pi10, pi11]] from per-fault pi01, pi10 (nf,)."""
    pi01 = np.asarray(pi01, dtype=float)
    pi10 = np.asarray(pi10, dtype=float)
    T = np.empty(pi01.shape + (2, 2))
    T[..., 0, 0] = 1.0 - pi01
    T[..., 0, 1] = pi01
    T[..., 1, 0] = pi10
    T[..., 1, 1] = 1.0 - pi10
    return T


class FixedTransition:
    """The thesis's fixed transition matrix: pi01, pi10 per fault (scalars: the same for all), every step."""

    adaptive = False
    proposal = False
    """Never a proposal: the jump's matrix is the model's (see `adaptive.AdaptiveTransition`)."""

    def __init__(self, pi01: np.ndarray | float, pi10: np.ndarray | float, nf: int) -> None:
        self.pi01 = np.broadcast_to(np.asarray(pi01, dtype=float), (nf,)).copy()
        self.pi10 = np.broadcast_to(np.asarray(pi10, dtype=float), (nf,)).copy()

    def matrices(self) -> np.ndarray:
        """(nf, 2, 2) transition matrices in force."""
        return transition_matrices(self.pi01, self.pi10)

    def observe(self, A: np.ndarray, F: np.ndarray, modes: np.ndarray, w: np.ndarray) -> None:
        """Fixed: nothing to learn from the cloud."""

    def log_weight_correction(self, before: np.ndarray | None, after: np.ndarray,
                              available: np.ndarray) -> None:
        """Fixed: the jump draws from the model's own matrix, no importance correction."""
        return None

    def annotate(self, out: StepOutput) -> None:
        """Fixed: nothing to add to the step's output."""


def jump(F: np.ndarray, modes: np.ndarray, amplitude: np.ndarray, available: np.ndarray,
         pi01: np.ndarray, pi10: np.ndarray, v: np.ndarray, forced_zero: bool = True,
         reset_to: np.ndarray | None = None) -> np.ndarray:
    """Apply Alg. 4.1 in place to fault entries F (nf, N) and modes (nf, N) bool.

    amplitude (nf, N): predicted fault amplitude per particle (A_f, eq. 4.14/4.16); available (nf,)
    bool: False where no amplitude could be predicted this frame (its measurement rows did not
    arrive), then no particle enters mode 1 for that fault (or (nf, N) per particle: a particle
    whose item has another type in mode 1 cannot enter, `fault_types.ItemExclusion`); pi01 (nf,),
    pi10 (nf,) or per particle (nf, N) (`FaintExit`); v (nf, N) ~ U(0, 1); reset_to (nf,): what an
    exit's fault entry becomes when not forced_zero (None: 0).
    Returns the sentinels (nf, N) bool: the particles that jumped 0 -> 1 this step.
    """
    may = available[:, None] if available.ndim == 1 else available
    exits = pi10[:, None] if pi10.ndim == 1 else pi10
    reset = np.zeros(modes.shape[0]) if reset_to is None else reset_to
    return jump_entries(F, modes, amplitude, may, pi01, exits, v, bool(forced_zero), reset)


def mode0_mean(F: np.ndarray, modes: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """((nf,) weighted mean of each fault entry over the particles in its mode 0 (0 where none is),
    (nf,) their share of the weight): the sensor's fault-free error as the cloud knows it
    (parts.mode0 = "drift"). F, modes (nf, N), w (N,) weights."""
    w0 = mode0_weights(modes, w)
    total = w0.sum(axis=1)
    return share_means(np.einsum("jn,jn->j", w0, F), total, float(w.sum()))


class DriftMemory:
    """The fault-free value of each fault entry, for exits to return to (parts.mode0 = "drift"):
    the mode-0 particles' mean, updated only while mode 0 holds most of the weight. During a fault
    the few mode-0 particles left are no estimate of the drift (an elevator's 0.9 deg of mis-trim
    in a dispersed airframe was lost, and after the fault mode 1, which still held it, won)."""

    def __init__(self, nf: int) -> None:
        self.value = np.zeros(nf)
        self.rollback: MemoryRollback | None = None
        """None, or the `MemoryRollback` of parts.fault_free_rollback_s."""

    def update(self, F: np.ndarray, modes: np.ndarray, w: np.ndarray) -> np.ndarray:
        """Take this step's mode-0 means where mode 0 has > half the weight; returns value (nf,)."""
        mean, share = mode0_mean(F, modes, w)
        return self._take(mean, share > 0.5)

    def _take(self, mean: np.ndarray, live: np.ndarray) -> np.ndarray:
        """value <- mean (nf,) where live (nf,) bool, after any rollback of the entries that froze."""
        if self.rollback is not None:
            self.rollback.before(self.value, live)
        np.copyto(self.value, mean, where=live)
        if self.rollback is not None:
            self.rollback.after(self.value)
        return self.value


class MemoryRollback:
    """The fault-free value as it was `steps` frames before it froze (parts.fault_free_rollback_s).

    The value follows its fault-free particles' mean until they fall below half the weight, which
    happens only once the fault's hypothesis has won. Until then those particles' drift absorbed
    part of the fault: an engine's lost thrust moved the throttle's value by 0.06 in the 1.5 s
    before the engine's hypothesis won (real-engine run 44), and every exit after the fault
    returned there. An entry whose value freezes takes back the value it had `steps` frames before.
    The cost: the sensor's true slow error over those frames (drift_sigma sqrt(steps dt)) is lost.
    """

    def __init__(self, nf: int, steps: int, entries: np.ndarray | None = None) -> None:
        self.past = np.zeros((int(steps), nf))
        """Ring of the last `steps` values (nf,), the oldest at `k`."""
        self.k = 0
        self.live = np.zeros(nf, dtype=bool)
        """(nf,) bool: the entries that followed their mean last step."""
        self.entries = np.ones(nf, dtype=bool) if entries is None else np.asarray(entries, dtype=bool)
        """(nf,) bool: the entries that roll back (the others freeze where they are)."""

    def before(self, value: np.ndarray, live: np.ndarray) -> None:
        """Roll back, in place, the entries of value (nf,) that freeze this step (live (nf,) bool)."""
        froze = self.live & ~live & self.entries
        if froze.any():
            np.copyto(value, self.past[self.k], where=froze)
        self.live = live

    def after(self, value: np.ndarray) -> None:
        """Keep this step's value (nf,)."""
        self.past[self.k] = value
        self.k = (self.k + 1) % self.past.shape[0]


class ItemDriftMemory(DriftMemory):
    """A `DriftMemory` kept from the particles whose whole item is fault-free (parts.fault_free_memory
    = "item"): a particle that holds another type of the entry's item in mode 1 (a stuck or blocked
    reading) leaves this entry in mode 0 but unobserved, and its value is no estimate of the
    sensor's fault-free error. The pitot's wind entry of a blocked particle wanders with the gust
    model; at an engine's return in real-engine run 63 those winds made the memory's airspeed
    42.3 m/s where the pitot read 40. Measured, not a default: real-engine 5 -> 6 false alarms,
    real-pitot 3 -> 3, real-stuck 4 -> 2 (docs/faults.md, "The held airspeed after a let-go");
    real-actuators 10 -> 21, real-drift 21 -> 17 (stop 51, "The fault-free value by item"). The
    inputs' by item, with a `MemoryRollback`, is the catalogue's since stop 52 ("The fault-free
    value from before the onset": real-actuators 12 -> 1).

    item (nf, nf): 1 where two entries are on the same item (a measurement row or an input), the
    diagonal included; an entry whose row is the identity's is kept by its own mode, as in
    `DriftMemory` (parts.fault_free_memory = "input_item": the inputs by item, the rows by entry)."""

    def __init__(self, item: np.ndarray) -> None:
        super().__init__(item.shape[0])
        self.item = np.asarray(item, dtype=float)

    def update(self, F: np.ndarray, modes: np.ndarray, w: np.ndarray) -> np.ndarray:
        """Take this step's item-fault-free means where those particles have > half the weight."""
        mean, share = mode0_mean(F, any_related(self.item, modes), w)    # (item @ modes) > 0
        return self._take(mean, share > 0.5)


class NoCarry:
    """Actuator sentinels keep their airframe state (parts.actuator_sentinel = "thesis")."""

    def capture(self, F: np.ndarray) -> None:
        return None

    def apply(self, X: np.ndarray, F: np.ndarray, before: None) -> None:
        """Nothing moves."""


class ActuatorCarry:
    """An actuator fault entry that jumps by dF moves its particle's airframe state by B_a dF: the
    amplitude is the fault that acted over the last frame (eq. 4.13), so the sentinel is weighted
    on this frame's data as it stands (parts.actuator_sentinel = "consistent").

    columns (k,): fault indices of the actuator faults; B (5, k): their one-frame airframe response.
    """

    def __init__(self, columns: np.ndarray, B: np.ndarray) -> None:
        self.columns = np.asarray(columns, dtype=int)
        self.B = np.asarray(B, dtype=float)
        self.index = {int(j): k for k, j in enumerate(self.columns)}
        """fault index -> column of B."""

    def capture(self, F: np.ndarray) -> np.ndarray:
        """The actuator fault entries (k, N) before the jump."""
        return F[self.columns]                    # an index array: a copy already

    def apply(self, X: np.ndarray, F: np.ndarray, before: np.ndarray) -> None:
        """X[:5] += B (F_act - before), in place."""
        dF = F[self.columns] - before
        X[:N_AIRFRAME] += self.B @ dF


class ExitFold:
    """On a 1 -> 0 exit, half the exiting particles (v < pi10 / 2) fold their sensor fault into the
    airframe state instead of dropping it (faults.on_exit = "reset_or_fold"): x += G f, so the
    sensor's prediction is unchanged and it is the state that was wrong. The other half reset f to
    its fault-free value (0, or the `DriftMemory` under mode0 = "drift": the fault ended).
    Without the fold a state error that a sensor's fault took the blame for (the altitude after a
    gyro fault, say) can never leave mode 1: every exit mispredicts that sensor by f.

    G (5, nf): per fault, the minimum-norm airframe change moving its row's prediction by f
    (H_r^T / |H_r|^2 on the airframe part of row r); zero columns for faults that do not fold.
    """

    def __init__(self, G: np.ndarray, arming: FoldArming | None = None) -> None:
        self.G = np.asarray(G, dtype=float)
        self.columns = np.flatnonzero(np.abs(self.G).sum(axis=0) > 0)
        self._G = self.G[:, self.columns]
        self._every = np.ones(self.G.shape[1], dtype=bool)
        self._zero = np.zeros(self.G.shape[1])
        self.arming = arming
        """None (every folding fault may fold), or the `FoldArming` of faults.fold_after."""

    def observe(self, modes: np.ndarray, w: np.ndarray) -> None:
        """Before `capture`, each step: the cloud's modes (nf, N) and prior weights (N,)."""
        if self.arming is not None:
            self.arming.observe(modes, w)

    @classmethod
    def for_sensors(cls, H: np.ndarray, sensor_row: np.ndarray, arming: FoldArming | None = None) -> ExitFold:
        """From the measurement matrix H (m, n) and each fault's row (nf,), -1 for actuators."""
        return cls(state_gain(H, sensor_row), arming)

    def capture(self, F: np.ndarray, modes: np.ndarray, v: np.ndarray, pi10: np.ndarray,
                reset_to: np.ndarray | None = None) -> np.ndarray | None:
        """pi10 (nf, 1) or (nf, N): the exit probabilities of this step; reset_to (nf,): what the
        exit leaves in the fault entry (None: 0), so the fold moves the state by the rest. The fault
        values (k, N) of the folding faults' particles that will fold (0 elsewhere),
        or None when none folds this step."""
        armed = self._every if self.arming is None else self.arming.armed
        values, anyone = exit_folds(F, modes, v, pi10, self.columns, armed,
                                    self._zero if reset_to is None else reset_to)
        return values if anyone else None

    def apply(self, X: np.ndarray, values: np.ndarray | None) -> None:
        """X[:5] += G values, in place (after the jump zeroed the exited entries)."""
        if values is not None:
            X[:N_AIRFRAME] += self._G @ values


_FAR = np.iinfo(np.int64).max // 4
"""A step count that stands for "never" (and does not overflow when counted on)."""


class FoldArming:
    """Folds that wait for another sensor's fault (faults.fold_after): a gated fault folds only
    while its own declaration is young (its item's P rose past 0.5 at most `young` steps ago) or
    within `window` steps of a step where the entries of its fold_after row held P >= 0.5.

    The attitude state is the integral of the gyro-pinned pitch rate, so it is only far off after
    the gyro was. While a gyro fault builds up unseen the attitude sensor takes the blame, and its
    folds keep the attitude on the sensor (the blame is young); once the gyro is declared they fold
    the attitude it left wrong. A standing attitude-sensor fault no longer folds after its first
    seconds: with every exit free to fold, a 7-deg fault put a few percent of the cloud 7 deg off,
    which until the altimeters and the velocities disowned them (about 1 s) tied the attitude to the
    altitude in the cloud's covariance; the Kalman gain turned altimeter noise into every particle's
    attitude, the crowd's attitude was 1 deg off when the fault ended, and a new attitude fault was
    declared (docs/robustness.md, "Attitude folds that wait for the gyro").

    gated (k,) fault indices; arming, own: per gated fault, the entry indices of its fold_after
    row and of its own item; window, young (k,) steps.
    """

    def __init__(self, nf: int, gated: np.ndarray, arming: list[np.ndarray], own: list[np.ndarray],
                 window: np.ndarray, young: np.ndarray) -> None:
        self.gated = np.asarray(gated, dtype=int)
        self.arming = [np.asarray(a, dtype=int) for a in arming]
        self.own = [np.asarray(o, dtype=int) for o in own]
        self.window = np.asarray(window, dtype=np.int64)
        self.young = np.asarray(young, dtype=np.int64)
        self.since_arming = np.full(self.gated.size, _FAR, dtype=np.int64)
        """Steps since each gated fault's fold_after entries last held P >= 0.5."""
        self.blamed_for = np.full(self.gated.size, _FAR, dtype=np.int64)
        """Steps since each gated fault's own item last rose past P = 0.5 (far while below)."""
        self.armed = np.ones(nf, dtype=bool)
        """(nf,) bool: the faults that may fold this step."""
        if max((a.size for a in self.arming + self.own), default=0) >= 8:
            raise ValueError("fold_after: at most 7 entries per row or item")   # numpy's in-order sum
        self._flat = tuple(x for lists in (self.arming, self.own)
                           for x in (np.concatenate(lists + [np.zeros(0, dtype=int)]),
                                     np.cumsum([a.size for a in lists], dtype=np.int64)))
        """(arming entries, their ends per gated fault, own entries, their ends) for `kernels.arm_folds`."""

    def observe(self, modes: np.ndarray, w: np.ndarray) -> None:
        """Update `armed` from the modes (nf, N) and prior weights (N,) of this step."""
        arm_folds(modes @ w, *self._flat, self.since_arming, self.blamed_for, self.window,
                  self.young, self.gated, self.armed, _FAR)


class NoFold:
    """Every 1 -> 0 exit resets its fault entry (faults.on_exit = "reset", the thesis)."""

    def observe(self, modes: np.ndarray, w: np.ndarray) -> None:
        """Nothing folds: nothing to watch."""

    def capture(self, F: np.ndarray, modes: np.ndarray, v: np.ndarray, pi10: np.ndarray,
                reset_to: np.ndarray | None = None) -> None:
        return None

    def apply(self, X: np.ndarray, values: None) -> None:
        """Nothing moves."""


class ModelExit:
    """A mode-1 particle exits with the transition's pi10, whatever its fault entry (the thesis)."""

    def pi10(self, F: np.ndarray, pi10: np.ndarray, center: np.ndarray | None = None) -> np.ndarray:
        """(nf, 1) exit probabilities of this step."""
        return pi10[:, None]


class FaintExit:
    """A mode-1 fault entry fainter than one frame's amplitude noise (|f| < threshold) exits at
    rate (per step) instead of pi10 (parts.pi10_faint). The Kalman correction lets a mode-1 entry
    follow its sensor back towards 0 when a fault ends; a fault of ~0 fits the data as well as
    mode 0, so with the model's pi10 alone P(fault) would decay at pi10 per step (0.01: 2 s to
    halve) and the service would clear seconds late. A fault no frame could tell from noise is not
    one to declare. threshold (nf,) SI: the amplitude predictor's sigma.
    """

    def __init__(self, threshold: np.ndarray, rate: float) -> None:
        self.threshold = np.asarray(threshold, dtype=float)[:, None]
        self.rate = float(rate)
        self._threshold = self.threshold[:, 0].copy()
        self._zero = np.zeros(self._threshold.size)

    def pi10(self, F: np.ndarray, pi10: np.ndarray, center: np.ndarray | None = None) -> np.ndarray:
        """(nf, N) exit probabilities of this step for fault entries F (nf, N), faint when within
        threshold of center (nf,): the fault-free value (None: 0; the drift under mode0 = "drift")."""
        return faint_exit_pi10(F, self._zero if center is None else center, self._threshold, pi10,
                               self.rate)


class JumpWrapper:
    """A jump part around another, `inner`: every attribute it does not define is the inner's
    (`drift_type.DriftJump`, `held_mean.HeldCount`)."""

    def __init__(self, inner) -> None:
        self.inner = inner

    def __getattr__(self, name: str):
        if name == "inner":                     # not set yet (copy, pickle): no recursion
            raise AttributeError(name)
        return getattr(self.inner, name)


class NoJump:
    """Filters without modes (RPF, RRPF, bootstrap): P(fault j) = weight of |f_j| > threshold_j.

    fault_threshold (nf,) SI (3 sigma of the fault's residual).
    """

    def __init__(self, fault_threshold: np.ndarray) -> None:
        self.fault_threshold = np.asarray(fault_threshold, dtype=float)
        self.sentinels = np.zeros((self.fault_threshold.size, 0), dtype=bool)

    def jump(self, X: np.ndarray, modes: np.ndarray, w: np.ndarray, frame: Frame,
             rng: np.random.Generator) -> None:
        """No modes: nothing jumps; no log-weight term."""
        return None

    def pin(self, X: np.ndarray, modes: np.ndarray) -> None:
        """No modes: fault entries are free."""

    def resample_modes(self, modes: np.ndarray, idx: np.ndarray) -> np.ndarray:
        return modes

    def reinitialise(self, modes: np.ndarray) -> None:
        """A fresh cloud: nothing held per particle."""

    def fault_probability(self, X: np.ndarray, modes: np.ndarray, w: np.ndarray) -> np.ndarray:
        return (np.abs(X[N_AIRFRAME:]) > self.fault_threshold[:, None]) @ w

    def annotate(self, out: StepOutput) -> None:
        """Nothing to add."""


class MarkovJump:
    """The jump step of the jump-Markov filters (Alg. 4.1) with a transition strategy.

    transition: `FixedTransition` | `adaptive.AdaptiveTransition`; amplitude: the A_f predictor;
    forced_zero: mode-0 fault entries pinned at 0 (parts.mode0); carry: `NoCarry` | `ActuatorCarry`;
    fold: what an exit does with a sensor fault, `NoFold` | `ExitFold` (faults.on_exit); exit:
    `ModelExit` | `FaintExit`; a typed estimator adds its `fault_types.TypeSwitch` (`use_types`).
    After `jump`, `sentinels` (nf, N) are the particles that jumped 0 -> 1 and `last_amplitude`
    (nf, N) their predicted amplitudes (indices before this step's resampling).
    """

    def __init__(self, transition, amplitude: AmplitudePredictor, forced_zero: bool, carry,
                 fold=None, exit=None, exit_to_drift: bool = False) -> None:
        self.transition = transition
        self.amplitude = amplitude
        self.forced_zero = bool(forced_zero)
        self.carry = carry
        self.fold = fold or NoFold()
        self.exit = exit or ModelExit()
        self.switch = None
        """None, or a `fault_types.TypeSwitch`: a fault handed to another type of its item."""
        self.exclusion = None
        """None, or the `fault_types.ItemExclusion`: one type per item, parts.exclusive_items."""
        self.unwind = NoUnwind()
        """`gyro_unwind.NoUnwind`, or the `GyroUnwind` of parts.gyro_exit_unwind > 0."""
        self.given_fault = False
        """True (typed estimators): `annotate` sets out.fault_value to each entry's mean over its
        mode-1 particles (what the fault is, if it is one), before `TypedPredict` words it per type."""
        self.fault_if_faulty = np.zeros(amplitude.layout.nf)
        nf = amplitude.layout.nf
        self.drift = DriftMemory(nf) if exit_to_drift else None
        """parts.mode0 = "drift": an exit's entry returns to the fault-free value (`DriftMemory`)."""
        self.sentinels = np.zeros((nf, 0), dtype=bool)
        self.last_amplitude = np.zeros((nf, 0))

    def jump(self, X: np.ndarray, modes: np.ndarray, w: np.ndarray, frame: Frame,
             rng: np.random.Generator) -> np.ndarray | None:
        """Jump the modes and fault entries of X in place; returns the (N,) log-weight term of a
        proposal transition (None for the model's own matrix)."""
        innov = frame.yv[:, None] - frame.mm.H @ X
        gyro_held = self.unwind.before(X, modes, frame)
        self.amplitude.observe(frame)
        A, avail = self.amplitude.predict(X, innov, frame.mask)
        F = X[N_AIRFRAME:]
        self.transition.observe(A, F, modes, w)
        v = rng.random(modes.shape)
        self.last_amplitude = A
        before = modes.copy() if self.transition.proposal else None
        carried = self.carry.capture(F)
        reset_to = self.drift.update(F, modes, w) if self.drift is not None else None
        pi10 = self.exit.pi10(F, self.transition.pi10, reset_to)
        self.fold.observe(modes, w)
        folded = self.fold.capture(F, modes, v, pi10, reset_to)
        anchored = None if self.switch is None else self.switch.anchor(F, modes, v, pi10, innov, frame)
        may = avail if self.exclusion is None else self.exclusion.open(avail, modes)
        self.sentinels = jump(F, modes, A, may, self.transition.pi01, pi10, v, self.forced_zero,
                              reset_to)
        self.carry.apply(X, F, carried)
        self.fold.apply(X, folded)
        self.unwind.after(X, modes, gyro_held, rng)
        if self.switch is not None:
            self.switch.apply_anchor(X, anchored)
            self.switch.apply(F, modes, reset_to, rng)
        return self.transition.log_weight_correction(before, modes, avail)

    def use_types(self, switch) -> None:
        """For an estimator with typed faults (`factory._typed`): the `fault_types.TypeSwitch` (or
        None) and `given_fault` on."""
        self.switch = switch
        self.given_fault = True

    def pin(self, X: np.ndarray, modes: np.ndarray) -> None:
        """Mode-0 fault entries back to 0 (forced_zero), in place."""
        if self.forced_zero:
            X[N_AIRFRAME:] *= modes

    def resample_modes(self, modes: np.ndarray, idx: np.ndarray) -> np.ndarray:
        self.unwind.resample(idx)
        return np.take(modes, idx, axis=1)

    def reinitialise(self, modes: np.ndarray) -> None:
        """A fresh cloud: nothing held per particle (`drift_type.DriftJump` holds rates)."""
        self.unwind.reinitialise()

    def fault_probability(self, X: np.ndarray, modes: np.ndarray, w: np.ndarray) -> np.ndarray:
        """P(mode 1) per fault (nf,) (Alg. 4.3); with `given_fault` on, also keeps each fault
        entry's mean over its mode-1 particles (`fault_if_faulty`)."""
        p = modes @ w
        if self.given_fault:
            F = X[N_AIRFRAME:]
            self.fault_if_faulty = np.where(p > 1e-9, np.einsum("jn,jn,n->j", F, modes, w)
                                            / np.maximum(p, 1e-9), F @ w)
        return p

    def annotate(self, out: StepOutput) -> None:
        """The transition's annotations; under parts.mode0 = "drift" the fault estimate is the
        change from the fault-free value (the drift is the sensor's or the model's error, no fault)."""
        self.transition.annotate(out)
        if self.given_fault:
            out.fault_value = self.fault_if_faulty - (self.drift.value if self.drift is not None else 0.0)
        if self.drift is not None:
            out.fault_estimate -= self.drift.value
