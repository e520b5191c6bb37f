"""A gyro fault's amplitude from the attitude it should integrate to (docs/robustness.md).

On a kinematic model the pitch rate q is a random walk the gyro row observes, so a gyro bias that
appears is first taken for a real change of q: the next frames' gyro innovations are zero and the
row's own amplitude (eq. 4.16, A = y_q - h_q(x)) proposes no sentinel. What tells the two apart is
theta' = q: over a window of W frames a biased gyro disagrees with the slope of the attitude
sensor. `RateWindowAmplitude` proposes the gyro fault's amplitude as that disagreement,

    b = mean(y_q) - slope(y_theta)      (least squares over the window's frames with both rows),

for every other particle (it is a property of the data, not of a particle), the row's own
amplitude for the rest (at a fault's onset, before the window sees it, the gyro's innovation is the
better guess): a two-component mixture proposal. The other faults' amplitudes are
`AmplitudePredictor`'s. Its std is sqrt(s_q^2 / n + 12 s_theta^2 / (dt^2 n (n^2 - 1))).
With the jump's carry (`jump.ActuatorCarry` with column -e_q) a sentinel's q moves by -dA, so it
still explains this frame's gyro reading and differs from its mode-0 parent only in what it
integrates from now on.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from fdir_service.estimation.amplitude import AmplitudePredictor
from fdir_service.estimation.kernels import window_centred

if TYPE_CHECKING:
    from fdir_service.estimation.frame import Frame


class RateWindow:
    """The last `frames` (theta, q) measurement pairs (rad, rad/s) and their frame times (s), in rows
    (t, theta, q) of a fixed (frames, 3) ring: the oldest at row `start`."""

    def __init__(self, frames: int, min_frames: int) -> None:
        self.buffer = np.empty((int(frames), 3))
        self.count = 0
        self.start = 0
        self.min_frames = int(min_frames)

    def add(self, t: float, theta: float, q: float) -> None:
        size = self.buffer.shape[0]
        if self.count == size:
            self.buffer[self.start] = (t, theta, q)
            self.start = (self.start + 1) % size
        else:
            self.buffer[(self.start + self.count) % size] = (t, theta, q)
            self.count += 1

    def bias(self) -> float | None:
        """mean(q) - LS slope of theta over the window (rad/s); None with too few samples."""
        if self.count < self.min_frames:
            return None
        if self.count > 128:
            return self._numpy_bias()
        tc, thc, q_mean = window_centred(self.buffer, self.start, self.count)
        return q_mean - float(tc @ thc / (tc @ tc))

    def _numpy_bias(self) -> float:
        """`bias` for windows past 128 frames (numpy's sums halve there; `kernels.window_centred`)."""
        n = self.count
        t, th, q = np.roll(self.buffer, -self.start, axis=0)[:n].T
        tc = t - t.sum() / n
        return float(q.sum() / n) - float(tc @ (th - th.sum() / n) / (tc @ tc))


class RateWindowAmplitude(AmplitudePredictor):
    """`AmplitudePredictor` whose gyro fault (index `gyro`) is proposed from a `RateWindow`.

    theta_row, q_row: the observed rows of the attitude and the gyro; window_frames: W.
    """

    def __init__(self, layout, meas, B_actuator, q_airframe, gyro: int, theta_row: int, q_row: int,
                 window_frames: int) -> None:
        super().__init__(layout, meas, B_actuator, q_airframe)
        self.gyro = int(gyro)
        self.theta_row, self.q_row = int(theta_row), int(q_row)
        self.window = RateWindow(window_frames, max(3, window_frames // 2))
        self._bias: float | None = None
        self._rows: dict[bytes, tuple[int, int]] = {}

    def observe(self, frame: Frame) -> None:
        """Add the frame's (theta, q) pair when both rows arrived; update the window's bias."""
        m = frame.mask
        if m[self.theta_row] and m[self.q_row]:
            k_theta, k_q = self._indices(m)
            self.window.add(frame.t, float(frame.yv[k_theta]), float(frame.yv[k_q]))
            self._bias = self.window.bias()

    def _indices(self, mask: np.ndarray) -> tuple[int, int]:
        """The attitude's and the gyro's indices in a frame's yv (its arrived rows), per mask."""
        key = mask.tobytes()
        hit = self._rows.get(key)
        if hit is None:
            hit = self._rows[key] = (int(np.count_nonzero(mask[:self.theta_row])),
                                     int(np.count_nonzero(mask[:self.q_row])))
        return hit

    def predict(self, X: np.ndarray, innovation: np.ndarray, mask: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
        A, avail = super().predict(X, innovation, mask)
        if self._bias is not None and avail[self.gyro]:
            A[self.gyro, ::2] = self._bias
        return A, avail
