"""The estimator's rows split into what a filter observes and what it takes as input.

An estimator may list input rows (`estimator_config.INPUT_ROWS`): the accelerometer (ax, az,
body-axis specific force, m/s^2), the pitot's airspeed (m/s), the roll attitude (rad), the body-y
velocity (m/s) and the roll and yaw rates p, r (rad/s). No filter observes them: a kinematic
process model integrates the accelerometer like an input (SPEC section 2's velocity equations with
the aerodynamic forces replaced by the measured ones), takes the dynamic pressure of its pitching
moment from the airspeed, and the lateral terms of its climb rate, velocities and attitude from
the roll, v, p and r. `RowSplit.split(y, mask, u)` turns a frame over all rows (m,) into the
observed rows (m_obs,) and the input [delta_e, delta_t] (2,), extended by the input rows (+k,
`INPUT_ROWS` order) when the process takes them. A sample that did not arrive holds the
last one (before the first: the trim's specific force and airspeed).

With parts.engine_tau_s > 0 the throttle the filter takes (the derived throttle row's command and
the throttle faults' input) is the command through a first-order lag of that time constant
(`EngineLag`): a propeller's speed, and so its thrust, follows a throttle step in a few tenths of
a second (JSBSim's Aerosonde 0.2-0.3 s), and read at once the autopilot's quick throttle moves in
turbulence looked like a throttle that does not act (docs/faults.md, "The catalogue on other
aircraft").
The pitot's hold (`pitot.PitotRow.command`) still reads the command itself.

The process integrates a frame from its start to its end; each input is the reading at the end
(the throttle's step shows in a_x at once). With parts.az_input = "frame_mean" a_z is instead the
mean of the frame's two readings: a_z follows the short-period motion within the frame, and the
pitching moment reads the angle of attack from it. On the catalogue's fault-free flight the
moment's one-frame miss of the gyro is then 0.52 instead of 0.70 deg/s rms, and w's 0.023 instead
of 0.032 m/s (`benchmarks/moment_residuals.py`; docs/faults.md, "The accelerometer over the frame").
"""

from __future__ import annotations

import math

import numpy as np

from fdir_service.estimation.pitot import PitotRow, near_level_flight, pitot_row
from fdir_service.estimation.thrust import ThrustCheck
from fdir_service.estimator_config import AIRSPEED_ROW, INPUT_ROWS, THRUST_ROW, EstimatorConfig

G = 9.80665
"""Standard gravity (m/s^2)."""


def trim_specific_force(z_trim: np.ndarray) -> np.ndarray:
    """[a_x, a_z] (2,) m/s^2 of steady flight at the airframe state z_trim (5,): gravity's reaction."""
    theta = float(z_trim[3])
    return np.array([G * np.sin(theta), -G * np.cos(theta)])


def trim_inputs(z_trim: np.ndarray) -> dict[str, float]:
    """Each input row's value in steady flight in still air at z_trim (5,)."""
    ax, az = trim_specific_force(z_trim)
    return {"ax": float(ax), "az": float(az), "airspeed": float(np.hypot(z_trim[1], z_trim[2])),
            "roll": 0.0, "v": 0.0, "p": 0.0, "r": 0.0}


class EngineLag:
    """The throttle a propeller delivers (0..1): the command through a first-order lag, tau_s (s),
    one step of dt (s) a frame, starting at the first command it sees."""

    def __init__(self, tau_s: float, dt: float) -> None:
        self.a = math.exp(-float(dt) / float(tau_s))
        self.value: float | None = None

    def step(self, command: float) -> float:
        """This frame's delivered throttle for the command (NaN: the last one held)."""
        if not math.isfinite(command):
            return command if self.value is None else self.value
        self.value = command if self.value is None else command + self.a * (self.value - command)
        return self.value


