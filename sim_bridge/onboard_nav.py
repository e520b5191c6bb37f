"""What the autopilot flies on (docs/real-world.md, "Whose estimate the autopilot flies on").

`[world.autopilot] navigation`:
- "monitor" (the thesis's closed loop, the default): the autopilot flies on the monitor's own
  estimate, so a monitor that loses the state upsets its aircraft, and the upset raises more alarms.
- "onboard": the autopilot flies on its own navigation, as a stock ArduPilot or PX4 does next to
  this monitor (their EKF, not our estimate): the true state seen through the autopilot's primary
  sensors, faults included, without their noise. The monitor then only watches. A stuck gyro or
  attitude sensor then takes the pitch loop's feedback and the aircraft upsets (as it would with
  one IMU and no fault handling): a crash test rather than a test of the monitor.
- "truth": the autopilot flies on the true state: a navigation that the faulty sensor does not
  reach (redundant sensors, EKF lanes that switch away from a failing IMU, as ArduPilot's EKF3
  and PX4's EKF2 run). The monitor only watches, and the flight is the same whatever it says.

The onboard navigation is an autopilot EKF that follows its sensors and has no fault detection of
its own: each injected sensor fault's additive-equivalent value (`sim_bridge.fault_types`: a bias's
offset, a stuck or blocked reading's distance from the true reading) moves the state its row
measures. The barometer is the height source (ArduPilot's EK3_SRC1_POSZ and PX4's EKF2_HGT_REF
default), so a GNSS altitude fault moves nothing; the accelerometer's rows move nothing; the pitot
moves the airspeed the autopilot holds. A noisy sensor's extra noise is left out (an EKF smooths it).
"""

from __future__ import annotations

import numpy as np

NAVIGATION = ("monitor", "onboard", "truth")
"""`[world.autopilot] navigation` values (module docstring)."""

STATE_OF_ROW = {"baro_alt": (0, -1.0), "u": (1, 1.0), "w": (2, 1.0), "theta": (3, 1.0), "q": (4, 1.0)}
"""Sensor row -> (state index, sign): how a fault on that row moves the onboard state
[p_d m (down), u, w m/s, theta rad, q rad/s]; a barometer reading f high puts p_d f lower."""

AIRSPEED_ROW = "airspeed"
"""The pitot's row: its fault moves the air-relative forward speed the autopilot holds."""

TYPES_LEFT_OUT = ("noisy",)
"""Sensor fault types whose value is not an offset of the reading (a noisy fault's k - 1)."""


class OnboardNavigation:
    """The onboard state (5,) the autopilot flies on, from a frame's truth and its faults.

    faults: the world's fault channels (`Scenario.faults`), in the order of `Frame.faults`.
    """

    def __init__(self, faults) -> None:
        n = len(faults)
        self.offset = np.zeros((5, n))
        """(5, nf): the onboard state's move per unit of each channel's additive-equivalent value."""
        self.airspeed = np.zeros(n)
        """(nf,): the held airspeed's move per unit of each channel's value (the pitot's faults)."""
        for j, f in enumerate(faults):
            if f.kind != "sensor" or f.fault_type in TYPES_LEFT_OUT:
                continue
            if f.target in STATE_OF_ROW:
                i, sign = STATE_OF_ROW[f.target]
                self.offset[i, j] = sign
            elif f.target == AIRSPEED_ROW:
                self.airspeed[j] = 1.0

    def view(self, frame) -> np.ndarray:
        """What the autopilot flies on at `frame` (`simulate.Frame`): its state (5,), u and w
        air-relative by the world's wind (`Frame.autopilot_view`), the pitot's faults on u."""
        f = np.nan_to_num(np.asarray(frame.faults, dtype=float))   # a jammed input's NaN: an actuator
        z = frame.autopilot_view(frame.z_true + self.offset @ f)   # a new array, ours to change
        z[1] += self.airspeed @ f
        return z


class TrueNavigation:
    """The autopilot's navigation under navigation = "truth": the true state (module docstring)."""

    def view(self, frame) -> np.ndarray:
        """The true state (5,), u and w air-relative by the world's wind (`Frame.autopilot_view`)."""
        return frame.autopilot_view(frame.z_true)


def autopilot_navigation(navigation: str, faults) -> OnboardNavigation | TrueNavigation | None:
    """The navigation the autopilot flies on for `[world.autopilot] navigation`, None for "monitor"
    (it flies on the monitor's estimate); faults: the world's channels (`Scenario.faults`)."""
    if navigation == "onboard":
        return OnboardNavigation(faults)
    return TrueNavigation() if navigation == "truth" else None
