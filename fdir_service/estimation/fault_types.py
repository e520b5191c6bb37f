"""Fault types: how a monitored fault's entry behaves beyond an additive bias (docs/faults.md).

Every type but "noisy" keeps the additive form of SPEC section 5 (the entry adds to its row or its
input, so the measurement model, the amplitude A of eq. 4.13-4.16, the sentinels and the Kalman
correction are those of a bias); what the type changes is how the entry evolves in mode 1 between
two frames (`TypedEvolution`):

    bias           f+ = f                          an offset (a random walk with sigma_f)
    stuck          f+ = f - h_r (z+ - z)           the reading y_r = h_r z + f holds whatever z does
    blocked        f+ = f - h_r (z+ - z) + g dh / y_r   a blocked pitot's reading follows the altitude h
                                                   only (V^2 = V0^2 + 2 g (h - h0): docs/faults.md)
    jammed         f+ = f - (u_k - u_k-1)          the applied input u + f holds whatever u does
    effectiveness  f+ = f + phi (u_k - u_k-1)      the applied input (1 + phi) u follows the command
                   with phi = clip(f / u_k-1, -1, 0) scaled down; g = 1 + phi is the remaining gain
    engine         f+ = f - (u_k - u_k-1) + (V_k - V_k-1) / k_m    the throttle gives no thrust:
                   the throttle the accelerometer implies (thrust.py) is V / k_m whatever the command

So a stuck sensor is told from a biased one when its state moves, a jammed surface from an offset
one when its command moves, a dead engine from a throttle offset when the autopilot opens the
throttle (the delivered throttle stays at V / k_m) and from a lost gain as the airspeed decays.
A noisy sensor's entry is k - 1 >= 0, k the multiplier of its row's noise: it leaves the row's
prediction alone and scales its likelihood (`TypedCorrection`, which also weighs a stuck row by its
own, state-free predictive); a new one is drawn from its prior k - 1 ~ U(1, amplitude_max)
(`NoisySentinels`). The parts wrap the predict, correction and sentinel slots of a recipe
(factory.py), so a filter without typed faults is unchanged.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from fdir_service.estimation.inputs import G
from fdir_service.estimation.kernels import any_related, hand_over
from fdir_service.estimation.layout import N_AIRFRAME, FaultLayout
from fdir_service.estimation.measurement import state_gain

if TYPE_CHECKING:
    from collections.abc import Sequence

    from fdir_service.estimation.base import StepOutput
    from fdir_service.estimation.frame import Frame

AIRSPEED_INPUT = 4
"""The airspeed's position (m/s) in a kinematic process model's input u = [delta_e, delta_t, a_x,
a_z, V, ...] (`kinematic.KinematicProcess`): the trusted pitot the thrust check reads."""
NOISY_SIGMA = 0.25
"""The amplitude sigma of a noisy entry (k - 1): k below 1.25 is a faint fault (`jump.FaintExit`)."""


def _indices(layout: FaultLayout, kind: str) -> np.ndarray:
    return np.array([j for j in range(layout.nf) if layout.type_of(j) == kind], dtype=int)


class TypedEvolution:
    """The mode-1 evolution of typed fault entries (module docstring), vectorised per type.

    layout: the fault layout; H (m, n): the measurement matrix (a stuck row's h_r is its airframe part);
    wind: the pitot's wind entry (`pitot.wind_entry`, -1: none), which a stuck or blocked pitot's
    reading does not follow (`pitot.PitotRow.evolve`); k_motor (m/s per unit throttle): the
    airframe's propeller constant, whose V / k_m is the throttle of zero thrust (engine entries).
    """

    def __init__(self, layout: FaultLayout, H: np.ndarray, wind: int = -1, k_motor: float = 1.0) -> None:
        self.H = np.asarray(H, dtype=float)
        self.stuck = np.sort(np.concatenate([_indices(layout, "stuck"), _indices(layout, "blocked")]))
        """Entries whose reading holds (stuck, and blocked pitots, which also follow the altitude)."""
        self.blocked = np.array([layout.type_of(j) == "blocked" for j in self.stuck], dtype=bool)
        self.stuck_rows = layout.sensor_row[self.stuck]
        self.wind = int(wind)
        self.wind_row = int(layout.sensor_row[wind]) if wind >= 0 else -1
        self.stuck_h = self.H[self.stuck_rows, :N_AIRFRAME]                   # (k, 5)
        self.jammed = _indices(layout, "jammed")
        self.jammed_input = layout.actuator_input[self.jammed]
        self.weak = _indices(layout, "effectiveness")
        self.weak_input = layout.actuator_input[self.weak]
        self.noisy = _indices(layout, "noisy")
        self.engine = _indices(layout, "engine")
        self.k_motor = float(k_motor)

    @property
    def needs_state(self) -> bool:
        """True when a stuck sensor needs the airframe state before the prediction."""
        return self.stuck.size > 0

    def apply(self, z_before: np.ndarray | None, X: np.ndarray, modes: np.ndarray,
              u: np.ndarray, u_prev: np.ndarray | None) -> None:
        """Evolve the typed entries of the predicted cloud X (n, N) in place: z_before (5, N) the
        airframe states before the prediction (stuck sensors), u, u_prev the commands of this and
        the last frame (None: the first frame, no command change)."""
        F = X[N_AIRFRAME:]
        if self.stuck.size:
            dz = self.stuck_h @ (X[:N_AIRFRAME] - z_before)          # (k, N)
            dz[self.blocked] -= self._climb(X, z_before, F)
            F[self.stuck] -= dz * modes[self.stuck]
        if u_prev is not None and (self.jammed.size or self.weak.size or self.engine.size):
            self._follow_commands(F, modes, u, u_prev)
        if self.noisy.size:
            F[self.noisy] = np.maximum(F[self.noisy], 0.0)

    def _follow_commands(self, F: np.ndarray, modes: np.ndarray, u: np.ndarray, u_prev: np.ndarray) -> None:
        """Jammed, effectiveness and engine entries (mode 1) follow this frame's command change, and
        an engine's the airspeed's (in place; u, u_prev the process inputs of this and the last frame)."""
        du = np.asarray(u[:2], dtype=float) - u_prev[:2]
        F[self.jammed] -= du[self.jammed_input, None] * modes[self.jammed]
        self._scale_weak(F, modes, du, u_prev)
        if self.engine.size:
            dc = (float(u[AIRSPEED_INPUT]) - float(u_prev[AIRSPEED_INPUT])) / self.k_motor
            F[self.engine] += (dc - du[1]) * modes[self.engine]

    def _climb(self, X: np.ndarray, z_before: np.ndarray, F: np.ndarray) -> np.ndarray:
        """(b, N) m/s: a blocked pitot's reading change over the step, d V = g dh / V from V^2 = V0^2
        + 2 g (h - h0) (the trapped total pressure against the falling static pressure; rho cancels),
        dh = -(p_d+ - p_d) m, V the particle's reading before the step (its whole row, >= 5 m/s)."""
        H = self.H[self.stuck_rows[self.blocked]]                        # (b, n)
        V = np.maximum(H[:, :N_AIRFRAME] @ z_before + H[:, N_AIRFRAME:] @ F, 5.0)
        return G * (z_before[0] - X[0]) / V

    def _scale_weak(self, F: np.ndarray, modes: np.ndarray, du: np.ndarray, u_prev: np.ndarray) -> None:
        """Effectiveness entries follow the command change by their gain loss phi (in place)."""
        if not self.weak.size:
            return
        phi = self.gain_loss(F[self.weak], u_prev[self.weak_input, None])
        F[self.weak] += phi * du[self.weak_input, None] * modes[self.weak]

    @staticmethod
    def gain_loss(f: np.ndarray, u: np.ndarray) -> np.ndarray:
        """phi = clip(f / u, -1, 0) for additive offsets f and commands u (broadcast); 0 where u = 0."""
        with np.errstate(divide="ignore", invalid="ignore"):
            phi = np.where(u != 0.0, f / np.where(u != 0.0, u, 1.0), 0.0)
        return np.clip(phi, -1.0, 0.0)

    def thrust_share(self, f: np.ndarray, u: np.ndarray) -> np.ndarray:
        """The share of the commanded thrust an engine entry f (delivered - commanded throttle)
        leaves, for the last frame's process input u: (d^2 - c^2) / (u_t^2 - c^2) with d = u_t + f
        and c = V / k_m (thrust ~ k_m^2 d^2 - V^2, SPEC section 2), clipped to [0, 1]; 0 while the
        command asks for (almost) no thrust."""
        u_t, c = float(u[1]), float(u[AIRSPEED_INPUT]) / self.k_motor
        asked = u_t * u_t - c * c
        if asked < 0.01:
            return np.zeros_like(f)
        return np.clip(((u_t + f) ** 2 - c * c) / asked, 0.0, 1.0)


class TypedPredict:
    """A predict part followed by the typed entries' evolution (`TypedEvolution`); keeps the last
    command, and reports each fault's user-facing value (`annotate`)."""

    def __init__(self, inner, evolution: TypedEvolution, layout: FaultLayout) -> None:
        self.inner = inner
        self.process = inner.process
        self.evolution = evolution
        self.layout = layout
        self.u_prev: np.ndarray | None = None

    def predict(self, X: np.ndarray, modes: np.ndarray, u: np.ndarray,
                rng: np.random.Generator) -> np.ndarray:
        ev = self.evolution
        z_before = X[:N_AIRFRAME].copy() if ev.needs_state else None
        Xp = self.inner.predict(X, modes, u, rng)
        ev.apply(z_before, Xp, modes, u, self.u_prev)
        self.u_prev = np.array(u, dtype=float)
        return Xp

    def annotate(self, out: StepOutput) -> None:
        """out.fault_types, and out.fault_value per type from each entry's fault f (out.fault_value
        when the jump set it, the mean over the mode-1 particles; else the estimate): a bias f, a
        stuck row's held reading f + h_r z, a jammed input's held position f + u, an
        effectiveness's gain 1 + phi, an engine's share of the commanded thrust, a noisy row's
        k = 1 + f."""
        out.fault_types = self.layout.types
        f = (out.fault_value if out.fault_value is not None else out.fault_estimate).copy()
        value = f.copy()
        ev, z = self.evolution, out.x_mean[:N_AIRFRAME]
        value[ev.stuck] = f[ev.stuck] + ev.stuck_h @ z
        if self.u_prev is not None:
            value[ev.jammed] = f[ev.jammed] + self.u_prev[ev.jammed_input]
            value[ev.weak] = 1.0 + ev.gain_loss(f[ev.weak], self.u_prev[ev.weak_input])
            if ev.engine.size:
                value[ev.engine] = ev.thrust_share(f[ev.engine], self.u_prev)
        value[ev.noisy] = 1.0 + f[ev.noisy]
        out.fault_value = value


class TypedCorrection:
    """A correction part that respects the typed entries:
    - a stuck sensor's held reading c = h_r z + f is not corrected: its entry anti-tracks the
      correction's move of the state (f -= h_r dz), or the held value would follow the readings;
    - a noisy row's entry is not in H, so it is not corrected either;
    - the row of a mode-1 stuck or noisy entry is weighed by its own predictive, not the cloud's:
      the particle's weight gains log N(e; 0, v1) - log N(e; 0, v0), e = y_r - h_r x its innovation,
      v0 = sigma_r^2 + the cloud's predicted spread of the row (what the correction assumed), v1 =
      sigma_r^2 for a stuck row (the held reading does not depend on the state: a gyro that follows
      turbulence is no stuck gyro, however wide the cloud's pitch rate) and v0 + (k^2 - 1)
      sigma_r^2 for a noisy one.

    evolution: the `TypedEvolution`; rows (nf,): each entry's measurement row (-1: no row);
    sigma (m,): the rows' noise.
    """

    def __init__(self, inner, evolution: TypedEvolution, rows: np.ndarray, sigma: np.ndarray) -> None:
        self.inner = inner
        self.evolution = evolution
        self.faults = np.concatenate([evolution.stuck, evolution.noisy])
        self.noisy = np.r_[np.zeros(evolution.stuck.size, bool), np.ones(evolution.noisy.size, bool)]
        self.held = np.r_[~evolution.blocked, np.zeros(evolution.noisy.size, bool)]
        """Weighed by the state-free predictive: stuck rows, not a blocked pitot (an autopilot that
        holds the airspeed makes every pitot look held; its blockage shows in the altitude term)."""
        self.rows = np.asarray(rows, dtype=int)[self.faults]
        self.sigma = np.asarray(sigma, dtype=float)[self.rows] if self.faults.size else np.zeros(0)

    def update(self, X: np.ndarray, w: np.ndarray, modes: np.ndarray, frame: Frame) -> np.ndarray:
        extra = self._extra_loglik(X, w, modes, frame) if self.faults.size else None
        held = X[N_AIRFRAME + self.faults].copy()
        z = X[:N_AIRFRAME].copy() if self.evolution.needs_state else None
        ll = self.inner.update(X, w, modes, frame)
        X[N_AIRFRAME + self.faults] = held
        if z is not None:
            ev = self.evolution
            X[N_AIRFRAME + ev.stuck] -= (ev.stuck_h @ (X[:N_AIRFRAME] - z)) * modes[ev.stuck]
        return ll if extra is None else ll + extra

    def _extra_loglik(self, X: np.ndarray, w: np.ndarray, modes: np.ndarray,
                      frame: Frame) -> np.ndarray | None:
        """(N,) log N(e; 0, v1) - log N(e; 0, v0) summed over the typed rows that arrived."""
        present = frame.mask[self.rows]
        if not present.any():
            return None
        ri = frame.row_of[self.rows[present]]
        js = self.faults[present]
        pred = frame.mm.H[ri] @ X                               # (k, N)
        e = frame.yv[ri, None] - pred
        spread = (pred - (pred @ w)[:, None]) ** 2 @ w          # (k,)
        s2 = (self.sigma[present] ** 2)[:, None]
        v0 = s2 + spread[:, None]
        k = 1.0 + np.maximum(X[N_AIRFRAME + js], 0.0)
        v1 = np.where(self.noisy[present, None], v0 + (k * k - 1.0) * s2,
                      np.where(self.held[present, None], s2, v0))
        v1 = np.where(modes[js], v1, v0)
        return (-0.5 * e * e * (1.0 / v1 - 1.0 / v0) - 0.5 * np.log(v1 / v0)).sum(axis=0)


def item_keys(layout: FaultLayout) -> list[tuple[str, str]]:
    """(nf,) each fault entry's item: its kind and target (a measurement row, or an input)."""
    return list(zip(layout.kinds, layout.targets, strict=True))


def same_item(layout: FaultLayout) -> np.ndarray:
    """(nf, nf) bool: the fault entries on the same item, the diagonal included."""
    items = item_keys(layout)
    return np.array([[a == b for b in items] for a in items], dtype=bool)


def exclusion_matrix(layout: FaultLayout, groups: tuple[str, ...]) -> np.ndarray:
    """(nf, nf) float: 1 at [b, a] where entry a in mode 1 keeps entry b out of it: additive
    entries on different targets of one group (parts.exclusive_items, each a space-separated
    string of fault targets)."""
    E = np.zeros((layout.nf, layout.nf))
    additive = np.array([layout.type_of(j) != "noisy" for j in range(layout.nf)])
    targets = np.array(layout.targets)
    for group in groups:
        member = np.isin(targets, group.split()) & additive
        E += np.outer(member, member) * (targets[:, None] != targets[None, :])
    return np.minimum(E, 1.0)


def pair_exclusion(pairs: np.ndarray, nf: int) -> np.ndarray:
    """(nf, nf) float: 1 at [b, a] for each pair (a, b) of `pairs` (p, 2) (`sibling_pairs`: one
    additive type per item at a time)."""
    E = np.zeros((nf, nf))
    E[pairs[:, 1], pairs[:, 0]] = 1.0
    return E


class ItemExclusion:
    """Fault entries a particle may not hold in mode 1 together: while entry a is in mode 1, entry
    b cannot enter it. Two sources, joined in one matrix: the additive types of one item
    (`pair_exclusion`: one type per item, `TypeSwitch`), and items that do not fail together
    (parts.exclusive_items, `exclusion_matrix`). The attitude reading and the gyro
    are the two observers of the pitch chain (theta' = q): with both in mode 1 nothing pins theta,
    and a jammed elevator's pitch that the moment model misses was taken for a gyro fault that an
    attitude drift then followed, the attitude 5-8 deg off and the altitude 14 m (real-actuators run
    24); an attitude ramp likewise for a gyro bias (real-drift run 2). That group is measured, not a
    default: over the catalogue's worlds a reshuffle (seed 0: 43 ->
    41 false alarms; real-actuators seed 1: 18 -> 31; docs/faults.md, "The pitch chain in one
    place, measured"). On the robust monitor, whose gyro faults are found through particles that
    hold both, it fails: 92-143 false alarms per internal world against 0 (docs/robustness.md,
    "The pitch chain's exclusion on the robust monitor").

    excludes (nf, nf): `exclusion_matrix`."""

    def __init__(self, excludes: np.ndarray) -> None:
        self.excludes = np.asarray(excludes, dtype=float)
        if (self.excludes < 0.0).any():
            raise ValueError("ItemExclusion: the exclusion matrix is 0 or 1")

    def open(self, may: np.ndarray, modes: np.ndarray) -> np.ndarray:
        """(nf, N) bool: may ((nf,) or (nf, N)) less the entries that an entry in mode 1 (modes
        (nf, N)) keeps out."""
        blocked = any_related(self.excludes, modes)            # (excludes @ modes) > 0
        return (may[:, None] if may.ndim == 1 else may) & ~blocked


def sibling_pairs(layout: FaultLayout) -> np.ndarray:
    """(p, 2) ordered pairs (a, b) of additive fault entries of different types on the same item
    (a measurement row, or an input): the hand-overs `TypeSwitch` may make."""
    items = item_keys(layout)
    additive = [j for j in range(layout.nf) if layout.type_of(j) != "noisy"]
    pairs = [(a, b) for a in additive for b in additive
             if a != b and items[a] == items[b] and layout.type_of(a) != layout.type_of(b)]
    return np.array(pairs, dtype=int).reshape(-1, 2)


class TypeSwitch:
    """A mode-1 fault may hand its offset to another type of the same item (per step and pair, at
    entry a's rate: its `pi_switch`, else parts.pi_switch): entry a leaves mode 1 (back to its
    fault-free value), entry b enters it with a's offset. All additive types read that offset the
    same way, so the particle's prediction of this frame is unchanged; only the next frames tell a
    stuck sensor from a biased one. Without it, the type that took the fault first keeps it until
    sentinels of the other happen to win.

    One type per item at a time (an `ItemExclusion` of these pairs, `pair_exclusion`): the
    additive types of an item add the same offset, so a particle with two of them in mode 1 could
    split one fault between them in any proportion.

    A stuck sensor that comes back re-anchors the state (`anchor`, `apply_anchor`): half the
    particles leaving a stuck mode (v < pi10 / 2) move their airframe state so that the row predicts
    this frame's reading, x += g_r (y_r - h_r z), g_r = h_r^T / |h_r|^2. While the sensor was held,
    the state it measures was estimated without it (the altitude from GNSS alone, metres off after
    a climb); without the anchor the returning barometer disagrees with that state and is declared
    biased until the state has crept back (most false alarms after a stuck barometer). A returning
    pitot anchors nothing: the wind it measures against u is what the anchor would move, and nothing
    else sees the wind, so an anchored wind would explain any standing pitot fault away (`pitot.py`).

    pairs (p, 2): `sibling_pairs`; rate: the hand-over probability per step and pair, one for all
    or per entry (nf,), the pair (a, b) at a's; evolution:
    the `TypedEvolution` (its stuck entries and their rows' h_r); rows (nf,): each entry's row.
    """

    def __init__(self, pairs: np.ndarray, rate: float | Sequence[float],
                 evolution: TypedEvolution | None = None, rows: np.ndarray | None = None) -> None:
        self.pairs = np.asarray(pairs, dtype=int).reshape(-1, 2)
        rate = np.asarray(rate, dtype=float)
        self.rates = (np.full(len(self.pairs), float(rate)) if rate.ndim == 0
                      else rate[self.pairs[:, 0]])                                      # (p,)
        self.active = bool(self.pairs.size) and bool((self.rates > 0.0).any())
        self.stuck = evolution.stuck if evolution is not None else np.zeros(0, int)
        self.stuck_rows = np.asarray(rows, dtype=int)[self.stuck] if self.stuck.size else self.stuck
        self.stuck_g = state_gain(evolution.H, self.stuck_rows) if self.stuck.size \
            else np.zeros((N_AIRFRAME, 0))                                                  # (5, k)
        if evolution is not None and evolution.wind >= 0:     # a returning pitot moves no state
            self.stuck_g[:, self.stuck_rows == evolution.wind_row] = 0.0

    def anchor(self, F: np.ndarray, modes: np.ndarray, v: np.ndarray, pi10: np.ndarray,
               innov: np.ndarray, frame: Frame) -> np.ndarray | None:
        """Before the jump: (k, N) the reading's distance y_r - h_r z of the stuck particles that
        will leave and re-anchor (0 elsewhere), or None. innov (m_rows, N): y - H x of the frame's
        rows; pi10 (nf, 1) or (nf, N) this step's exit probabilities."""
        if not self.stuck.size:
            return None
        present = frame.mask[self.stuck_rows]
        if not present.any():
            return None
        go = modes[self.stuck] & (v[self.stuck] < 0.5 * pi10[self.stuck]) & present[:, None]
        if not go.any():
            return None
        ri = frame.row_of[self.stuck_rows]
        dist = innov[np.where(present, ri, 0)] + F[self.stuck]       # y_r - h_r z (the held f out)
        return np.where(go, dist, 0.0)

    def apply_anchor(self, X: np.ndarray, values: np.ndarray | None) -> None:
        """After the jump: X[:5] += g values, in place."""
        if values is not None:
            X[:N_AIRFRAME] += self.stuck_g @ values

    def apply(self, F: np.ndarray, modes: np.ndarray, reset_to: np.ndarray | None,
              rng: np.random.Generator) -> None:
        """Hand over in place: F (nf, N) fault entries, modes (nf, N); reset_to (nf,) the fault-free
        values (None: 0)."""
        if not self.active:
            return
        v = rng.random((len(self.pairs), F.shape[1]))
        back = np.zeros(F.shape[0]) if reset_to is None else reset_to
        hand_over(F, modes, v, self.pairs, self.rates, back)   # the row's offset F[a] + F[b] is kept


class NoisySentinels:
    """A sentinel weighting plus the noisy faults' proposal: a noisy entry that just jumped gets
    k - 1 from its prior, k log-uniform on [1 + low, 1 + high] (a scale's prior: k = 1.5 to 3 is
    as likely as 3 to 6), with no importance term (proposal = prior).

    faults (k,): the noisy entries; low, high (k,): the prior's bounds of k - 1."""

    def __init__(self, inner, faults: np.ndarray, low: np.ndarray, high: np.ndarray) -> None:
        self.inner = inner
        self.faults = np.asarray(faults, dtype=int)
        self.low = np.asarray(low, dtype=float)
        self.high = np.asarray(high, dtype=float)

    def weigh(self, X: np.ndarray, frame: Frame, sentinels: np.ndarray,
              rng: np.random.Generator) -> np.ndarray | None:
        bonus = self.inner.weigh(X, frame, sentinels, rng)
        for j, lo, hi in zip(self.faults.tolist(), self.low.tolist(), self.high.tolist(), strict=True):
            cols = np.flatnonzero(sentinels[j])
            if cols.size:
                X[N_AIRFRAME + j, cols] = np.exp(rng.uniform(np.log1p(lo), np.log1p(hi), cols.size)) - 1.0
        return bonus
