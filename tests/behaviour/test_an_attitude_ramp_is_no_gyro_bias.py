"""An attitude reading that ramps (0.6 deg/s) disagrees with the gyro's integral exactly as a gyro
bias would, and the rate window proposes gyro sentinels with that bias. With both the gyro and
the attitude free to be faulty at once, the cloud followed the ramping reading through gyro-faulty
particles, theta went 3-4 deg off, the altitude 9 m, and the barometer was declared before the
attitude. With parts.exclusive_items = ["theta q"] (`fault_types.ItemExclusion`; not the default)
a particle that holds the gyro faulty cannot also hold the attitude faulty: the ramp is declared on
the attitude first, and the altitude holds (docs/faults.md, "The pitch chain in one place, measured").

real-drift run 2 (campaign seed 0), monitor loop, to 42 s: the attitude reading ramps 21.6-35.6 s
(to 8.2 deg). In the campaign without the exclusion the barometer stood at 38.7 s: a false alarm."""

from __future__ import annotations

from tests.helpers.declarations import TRACED_BEFORE_STOP_52, fly_with_parts


def flight(exclusive: tuple[str, ...]) -> tuple[dict[str, float], float]:
    """({item: first declared (s)}, the largest altitude error (m)) with those exclusive items."""
    return fly_with_parts("real-drift", 2, 42.0, exclusive_items=exclusive,
                          **TRACED_BEFORE_STOP_52)


def test_the_attitude_is_declared_and_the_altitude_holds():
    found, altitude_error = flight(("theta q",))
    assert set(found) == {"theta"} and 21.6 < found["theta"] < 27.0
    assert altitude_error < 2.0


def test_without_the_exclusion_the_barometer_is_declared_first():
    found, altitude_error = flight(())
    assert found["baro"] < found["theta"] and altitude_error > 6.0
