"""The attitude a gyro-fault hypothesis integrated, taken back when it ends (parts.gyro_exit_unwind;
docs/faults.md, "The attitude a gyro fault integrated").

On the kinematic model theta' = q, and a particle that holds the gyro faulty (any type of its item:
a bias, a stuck reading) integrates its own q state instead of the gyro's reading. An attitude
sensor that starts to ramp is, for its first seconds, as well explained by a gyro bias whose
integral follows the ramp: in real-drift run 14 the gyro's hypothesis held 60-85 % of the weight
for 4 s, its particles' attitude walked 3 deg along the ramp, and when the attitude's own drift
took over the attitude state stayed 2 deg off. Through h' = u sin(theta) - w cos(theta) the altitude
left the altimeters by 7 m and the barometer was declared in its place.

Each particle keeps the attitude its gyro hypothesis integrated away from the gyro,

    S_i = sum over its frames in the gyro's mode 1 of dt (y_q - q_i)          (rad),

and when it leaves that mode (every entry of the gyro's item back to mode 0) a share of those that
leave take it back, theta_i += S_i: the gyro was right, so the attitude is the one its readings
integrate to. The others keep their attitude (the gyro was faulty and the fault ended). The data
then weigh the two, as with an exit's fold (`jump.ExitFold`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from fdir_service.estimation.frame import Frame

THETA, Q = 3, 4
"""Indices of the pitch angle (rad) and the pitch rate (rad/s) in the airframe state (layout.py)."""


class NoUnwind:
    """A particle leaving a gyro fault keeps its attitude (parts.gyro_exit_unwind = 0)."""

    def before(self, X: np.ndarray, modes: np.ndarray, frame: Frame) -> None:
        return None

    def after(self, X: np.ndarray, modes: np.ndarray, held: None, rng: np.random.Generator) -> None:
        """Nothing moves."""

    def resample(self, idx: np.ndarray) -> None:
        """Nothing held per particle."""

    def reinitialise(self) -> None:
        """Nothing held per particle."""


class GyroUnwind:
    """S (N,) per particle, the attitude its gyro hypothesis integrated away from the gyro (rad);
    a share of the particles that leave the hypothesis take it back (module docstring).

    entries (k,): the fault indices of the gyro's item; q_row: the gyro's measurement row; dt (s);
    share in [0, 1]; N particles.
    """

    def __init__(self, entries: np.ndarray, q_row: int, dt: float, share: float, N: int) -> None:
        self.entries = np.asarray(entries, dtype=int)
        self.q_row = int(q_row)
        self.dt = float(dt)
        self.share = float(share)
        self.S = np.zeros(int(N))

    def before(self, X: np.ndarray, modes: np.ndarray, frame: Frame) -> np.ndarray:
        """Before the jump, on the predicted cloud X (n, N): add this frame's dt (y_q - q) to the
        particles in the gyro's mode 1; returns that (N,) bool mask."""
        faulty = modes[self.entries].any(axis=0)
        if frame.mask[self.q_row]:
            y_q = frame.yv[int(frame.row_of[self.q_row])]
            self.S += np.where(faulty, self.dt * (y_q - X[Q]), 0.0)
        return faulty

    def after(self, X: np.ndarray, modes: np.ndarray, held: np.ndarray, rng: np.random.Generator) -> None:
        """After the jump: the share of the particles that left the gyro's mode 1 (held (N,) bool
        before, modes (nf, N) after) take back S into their attitude, in place; S is 0 in mode 0."""
        faulty = modes[self.entries].any(axis=0)
        left = held & ~faulty
        if left.any():
            unwind = left & (rng.random(left.size) < self.share)
            X[THETA, unwind] += self.S[unwind]
        self.S[~faulty] = 0.0

    def resample(self, idx: np.ndarray) -> None:
        """S follows its particles (idx (N,))."""
        self.S = np.take(self.S, idx)

    def reinitialise(self) -> None:
        """A fresh cloud: nothing integrated."""
        self.S[:] = 0.0
