"""An attitude reading that starts to ramp is, for its first seconds, as well explained by a gyro
bias whose integral follows it. The particles that hold the gyro faulty walk their attitude along
the ramp; when the attitude's own fault takes over, the attitude state stays where they left it,
and through h' = u sin(theta) - w cos(theta) the altitude leaves the altimeters: the barometer is
declared beside the attitude. With parts.gyro_exit_unwind = 0.5 (`gyro_unwind.GyroUnwind`) half
the particles that leave the gyro's fault take back the attitude their gyro hypothesis integrated
(docs/faults.md, "The attitude a gyro fault integrated").

real-drift run 14 (campaign seed 0), the monitor loop, to 40 s: the attitude reading ramps
18.8-30.7 s (0.5 deg/s); the gyro's hypothesis holds 60-85 % of the weight at 20.5-24 s. Flown
with the catalogue's fault-free value as it was when traced (stop 52's, `MEMORY_AT_STOP_52`)."""

from __future__ import annotations

from tests.helpers.declarations import MEMORY_AT_STOP_52, declared_when_quiet, fly_with_parts

TRACED = ("real-drift", 14, 40.0)                  # world, run, seconds flown


def test_with_the_unwind_only_the_attitude_is_declared_and_the_altitude_holds():
    found, altitude_error = fly_with_parts(*TRACED, gyro_exit_unwind=0.5, **MEMORY_AT_STOP_52)
    assert set(found) == {"theta"} and 18.8 < found["theta"] < 25.0
    assert altitude_error < 1.5
    assert declared_when_quiet(*TRACED, gyro_exit_unwind=0.5, **MEMORY_AT_STOP_52) == {}


def test_without_it_the_altitude_leaves_and_the_barometer_stands_after_the_ramp():
    found, altitude_error = fly_with_parts(*TRACED, gyro_exit_unwind=0.0, **MEMORY_AT_STOP_52)
    assert "baro" in found and altitude_error > 5.0
    standing = declared_when_quiet(*TRACED, gyro_exit_unwind=0.0, **MEMORY_AT_STOP_52)
    assert standing.get("baro", 0.0) > 3.0
