"""The simulated Aerosonde on the wire: what an autopilot would send, and the estimates coming back.

Sent per frame k (all stamped with the simulation time t_k; `time_boot_ms` = round(t_k * 1000),
`time_usec` = round(t_k * 1e6)), only for the measurements the scenario has:
  GPS_RAW_INT      alt (mm above MSL) = GNSS altitude measurement
  SCALED_PRESSURE  press_abs (hPa) = the barometer's static pressure (barometric formula)
  ATTITUDE         pitch (rad), pitchspeed (rad/s) = measured pitch and pitch rate
                   (roll, rollspeed, yawspeed too when the world measures them, JSBSim's)
  ODOMETRY         child_frame_id MAV_FRAME_BODY_FRD; vx, vz (m/s) = measured body velocities u, w;
                   pose unknown (NaN) - the truth never goes on the wire
and, once the autopilot has computed u_k, the actuator outputs stamped t_k:
  SERVO_OUTPUT_RAW servo2_raw = elevator: 1500 + 500 * delta_e / 30 deg us (1000..2000),
                   servo3_raw = throttle: 1000 + 1000 * delta_t us (ArduPlane channel order)
  ACTUATOR_OUTPUT_STATUS actuator[0] = delta_e (rad), actuator[1] = delta_t (0..1), float32:
                   the unquantised copy (1 us of PWM is 0.06 deg of elevator).
HEARTBEAT (MAV_TYPE_FIXED_WING, system 1, component 1) once per second of simulation time.
That is the "native" message set; `profile="ardupilot"` sends ArduPlane's stock set instead,
`profile="px4"` PX4's Onboard-mode set (`sim_bridge.profiles`, `sim-bridge fly --profile`).
"""

from __future__ import annotations

import numpy as np

from fdir_service.mavlink import new_mavlink
from fdir_service.mavlink import pack as fast_pack
from sim_bridge.profiles import (  # noqa: F401  (re-exported: the native PWM scaling)
    ELEVATOR_PWM_RANGE_RAD,
    elevator_to_pwm,
    make_message_set,
    throttle_to_pwm,
)
from sim_bridge.scenario import Scenario


class AutopilotLink:
    """Encodes the simulator's frames as an autopilot's MAVLink 2 stream and decodes replies.

    system/component: the autopilot's ids; key: optional 32-byte signing key; profile: the message
    set on the wire (`sim_bridge.profiles`: "native", the default, "ardupilot" or "px4"); params:
    parameter values that differ from the profile's defaults (ardupilot: its SERVOn_*).
    """

    def __init__(self, scenario: Scenario, system: int = 1, component: int = 1,
                 key: bytes | None = None, signing_timestamp: int = 0, profile: str = "native",
                 params: dict[str, float] | None = None) -> None:
        self.scenario = scenario
        self.rows = {name: j for j, name in enumerate(scenario.sensors.measurements)}
        self.messages = make_message_set(profile, scenario, system, params)
        self.profile = profile
        self.tx = new_mavlink(system, component, key=key, initial_timestamp=signing_timestamp)
        self.rx = new_mavlink(255, 0, key=key)
        self._last_hb_s: int | None = None

    def _pack(self, msg) -> bytes:
        return fast_pack(msg, self.tx)   # = bytes(msg.pack(self.tx)), cheaper

    def heartbeat(self) -> bytes:
        """The profile's HEARTBEAT (fixed wing, armed, auto mode)."""
        return self._pack(self.messages.heartbeat())

    def sensor_messages(self, t: float, y: np.ndarray, mask: np.ndarray,
                        static_pressure_pa: float) -> list[bytes]:
        """The sensor messages of one frame at simulation time t (s), HEARTBEAT first on each new
        second; y (m,) SI in scenario row order, mask (m,) the rows measured; static pressure Pa.
        The messages and their order are the profile's (`sim_bridge.profiles`)."""
        t_ms = int(round(t * 1000.0))
        out: list[bytes] = []
        if self._last_hb_s != t_ms // 1000:
            self._last_hb_s = t_ms // 1000
            out.append(self.heartbeat())
        values = {name: (float(y[j]) if mask[j] else None) for name, j in self.rows.items()}
        out.extend(self._pack(m) for m in self.messages.sensors(t, values, static_pressure_pa))
        return out

    def actuator_messages(self, t: float, u_cmd: np.ndarray) -> list[bytes]:
        """The actuator messages for the command u_cmd (2,) [delta_e rad, delta_t 0..1] at t (s):
        native SERVO_OUTPUT_RAW + ACTUATOR_OUTPUT_STATUS, ardupilot / px4 SERVO_OUTPUT_RAW."""
        return [self._pack(m) for m in self.messages.actuators(t, u_cmd)]

    def answer(self, msg) -> list[bytes]:
        """The autopilot's replies to a message from the service (ardupilot, px4: PARAM_VALUEs;
        every profile: COMMAND_ACK for a stream request)."""
        return [self._pack(m) for m in self.messages.answer(msg)]

    def parse(self, data: bytes) -> list:
        """Decode bytes coming back from the service (robust; signature checked when keyed)."""
        return [m for m in (self.rx.parse_buffer(data) or []) if m.get_type() != "BAD_DATA"]


class LossyLink:
    """Deterministic random packet loss: each MAVLink packet (one encoded message) is dropped with
    probability `loss`, drawn from its own seeded stream (independent of the simulation's)."""

    def __init__(self, loss: float, seed: int = 0) -> None:
        if not 0.0 <= loss < 1.0:
            raise ValueError(f"packet loss must be in [0, 1), got {loss}")
        self.loss = float(loss)
        self.rng = np.random.default_rng(np.random.SeedSequence([int(seed), 0x1055]))
        self.sent = 0
        self.dropped = 0

    def filter(self, packets: list[bytes]) -> list[bytes]:
        """The packets that survive (order kept)."""
        if not self.loss:
            self.sent += len(packets)
            return list(packets)
        keep = self.rng.random(len(packets)) >= self.loss
        out = [b for b, k in zip(packets, keep, strict=True) if k]
        self.sent += len(out)
        self.dropped += len(packets) - len(out)
        return out


