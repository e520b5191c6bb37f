"""The pitot observed against the ground speed, and the wind it measures (docs/faults.md, "Pitot").

A kinematic estimator that watches the pitot observes its airspeed row as V ~ u + W
(`measurement.DERIVED_STATE`): u the body-axis speed over the ground, W = -w_x the head wind along
body x. The wind is the pitot's bias entry in its fault-free mode (`wind_entry`); in mode 1 the
entry is the wind plus the pitot's offset. `PitotRow` is the wind's model and the pitot's plumbing:
- `start`: on the first frame with a pitot reading the wind starts at y - u per particle (it is
  unknown and may be 10 m/s: left to the sentinels, a blockage would take it);
- `evolve`, after each prediction: a Gauss-Markov wind, a mean plus a Dryden-shaped gust (the
  first-order form of MIL-F-8785C's longitudinal gust, sigma_u over L_u / V):

      c+ = M + a (c - M) + sigma sqrt(1 - a^2) e,    a = exp(-dt / tau),   e ~ N(0, 1),
      c = W + kappa u,   W+ = c+ - kappa u+

  on the mode-0 particles, with M the mean of c (one value, following the mode-0 particles' mean
  with time constant tau_m while the pitot is fault-free) and u, u+ the particle's ground speed
  before and after the prediction. kappa (`parts.wind_hold`) is the share of a ground-speed
  change that is the wind's. kappa = 0: an aircraft that flies through the gusts on its inertia,
  the airspeed takes the gust and c is the head wind. kappa = 1: under an autopilot's airspeed
  hold a gust moves the ground speed, not the airspeed; c = u + W is the airspeed the healthy
  pitot reads, its gusts what the hold lets through (sigma `held_airspeed_sigma`, not the wind's
  `wind_gust_sigma`: `gust_sigma`), M the held airspeed. With kappa = 0 in such
  flight the wind had to follow every swing of u through its gust model alone and lagged the fast
  ones, so a held-reading hypothesis (blocked) fitted the steady reading better than the healthy
  pitot (false alarms in level flight). A gust returns to the mean, so an
  offset that stands longer than the gusts last is a fault, not wind; a stuck or blocked pitot's
  entry anti-tracks the wind's move (its reading does not see the air), so the wind keeps drifting
  unobserved under a held pitot and after a long fault the cloud spans the winds it may have become;
- `command`: the hold needs the throttle's authority. While the throttle command sits at a limit
  (`THROTTLE_LIMITS`: an autopilot at full throttle after an engine loss, or idle in a dive), and
  for `HOLD_SETTLE_S` after it leaves it (the airspeed loop's transient: an engine that comes back
  at full throttle overshoots the airspeed), no airspeed is held: the step is flown with kappa = 0
  and the wind's own gust (`free_sigma`, `wind_gust_sigma`), and M is re-expressed as the mean of
  the new c (the head wind, then the airspeed again when the hold takes over), so the airspeed the
  hold returns to is the one the aircraft has, not the one it had before it lost its engine;
- `use_memory`: the fault-free value an exit returns the wind's entry to (`jump.DriftMemory`)
  moves with the gust model while a pitot fault holds the entry, so a pitot that returns fits the
  wind of now, not of the fault's onset;
- `follow` / `trusted`: the pitching moment and the thrust check take the airspeed less the pitot's
  estimated fault, so a blocked pitot does not make the elevator or the engine look faulty.
"""

from __future__ import annotations

import math

import numpy as np

from fdir_service.estimation.layout import N_AIRFRAME

THROTTLE_LIMITS = (0.0, 1.0)
"""The throttle command's range: at either end the autopilot has no authority left to hold the
airspeed (`PitotRow.command`)."""
HOLD_SETTLE_S = 3.0
"""s: after the throttle leaves a limit, the time an airspeed loop takes to bring the airspeed back
before the hold is assumed again (a few seconds for a small UAV; set a priori, not fitted)."""
PITOT_MAX_PITCH_RAD = math.radians(25.0)
PITOT_MAX_RATE_RADPS = math.radians(15.0)
PITOT_MAX_ALPHA_RAD = math.radians(20.0)
"""Beyond this pitch attitude (rad), pitch rate (rad/s) or angle of attack of the body's velocity
over the ground (atan2(w, u) of the u, w readings, rad) the pitot is not read: V ~ u + W holds near
level flight, and in an upset the head wind's share along body x (W_N cos theta) and the vertical
velocity's share of V change faster than any gust, so the row would blame the pitot for the attitude.
V ~ u + W leaves out w: 6 % of V at 20 deg, 20 % at 33 deg, where a freed elevator's stall put
the pitch back under 25 deg while the wing was still stalled (real-actuators run 76). The readings'
angle reaches 11 deg in ordinary climbs in turbulence (8 deg true, 1.4 deg of noise from the u, w
readings): 10 deg let the hold go on noise and raised a pitot false alarm. The derived
throttle row (`thrust.ThrustCheck`: linear lift, a parabolic polar) is read within the same limits
(`near_level_flight`, `inputs.RowSplit`)."""