class RowSplit:
    """Observed rows and IMU inputs of an estimator's frames (module docstring).

    observed (m_obs,) and imu (k,) are row indices into the estimator's rows (imu: the input rows);
    imu_as_input: append them to u (a kinematic process model), else they are dropped.
    """

    def __init__(self, observed: np.ndarray, imu: np.ndarray, imu_as_input: bool,
                 hold: np.ndarray | None = None, thrust: ThrustCheck | None = None,
                 pitot: PitotRow | None = None, attitude: tuple[int, ...] = (-1, -1, -1, -1),
                 az_mean: int = -1, engine: EngineLag | None = None) -> None:
        self.observed = np.asarray(observed, dtype=int)
        self.imu = np.asarray(imu, dtype=int)
        self.imu_as_input = bool(imu_as_input)
        self.identity = self.imu.size == 0
        self.hold = np.zeros(self.imu.size) if hold is None else np.asarray(hold, dtype=float).copy()
        self.thrust = thrust
        """A `ThrustCheck` when the estimator derives the throttle row (held ax, az, airspeed)."""
        self.pitot = pitot
        """A `pitot.PitotRow` when the airspeed is also an observed row (`AIRSPEED_ROW`): the pitching
        moment and the thrust check then take it less its estimated fault."""
        self.attitude = attitude
        """The attitude, pitch-rate and body-velocity (u, w) rows among the estimator's rows (-1:
        none): the pitot and the derived throttle row are read near level flight only
        (`pitot.near_level_flight`)."""
        self.az_mean = az_mean
        """a_z's position in the held inputs when the process takes the frame's mean (-1: its end)."""
        self._az_start = float(self.hold[az_mean]) if az_mean >= 0 else 0.0
        self.engine = engine
        """An `EngineLag` the throttle command passes through (parts.engine_tau_s), or None."""

    @classmethod
    def of(cls, estimator: EstimatorConfig, imu_as_input: bool, z_trim: np.ndarray) -> RowSplit:
        """The split of `estimator`'s rows; the held IMU starts at the trim's specific force."""
        rows = estimator.measurements
        imu = [rows.index(r) for r in INPUT_ROWS if r in rows]       # INPUT_ROWS order
        observed = [j for j, r in enumerate(rows) if r not in INPUT_ROWS]
        trim = trim_inputs(z_trim)
        derived = estimator.derived_rows
        az_mean = imu.index(rows.index("az")) if estimator.settings.az_input == "frame_mean" else -1
        thrust = ThrustCheck(estimator.airframe_params()) if THRUST_ROW in derived else None
        tau = estimator.settings.engine_tau_s
        engine = EngineLag(tau, estimator.dt_s) if tau > 0 and thrust is not None else None
        return cls(np.array(observed), np.array(imu), imu_as_input, np.array([trim[rows[j]] for j in imu]),
                   thrust, pitot_row(estimator) if AIRSPEED_ROW in derived else None,
                   tuple(rows.index(r) if r in rows else -1 for r in ("theta", "q", "u", "w")), az_mean,
                   engine)

    def split(self, y: np.ndarray, mask: np.ndarray, u: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(y_obs (m_obs,), mask_obs (m_obs,), u (2,) or (2 + k,)) of a frame over all rows."""
        if self.identity:
            return y, mask, u
        y = np.asarray(y, dtype=float)
        mask = np.asarray(mask, dtype=bool)
        fresh = mask[self.imu] & np.isfinite(y[self.imu])
        self.hold[fresh] = y[self.imu][fresh]
        u = np.asarray(u, dtype=float)[:2]
        y_obs, mask_obs = y[self.observed], mask[self.observed]
        held = self.hold
        theta, q, vu, vw = (float(y[j]) if j >= 0 and mask[j] else None for j in self.attitude)
        alpha = math.atan2(vw, vu) if vu is not None and vw is not None else None
        level = near_level_flight(theta, q, alpha)     # both derived rows hold near level flight only
        if self.pitot is not None:              # hold = [ax, az, airspeed, ...]: the trusted airspeed
            self.pitot.command(float(u[1]), level)
            held = held.copy()
            held[2] = self.pitot.trusted(held[2])
        if self.engine is not None:             # the throttle the propeller delivers
            u = np.array([u[0], self.engine.step(float(u[1]))])
        if self.thrust is not None:             # the derived throttle row
            ax, az, V = held[:3]
            y_obs = np.append(y_obs, self.thrust.implied_throttle(ax, az, V, u[0]) - u[1])
            mask_obs = np.append(mask_obs, bool(fresh[0]) and level)
        if self.pitot is not None:              # the derived airspeed row: the pitot's own reading
            y_obs = np.append(y_obs, self.hold[2])
            mask_obs = np.append(mask_obs, bool(fresh[2]) and level)
        if self.imu_as_input:
            u = np.concatenate([u, self._frame_inputs(held)])
        return y_obs, mask_obs, u

    def _frame_inputs(self, held: np.ndarray) -> np.ndarray:
        """The process's inputs (k,) from this frame's held readings: a_z the mean of the frame's
        start and end when `az_mean` (module docstring), else held itself."""
        if self.az_mean < 0:
            return held
        end = float(held[self.az_mean])
        held = held.copy()
        held[self.az_mean] = 0.5 * (self._az_start + end)
        self._az_start = end
        return held


NO_SPLIT = RowSplit(np.zeros(0, dtype=int), np.zeros(0, dtype=int), False)
"""The split of an estimator without IMU rows: frames pass through unchanged (shared, stateless)."""
