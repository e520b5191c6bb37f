"""When the elevator jams, the pitch the moment model misses is first taken for a gyro fault; the
gyro-faulty particles' q then follows the moment model, an attitude drift follows the attitude
they integrate, theta ends 5-8 deg off, w and the altitude with it, and the barometer is blamed
after the jam. The attitude reading and the gyro are the two observers of theta' = q: with
parts.exclusive_items = ["theta q"] (`fault_types.ItemExclusion`; measured, not the catalogue's
default) a particle may hold only one of them faulty, so the pitch chain keeps one anchor
(docs/faults.md, "The pitch chain in one place, measured").

real-actuators run 24 (campaign seed 0), the autopilot on the monitor's estimate as in the
campaign, to 32 s: the elevator jams 20.9-24.0 s. In the campaign without the exclusion the
barometer stood at 27 s, 3 s after the jam's end: a false alarm."""

from __future__ import annotations

from tests.helpers.declarations import TRACED_BEFORE_STOP_52, fly_with_parts


def flight(exclusive: tuple[str, ...]) -> tuple[dict[str, float], float]:
    """({item: first declared (s)}, the largest altitude error (m)) with those exclusive items."""
    return fly_with_parts("real-actuators", 24, 32.0, exclusive_items=exclusive,
                          **TRACED_BEFORE_STOP_52)


def test_with_the_pitch_chain_exclusive_only_the_elevator_is_declared():
    found, altitude_error = flight(("theta q",))
    assert set(found) == {"de"} and 20.9 < found["de"] < 23.0
    assert altitude_error < 3.0


def test_without_it_the_attitude_and_then_the_barometer_are_blamed():
    found, altitude_error = flight(())
    assert 20.9 < found["theta"] < 23.0 and 23.0 < found["baro"] < 26.0
    assert altitude_error > 10.0
