"""A gyro that reads steady for a few frames in ordinary flight is not a stuck gyro: the catalogue
estimator, its pitch-rate noise learnt from the flight (parts.q_noise = "learned",
fdir_service/estimation/pitch_noise.py) and its moment reading the angle of attack from the frame's
mean a_z (parts.az_input = "frame_mean"), raises nothing in the first 195 s of
real-catalogue-faultfree run 21 (campaign seed 0, the autopilot on the truth), where the build
before them (the configured noise, the frame's last a_z; and the Euler velocity step, which came
before the rotation of stop 45) let the gyro's stuck entry take the cloud in a steady pitch and
declared the gyro at 192.0 s (stop 42's false alarms; docs/faults.md, "The pitch-rate noise the
flight shows")."""

from __future__ import annotations

import dataclasses

import pytest

from sim_bridge.campaign import fly
from sim_bridge.scenario import load_scenario
from tests.helpers.declarations import TRACED_BEFORE_STOP_52, first_declarations


def declared_items(**parts: str) -> dict[str, float]:
    """{item: first declaration time (s)} over the first 195 s of the flight, by the service's rule,
    with the catalogue's [parts] changed by `parts`."""
    sc = load_scenario("real-catalogue-faultfree")
    est = sc.estimator
    est = dataclasses.replace(est, settings=dataclasses.replace(est.settings,
                                                                **{**TRACED_BEFORE_STOP_52, **parts}))
    sc = dataclasses.replace(sc, estimator=est, navigation="truth", duration_s=195.0)
    return first_declarations(est.faults, fly(sc, "RJMRPF", 21, 0))


def test_the_catalogue_learns_its_pitch_noise_from_the_frames_mean_a_z():
    settings = load_scenario("real-catalogue-faultfree").estimator.settings
    assert (settings.q_noise, settings.az_input) == ("learned", "frame_mean")


@pytest.mark.parametrize("build", ["today", "before"])
def test_a_steady_pitch_raises_nothing_once_the_pitch_noise_is_learnt(build):
    if build == "today":
        assert declared_items() == {}
    else:                              # the contrast: the same flight on the build before
        found = declared_items(q_noise="fixed", az_input="frame_end", velocity_step="euler",
                               frame_angle="trapezoid", moment_alpha="lift", moment_wind="entry",
                               hold_resume="cloud")
        assert set(found) == {"q"} and 191.5 < found["q"] < 192.5
