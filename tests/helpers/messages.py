"""Hand-made autopilot messages of one frame (GNSS, baro, attitude, odometry; actuator outputs) for
the frame-assembly tests, and a feeder."""

from __future__ import annotations

import math

import numpy as np

from fdir_service.atmosphere import pressure_from_altitude
from fdir_service.mavlink import dialect

TRIM_U = np.array([-0.083, 0.532])


P500_HPA = pressure_from_altitude(500.0) / 100.0


def sensors(t_ms: int, alt=500.0, press_hpa=P500_HPA, pitch=0.05, q=0.0, u=40.0, w=1.9):
    nan = math.nan
    return [
        dialect.MAVLink_gps_raw_int_message(t_ms * 1000, 3, 0, 0, int(alt * 1000), 100, 150, 0, 0, 12),
        dialect.MAVLink_scaled_pressure_message(t_ms, press_hpa, 0.0, 1500),
        dialect.MAVLink_attitude_message(t_ms, 0.0, pitch, 0.0, 0.0, q, 0.0),
        dialect.MAVLink_odometry_message(t_ms * 1000, 1, 12, nan, nan, nan, [1, 0, 0, 0], u, nan, w,
                                         nan, nan, nan, [nan] * 21, [nan] * 21, 0, 1, 0),
    ]


def actuators(t_ms: int, de: float, dt: float):
    act = [0.0] * 32
    act[0], act[1] = de, dt
    return [dialect.MAVLink_actuator_output_status_message(t_ms * 1000, 3, act)]


def feed(asm, msgs):
    """Every frame the assembler completes on msgs."""
    out = []
    for m in msgs:
        out += asm.accept(m)
    return out