def _within(value: float | None, limit: float) -> bool:
    return value is None or not math.isfinite(value) or abs(value) <= limit


def near_level_flight(theta: float | None, q: float | None, alpha: float | None = None) -> bool:
    """True at a pitch attitude theta (rad), pitch rate q (rad/s) and angle of attack alpha (rad)
    where the pitot and the thrust check may be read (None or not finite: not measured, no limit)."""
    return (_within(theta, PITOT_MAX_PITCH_RAD) and _within(q, PITOT_MAX_RATE_RADPS)
            and _within(alpha, PITOT_MAX_ALPHA_RAD))


def wind_entry(faults) -> int:
    """The fault entry carrying the wind: the first bias entry on the airspeed row (faults (nf,)
    `FaultSpec`s); -1 when there is none."""
    for j, f in enumerate(faults):
        if f.target == "airspeed" and f.fault_type == "bias":
            return j
    return -1


class PitotRow:
    """The pitot's wind and trusted airspeed (module docstring).

    entries (k,): the fault entries on the pitot; wind: the wind's entry (-1: none); held (h,): the
    stuck and blocked entries on the pitot; row: the derived airspeed row among the observed rows;
    sigma (m/s): its noise (the spread of the wind's start); dt (s); gust (sigma m/s, tau s, tau_m s);
    hold: kappa, the share of a ground-speed change that is the wind's (parts.wind_hold); free_sigma
    (m/s): the gust's sigma while the hold lets go (`command`; None: gust's sigma).
    """

    def __init__(self, entries: np.ndarray, wind: int, held: np.ndarray, row: int, sigma: float,
                 dt: float = 0.05, gust: tuple[float, float, float] = (1.5, 10.0, 60.0),
                 hold: float = 0.0, free_sigma: float | None = None, resume_held: bool = False,
                 held_tau: float | None = None) -> None:
        self.entries = np.asarray(entries, dtype=int)
        self.wind = int(wind)
        self.held = np.asarray(held, dtype=int)
        self.row = int(row)
        self.sigma = float(sigma)
        g_sigma, tau, tau_m = (float(v) for v in gust)
        self.free_a = math.exp(-dt / tau)
        self.a = self.free_a if held_tau is None else math.exp(-dt / float(held_tau))
        """The gusts' one-step correlation under the hold (`held_tau`, s; None: the wind's tau)."""
        self.step_sigma = g_sigma * math.sqrt(1.0 - self.a * self.a)
        free = g_sigma if free_sigma is None else float(free_sigma)
        self.free_step_sigma = free * math.sqrt(1.0 - self.free_a * self.free_a)
        self.mean_rate = min(dt / tau_m, 1.0)
        self.hold = float(hold)
        """kappa (0..1): the share of the ground speed's predicted change that the wind takes (`evolve`)."""
        self.mean: float | None = None
        """m/s: the mean M the gusts return to, of W + kappa u: the mean wind (kappa = 0), the mean
        airspeed (kappa = 1) (None before the first pitot reading)."""
        self.authority = True
        """False while the throttle command sits at a limit, and HOLD_SETTLE_S after (`command`): no
        airspeed is held."""
        self.settle_frames = math.ceil(HOLD_SETTLE_S / float(dt) - 1e-9)
        self.off_limit = self.settle_frames
        """Frames since the throttle command last sat at a limit (up to settle_frames)."""
        self.kappa = self.hold
        """The kappa that M is the mean for (`hold`, or 0 while the hold lets go)."""
        self.error = 0.0
        """m/s: the pitot's estimated fault after the last step (`follow`)."""
        self.memory = None
        """The jump's `jump.DriftMemory` (parts.mode0 = "drift"; `use_memory`), or None."""
        self.resume_held = bool(resume_held)
        """parts.hold_resume = "held": when the hold takes over again and the fault-free particles
        are not most of the cloud, M returns to the held airspeed the let-go left (`_kappa`)."""
        self.held_mean: float | None = None
        """m/s: M as the hold last let go (the airspeed it held), or None."""

    def use_memory(self, memory) -> None:
        """The fault-free values that exits return to (a `jump.DriftMemory`): its wind entry moves
        as the wind's expected value while a pitot fault holds it (`_evolve_memory`)."""
        self.memory = memory

    def fault_free_wind(self, X: np.ndarray, modes: np.ndarray) -> np.ndarray:
        """Each particle's head wind W (N,) m/s: its wind entry where that is in mode 0, else the
        fault-free value the entry's exit returns to (`use_memory`; the entry itself without one),
        the wind the gust model expects while a pitot bias holds the entry (wind plus offset)."""
        W = X[N_AIRFRAME + self.wind]
        if self.memory is None:
            return W
        return np.where(modes[self.wind], self.memory.value[self.wind], W)

    def command(self, throttle: float, level: bool = True) -> None:
        """This frame's throttle command (0..1, NaN: unknown) and whether the aircraft flies near
        level (`near_level_flight`): whether the autopilot can hold the airspeed (off the throttle's
        limits and near level for HOLD_SETTLE_S). In an upset no airspeed loop holds the airspeed,
        and a freed elevator's pull-up took 7 m/s off the ground speed in 0.2 s, which the hold
        turned into 5 m/s of head wind the pitot then disowned once it was read again."""
        at_limit = not THROTTLE_LIMITS[0] < throttle < THROTTLE_LIMITS[1] and math.isfinite(throttle)
        at_limit = at_limit or not level
        self.off_limit = 0 if at_limit else min(self.off_limit + 1, self.settle_frames)
        self.authority = self.off_limit >= self.settle_frames

    def trusted(self, airspeed: float) -> float:
        """The airspeed (m/s) the models take: the reading less the estimated fault."""
        return airspeed - self.error

    def evolve(self, X: np.ndarray, modes: np.ndarray, y: np.ndarray, mask: np.ndarray,
               rng: np.random.Generator, u_before: np.ndarray | None = None) -> None:
        """After the prediction of the cloud X (n, N), modes (nf, N), with the frame's observed rows
        y, mask (m_obs,): start the wind on the first pitot reading, else move it (in place):
        c = W + kappa u returns to M as a gust and W+ = c+ - kappa u+, u_before (N,) m/s the ground
        speed before the prediction (None: u did not change)."""
        if self.wind < 0:
            return
        if self.mean is None:
            self._start(X, y, mask, rng)
            return
        W = X[N_AIRFRAME + self.wind]
        free = ~modes[self.wind]
        u0 = X[1] if u_before is None else u_before
        fault_free = free & ~modes[self.held].any(axis=0)
        kappa = self._kappa(W, u0, fault_free)
        c = self._held_sum(W, u0, kappa)
        a, sigma = self._gust_step(kappa)
        c_next = self.mean + a * (c - self.mean) + sigma * rng.standard_normal(W.size)
        step = self._wind_of(c_next, X[1], kappa) - W
        step *= free
        W += step
        X[N_AIRFRAME + self.held] -= step * modes[self.held]
        self._follow_mean(self._held_sum(W, X[1], kappa), fault_free)
        self._evolve_memory(float(u0.mean()), float(X[1].mean()), kappa)

    def _evolve_memory(self, u0: float, u1: float, kappa: float) -> None:
        """The wind's fault-free value (`memory`) one step on, as the gust model expects it: c = W +
        kappa u returns to M and W+ = c+ - kappa u+, with u0, u1 (m/s) the cloud's mean ground speed
        before and after the prediction. While mode 0 holds most of the weight `DriftMemory.update`
        replaces it by the mode-0 mean; under a pitot fault no reading sees the wind, and without
        this the exits returned to the wind of the fault's onset: under the airspeed hold the head
        wind takes every change of the ground speed (2 m/s in a 13 s bias while climbing), and the
        healthy pitot was declared again, biased by that change, for 20 s after the fault ended."""
        if self.memory is None:
            return
        c = self._held_sum(self.memory.value[self.wind], u0, kappa)
        a, _ = self._gust_step(kappa)
        self.memory.value[self.wind] = self._wind_of(self.mean + a * (c - self.mean), u1, kappa)

    def _gust_step(self, kappa: float) -> tuple[float, float]:
        """(a, sigma m/s): the gust's one-step correlation and noise this step, the held airspeed's
        under the hold (kappa = `hold`), the wind's while it lets go."""
        return (self.a, self.step_sigma) if kappa == self.hold else (self.free_a, self.free_step_sigma)

    def _kappa(self, W: np.ndarray, u: np.ndarray, fault_free: np.ndarray) -> float:
        """This step's kappa: `hold`, or 0 while the throttle has no authority (`command`); when it
        changes, M becomes the mean of the new c = W + kappa u (the fault-free particles', if they
        are most of the cloud; else every particle's, or with `resume_held` the airspeed held
        before the let-go when the hold takes over again: with the pitot declared, every
        particle's mean took the biased and blocked particles' winds, 2.5 m/s off in real-engine
        run 96, and M, which then follows only fault-free particles, never came back)."""
        kappa = self.hold if self.authority else 0.0
        if kappa != self.kappa:
            if self.kappa == self.hold:
                self.held_mean = self.mean
            c = self._held_sum(W, u, kappa)
            mean = self._fault_free_mean(c, fault_free)
            if mean is None and kappa == self.hold and self.resume_held and self.held_mean is not None:
                mean = self.held_mean
            self.mean = float(c.mean()) if mean is None else mean
            self.kappa = kappa
        return kappa

    @staticmethod
    def _held_sum(W: np.ndarray, u: np.ndarray, kappa: float) -> np.ndarray:
        """c = W + kappa u (m/s, (N,)): the quantity whose gusts return to the mean M, the head wind
        (kappa = 0) or, under an airspeed hold (kappa = 1), the airspeed u + W."""
        return W + kappa * u if kappa > 0.0 else W

    @staticmethod
    def _wind_of(c, u, kappa: float):
        """W = c - kappa u (m/s): the head wind of a held sum c at ground speed u (`_held_sum`'s inverse)."""
        return c - kappa * u if kappa > 0.0 else c

    def _start(self, X: np.ndarray, y: np.ndarray, mask: np.ndarray, rng: np.random.Generator) -> None:
        """On the first frame whose pitot arrived: X[wind] = y_pitot - u + N(0, sigma^2) per particle."""
        if not mask[self.row] or not np.isfinite(y[self.row]):
            return
        X[N_AIRFRAME + self.wind] = y[self.row] - X[1] + self.sigma * rng.standard_normal(X.shape[1])
        self.kappa = self.hold if self.authority else 0.0
        self.mean = float(np.mean(self._held_sum(X[N_AIRFRAME + self.wind], X[1], self.kappa)))

    def _follow_mean(self, c: np.ndarray, fault_free: np.ndarray) -> None:
        """M follows the fault-free particles' mean of c (W + kappa u, m/s) while they are most of
        the cloud."""
        mean = self._fault_free_mean(c, fault_free)
        if mean is not None:
            self.mean += self.mean_rate * (mean - self.mean)

    @staticmethod
    def _fault_free_mean(c: np.ndarray, fault_free: np.ndarray) -> float | None:
        """The fault-free particles' mean of c (N,) when they are most of the cloud, else None."""
        return float(c[fault_free].mean()) if 2 * np.count_nonzero(fault_free) > c.size else None

    def follow(self, fault_estimate: np.ndarray) -> None:
        """After a step: the sum of the pitot entries' estimates (nf,) SI, each the change from its
        fault-free value, for the next frame's `trusted` airspeed (0 if not finite)."""
        err = float(np.sum(fault_estimate[self.entries]))
        self.error = err if np.isfinite(err) else 0.0


