"""The pitch-rate process noise learnt from the gyro's own readings (parts.q_noise = "learned";
docs/faults.md, "The pitch-rate noise the flight shows").

The kinematic model predicts q through the pitching moment (`kinematic.PitchMoment`), and what the
moment leaves unexplained is process noise, sigma_x[4] per sqrt(s). The configured value has to
cover the worst air and airframe the estimator may meet (JSBSim's turbulence); on a better-modelled
aircraft it is several times what the flight shows (real-catalogue-faultfree run 4: the moment's
one-frame error 0.71 deg/s rms, against 1.92 deg/s configured). A stuck-gyro hypothesis, which
frees q from the gyro and predicts the next reading to be the held one within the gyro's noise, then gains the
ratio of the two predictive widths, log(1.92 / 0.24) ~ 2 nats, every frame the reading happens to
be steady: three such frames in ordinary flight made the stuck entry take the cloud (stop 42's
eight false alarms in five fault-free hours on the truth).

Here the noise is learnt from the data. Each frame with the gyro's reading and the last one, the
one-frame residual of the moment model run from the last reading,

    e_k = y_k - y_k-1 - dt q'(y_k-1, delta_e, a_z, V)          (the frame's inputs u)

feeds a running mean m and variance v about it, gain max(dt / tau_s, 1 / n) with the configured
noise counted as the first PRIOR_FRAMES of the n residuals: a plain average at first, exponential
(time constant tau_s) once 1 / n < dt / tau_s (a trim misfit is the mean, the elevator's drift
carries it). The predict's pitch-rate noise per step is then

    sqrt(v - 2 sigma_r^2)    clipped to [FLOOR_SHARE, 1] x the configured per-step noise of q

(sigma_r: the gyro's assumed noise, twice for the two readings). So the configured value is an upper
bound the data can only narrow. The heavy tail (parts.q_tail: a share of the particles with its
scale x the noise) keeps the configured noise times its scale: it stands for the pitch
accelerations no moment foresees (an upset, a surface that snaps free), of which quiet frames say
nothing. Learnt with the tail narrowed too, real-actuators raised 111 false alarms after its
faults against 83 (stop 43); with the tail kept, 105. With the moment reading a_z over the frame
(parts.az_input = "frame_mean") and the configured noise back under a fault (below), 77: the
catalogue learns it since stop 44 (docs/faults.md, "The pitch-rate noise the flight shows", "The
accelerometer over the frame").

A residual further than WINSOR sigmas from m is clipped before it enters v. While the probability
that some fault is active exceeds 0.5 (the prior weights over the frame's modes after its jump)
nothing is learnt, its residuals being the fault's, not the model's, and the predict takes the
configured noise back: under a fault the moment's inputs may be wrong in ways no entry carries
(a pitot fault's airspeed, the transients after a surface frees), and with the learnt noise the
elevator took the blame for them (real-pitot run 2: the elevator declared at 27.0 s, 9.5 s into a
pitot step; none with the configured noise back; docs/faults.md, "The accelerometer over the
frame"). The residual takes the trusted airspeed reading and the elevator command, where a
particle's predict may take its own airspeed and elevator fault entries.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from fdir_service.estimation.frame import Frame
    from fdir_service.estimation.kinematic import PitchMoment

FLOOR_SHARE = 0.1
"""The learnt pitch-rate noise never falls below this share of the configured one."""
PRIOR_FRAMES = 20
"""The configured pitch-rate noise weighs as much as this many residuals at the start."""
WINSOR = 4.0
"""A residual is clipped to this many standard deviations about the mean before it is learnt."""


class LearnedPitchNoise:
    """A correction wrapper (the inner's log-likelihoods unchanged) that learns the pitch-rate
    process noise per step from the gyro row (module docstring) and sets it in the predict's
    per-step noise `q_std` (n, 1), row 4, and its tail's scale `q_tail` (if it has one).

    predict: the predict part (a `predict.GaussianPredict`); moment: the process's pitch moment;
    gyro: the gyro's measurement row; sigma_r: its assumed noise (rad/s); dt (s); tau_s: the
    learning time constant (s). The frame's input u holds [delta_e, delta_t, a_x, a_z, V, ...]
    (`kinematic.KinematicProcess`).
    """

    def __init__(self, inner, predict, moment: PitchMoment, gyro: int, sigma_r: float,
                 dt: float, tau_s: float) -> None:
        self.inner = inner
        self.predict = predict
        self.q_std = predict.q_std
        self.tail = getattr(predict, "q_tail", None)
        """(share, scale) of the configured tail; None: the predict has none."""
        self.moment = moment
        self.gyro = int(gyro)
        self.dt = float(dt)
        self.top = float(self.q_std[4, 0])
        self.noise_var = 2.0 * float(sigma_r) ** 2
        self.alpha = min(1.0, self.dt / float(tau_s))
        self.learnt = PRIOR_FRAMES
        self.mean = 0.0
        self.var = self.top ** 2 + self.noise_var       # start where the configured noise stands
        self.last: float | None = None
        self.learnt_sigma = self.top
        """The learnt noise per step (rad/s): the predict's while no fault is believed."""

    def update(self, X: np.ndarray, w: np.ndarray, modes: np.ndarray, frame: Frame) -> np.ndarray:
        """The inner correction of X (n, N) in place; then learn from the frame (module docstring)."""
        ll = self.inner.update(X, w, modes, frame)
        if not frame.mask[self.gyro]:
            self.last = None
            return ll
        y = float(frame.yv[frame.row_of[self.gyro]])
        if not np.isfinite(y):                       # a bad reading is a missing one
            self.last = None
            return ll
        quiet = float(w @ modes.any(axis=0)) <= 0.5
        if self.last is not None and quiet:
            e = y - self.last - self.dt * self._qdot(self.last, frame.u)
            if np.isfinite(e):
                self._learn(e)
        self._set(self.learnt_sigma if quiet else self.top)
        self.last = y
        return ll

    def _qdot(self, q: float, u: np.ndarray) -> float:
        """The moment's q' (rad/s^2) at pitch rate q with the frame's inputs."""
        return float(self.moment.qdot(np.array([q]), float(u[0]), float(u[3]), float(u[4]))[0])

    def _learn(self, e: float) -> None:
        """One residual e (rad/s) into the mean and variance, then the predict's noise."""
        sd = np.sqrt(self.var)
        d = min(max(e - self.mean, -WINSOR * sd), WINSOR * sd)
        self.learnt += 1
        a = max(self.alpha, 1.0 / self.learnt)
        self.mean += a * d
        self.var += a * (d * d - self.var)
        model = np.sqrt(max(self.var - self.noise_var, 0.0))
        self.learnt_sigma = min(max(model, FLOOR_SHARE * self.top), self.top)

    def _set(self, sigma: float) -> None:
        """The predict's pitch-rate noise per step (rad/s), its tail kept at the configured width."""
        self.q_std[4, 0] = sigma
        if self.tail is not None and sigma > 0.0:
            self.predict.q_tail = (self.tail[0], self.tail[1] * self.top / sigma)

    @property
    def sigma(self) -> float:
        """The pitch-rate process noise per step now (rad/s)."""
        return float(self.q_std[4, 0])
