"""The service asks the autopilot for the parameters its profile reads, and uses the answers.

`sim-bridge fly --profile ardupilot` with the elevator NOT on ArduPlane's default output: SERVO2 is
a second aileron (SERVO2_FUNCTION = 4) and the elevator is on output 5, reversed (SERVO5_FUNCTION =
19, SERVO5_REVERSED = 1). The simulated ArduPlane, as a stock one, sends PARAM_VALUE only when
asked. Flown into `fdir run --autopilot auto` over loopback UDP: after the HEARTBEAT the service
asks (PARAM_REQUEST_READ), finds the elevator on output 5 and asks for its MIN / TRIM / MAX /
REVERSED, and its delta_e input is the autopilot's elevator command to PWM resolution, sign
included. The same recorded input without the PARAM_VALUE answers (what the service had before
it asked: the profile's defaults) reads the aileron on output 2 as the elevator: wrong."""

from __future__ import annotations

import math

import pytest

from fdir_service.recording.logtools import McapLog
from tests.e2e.test_sim_ardupilot_profile_into_service import SCENARIO, command_errors, frames_of
from tests.helpers.loopback import ROBUST_SPEED, fly_into_service

MOVED_ELEVATOR = ("SERVO2_FUNCTION=4", "SERVO5_FUNCTION=19", "SERVO5_REVERSED=1")
HALF_US_RAD = 0.5 * math.radians(25.0) / 400 + 1e-6
"""Half a microsecond of elevator PWM (25 deg over SERVO5_MAX - TRIM = 400 us), rad."""


@pytest.fixture(scope="module")
def flight(tmp_path_factory):
    """(service recording, truth recording, the service's stderr) of a 20 s flight."""
    tmp = tmp_path_factory.mktemp("params")
    log, truth = tmp / "flight.mcap", tmp / "truth.mcap"
    params = [a for p in MOVED_ELEVATOR for a in ("--param", p)]
    f = fly_into_service(["--autopilot", "auto", "--record", str(log)],
                         [SCENARIO, "--profile", "ardupilot", *params, "--speed", ROBUST_SPEED,
                          "--nav", "truth", "--duration", "20", "--record", str(truth), "--wait", "60"])
    assert f.service_rc == 0 and f.sim_rc == 0, f.service_err + f.sim_err
    return log, truth, f.service_err


def test_the_service_reports_the_parameters_the_autopilot_confirmed(flight):
    log, _, err = flight
    logged = [r["message"] for _, r in McapLog(log).iter_json("/fdir/log")]
    report = [m for m in logged if "parameters confirmed by the autopilot" in m]
    assert len(report) == 1, logged
    confirmed = report[0].split(": ", 1)[1].split(", ")
    assert {"SERVO2_FUNCTION", "SERVO5_FUNCTION", "SERVO5_MIN", "SERVO5_TRIM", "SERVO5_MAX",
            "SERVO5_REVERSED", "SERVO3_MAX"} <= set(confirmed)
    assert "default" not in report[0] and "no answer" not in report[0]
    assert "fdir: parameters confirmed by the autopilot: SERVO1_FUNCTION" in err


def test_the_elevator_on_a_moved_reversed_output_is_right_because_the_service_asked(flight):
    log, truth, _ = flight
    _, calls, _ = frames_of(log)
    err = command_errors(calls, truth, t_from=2.0)
    assert len(err) > 300
    assert err[:, 0].max() <= HALF_US_RAD, err[:, 0].max()
    assert err[:, 1].max() <= 0.5 / 800 + 1e-6

    _, blind, _ = frames_of(log, drop=("PARAM_VALUE",))            # the profile's defaults only
    wrong = command_errors(blind, truth, t_from=2.0)
    assert len(wrong) > 300
    assert wrong[:, 0].max() > 100 * HALF_US_RAD                   # the aileron's trim read as elevator