class NoWind:
    """An estimator that does not watch the pitot: no wind to move, no fault to follow."""

    def evolve(self, X: np.ndarray, modes: np.ndarray, y: np.ndarray, mask: np.ndarray,
               rng: np.random.Generator, u_before: np.ndarray | None = None) -> None:
        """Nothing moves."""

    def follow(self, fault_estimate: np.ndarray) -> None:
        """Nothing to follow."""


NO_WIND = NoWind()
"""The wind part of a filter without a pitot (shared, stateless)."""


def gust_sigma(settings) -> float:
    """The stationary sigma (m/s) of c = W + kappa u about its mean: the head wind's gust
    (`wind_gust_sigma`) with no hold, the airspeed's that the hold lets through
    (`held_airspeed_sigma`) under it, blended by kappa in between (settings: `FilterSettings`)."""
    kappa = settings.wind_hold
    return (1.0 - kappa) * settings.wind_gust_sigma + kappa * settings.held_airspeed_sigma


def pitot_row(estimator) -> PitotRow:
    """The `PitotRow` of an estimator (`EstimatorConfig`) that observes the airspeed (a derived row)."""
    faults, s = estimator.faults, estimator.settings
    entries = [j for j, f in enumerate(faults) if f.target == "airspeed"]
    held = [j for j in entries if faults[j].fault_type in ("stuck", "blocked")]
    sigma = estimator.sigma[estimator.measurements.index("airspeed")]
    return PitotRow(np.array(entries), wind_entry(faults), np.array(held, dtype=int),
                    estimator.observed.index("airspeed"), sigma, estimator.dt_s,
                    (gust_sigma(s), s.wind_gust_tau_s, s.wind_mean_tau_s), s.wind_hold, s.wind_gust_sigma,
                    s.hold_resume == "held", s.held_airspeed_tau_s)
