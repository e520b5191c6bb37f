"""End to end through loopback UDP: `sim-bridge fly --profile ardupilot|px4` (ArduPlane's stock
message set, PX4's Onboard-mode one) into `fdir run --autopilot auto` with the default robust
monitor, in a fault-free real-sky world: the service picks the autopilot's profile from the
HEARTBEAT, the frames carry every row (u, w derived from GLOBAL_POSITION_INT / LOCAL_POSITION_NED
+ ATTITUDE, the elevator from SERVO_OUTPUT_RAW PWM), the inputs are the autopilot's commands to
PWM resolution (elevator sign included), and nothing is declared. The simulated ArduPlane answers
PARAM_REQUEST_LIST / READ with its SERVOn_* defaults (all 16 outputs), the simulated PX4 with px4.toml's
[parameters], integers bytewise."""

from __future__ import annotations

import math
import struct
import tomllib
from pathlib import Path

import numpy as np
import pytest

from fdir_service.autopilot_profile import select_autopilot
from fdir_service.mavlink import dialect, new_mavlink
from fdir_service.pipeline import Pipeline
from fdir_service.recording.logtools import McapLog
from fdir_service.replay import raw_input
from fdir_service.runtime.derived import param_number
from fdir_service.service_config import load_service_config
from sim_bridge.mavlink_bridge import AutopilotLink
from sim_bridge.scenario import load_scenario
from tests.helpers.loopback import ROBUST_SPEED, ROOT, fly_into_service
from tests.helpers.service import fake_factory

SCENARIO = "real-calm-faultfree"
SECONDS = 25.0
PROFILES = {
    # --profile: (what the service logs on selecting it, elevator PWM (us) over 25 deg, throttle PWM
    # span (us)): ArduPlane's SERVOn_MIN / TRIM / MAX 1100 / 1500 / 1900, px4.toml's PWM_MAIN 1000 / 2000
    "ardupilot": ("autopilot profile ardupilot (HEARTBEAT autopilot 3)", 400, 800),
    "px4": ("autopilot profile px4 (HEARTBEAT autopilot 12)", 500, 1000),
}


@pytest.fixture(scope="module", params=list(PROFILES))
def flight(request, tmp_path_factory):
    """(profile, ground station, service recording, truth recording, stderr of both) of one flight."""
    profile = request.param
    tmp = tmp_path_factory.mktemp(f"sim{profile}")
    log, truth = tmp / "flight.mcap", tmp / "truth.mcap"
    f = fly_into_service(["--autopilot", "auto", "--record", str(log)],
                         [SCENARIO, "--profile", profile, "--speed", ROBUST_SPEED, "--nav", "truth",
                          "--duration", str(SECONDS), "--record", str(truth), "--wait", "60"])
    assert f.service_rc == 0 and "aerosonde-robust" in f.service_err, f.service_err
    assert f.sim_rc == 0 and f"profile {profile}" in f.sim_err, f.sim_err
    return profile, f.gs, log, truth, f.service_err + f.sim_err


def _without(data: bytes, drop: tuple[str, ...]) -> bytes:
    """The MAVLink packets in `data` but those of the message types `drop`."""
    if not drop:
        return data
    msgs = new_mavlink(255, 0).parse_buffer(data) or []
    return b"".join(bytes(m.get_msgbuf()) for m in msgs if m.get_type() not in drop)


def frames_of(log: Path, drop: tuple[str, ...] = ()) -> tuple[list[str], list, Pipeline]:
    """The recorded input bytes (without the message types `drop`) through `--autopilot auto`'s
    pipeline with a recording fake filter: (row names, [(t, y, mask, u)] per frame, pipeline)."""
    config = select_autopilot(load_service_config(estimator="aerosonde-robust"), "auto")
    filters: list = []
    p = Pipeline(config, observers=[], filter_factory=fake_factory(filters))
    for t_ns, data in raw_input(McapLog(log)):
        p.feed(_without(data, drop), t_ns)
    p.close()
    return p.assembler.names, [c for f in filters for c in f.calls], p


def command_errors(calls: list, truth: Path, t_from: float = 1.0) -> np.ndarray:
    """(frames, 2) |input - the autopilot's command| [delta_e rad, delta_t] of the frames `calls`
    from t_from (s) on, against the simulator's truth recording (the command of the frame before)."""
    cmd = {round(r["t"], 3): (r["delta_e"], r["delta_t"]) for _, r in McapLog(truth).iter_json("/sim/truth")}
    err = [np.subtract(u, cmd[round(t - 0.05, 3)]) for t, _, _, u in calls
           if t >= t_from and round(t - 0.05, 3) in cmd]
    return np.abs(np.array(err))


def test_the_service_selects_the_profile_and_every_row_is_there(flight):
    profile, _, log, _, err = flight
    logged = [r["message"] for _, r in McapLog(log).iter_json("/fdir/log")]
    assert any(PROFILES[profile][0] in m for m in logged), (logged, err)
    names, calls, p = frames_of(log)
    assert len(calls) >= 0.95 * SECONDS / 0.05, (len(calls), dict(p.rejected_counts))
    settled = [c for c in calls if c[0] >= 1.0]
    mask = np.array([m for _, _, m, _ in settled])
    for _, y, m, u in settled:
        assert np.all(np.isfinite(y[m])) and np.all(np.isfinite(u))
    seen = dict(zip(names, mask.mean(axis=0), strict=True))
    # GNSS at 5 Hz: a fix in every 4th 20 Hz frame; every other row in >= 90 % of the frames
    assert all(v >= 0.9 for n, v in seen.items() if n != "gnss_alt"), seen
    assert seen["gnss_alt"] >= 0.9 * 0.25, seen
    assert not any("not derivable" in k for k in p.rejected_counts), dict(p.rejected_counts)


def test_inputs_are_the_commands_to_pwm_resolution(flight):
    """delta_e from the elevator's PWM (ArduPilot, PX4: + = nose up) equals the autopilot's command:
    sign and scale."""
    profile, _, log, truth, _ = flight
    _, elevator_us, throttle_us = PROFILES[profile]
    _, calls, _ = frames_of(log)
    err = command_errors(calls, truth)
    assert len(err) > 400
    err = err.max(axis=0)
    assert err[0] <= 0.5 * math.radians(25.0) / elevator_us + 1e-6, err   # half a microsecond of PWM
    assert err[1] <= 0.5 / throttle_us + 1e-6, err


def test_a_fault_free_flight_declares_nothing(flight):
    _, gs, _, _, _ = flight
    assert gs.estimates, gs.statustexts
    declared = [txt for _, _, txt in gs.statustexts if txt.startswith("FDIR") and "fault" in txt]
    assert declared == [], declared


def _asker(profile: str, count: int):
    """ask(request) -> {param_id: the value as the service decodes it} of the simulated autopilot's
    PARAM_VALUE replies (each checked to announce `count` parameters); ask.raw: the replies."""
    link = AutopilotLink(load_scenario(SCENARIO), profile=profile)

    def ask(msg) -> dict[str, float]:
        ask.raw = link.parse(b"".join(link.answer(msg)))
        assert all(r.get_type() == "PARAM_VALUE" and r.param_count == count for r in ask.raw)
        return {r.param_id: param_number(r.param_value, r.param_type) for r in ask.raw}
    return ask


def _read(name: str = "", index: int = -1, system: int = 1):
    """PARAM_REQUEST_READ of `name` (index -1) or `index`, to `system`."""
    return dialect.MAVLink_param_request_read_message(system, 1, name.encode("ascii"), index)


def test_the_simulated_arduplane_answers_parameter_requests():
    ask = _asker("ardupilot", 80)                  # SERVO1..16_FUNCTION, then MIN / TRIM / MAX / REVERSED
    every = ask(dialect.MAVLink_param_request_list_message(1, 1))
    assert every["SERVO2_FUNCTION"] == 19 and every["SERVO3_FUNCTION"] == 70 and len(every) == 80
    assert every["SERVO5_FUNCTION"] == 0 and every["SERVO16_MAX"] == 1900
    assert all(r.param_value == every[r.param_id] for r in ask.raw)       # integers cast to float
    assert ask(_read("SERVO2_TRIM")) == {"SERVO2_TRIM": 1500}
    assert ask(_read(index=22)) == {"SERVO2_MAX": 1900}
    assert ask(_read("NO_SUCH")) == {}
    assert ask(_read("SERVO2_TRIM", system=7)) == {}


def test_the_simulated_px4_answers_with_the_profiles_parameters_bytewise():
    profile = tomllib.loads((ROOT / "config/autopilots/px4.toml").read_text())["parameters"]
    ask = _asker("px4", len(profile))
    assert ask(dialect.MAVLink_param_request_list_message(1, 1)) == profile
    func3 = next(r for r in ask.raw if r.param_id == "PWM_MAIN_FUNC3")
    assert func3.param_type == dialect.MAV_PARAM_TYPE_INT32
    assert struct.pack("<f", func3.param_value) == struct.pack("<i", 203)   # the int32's bytes, not 203.0
    assert ask(_read("CA_SV_CS2_TYPE")) == {"CA_SV_CS2_TYPE": 3}
    assert ask(_read(index=8)) == {"PWM_MAIN_FUNC5": 101}
    assert ask(_read("NO_SUCH")) == {}
    assert ask(_read("PWM_MAIN_REV", system=7)) == {}


@pytest.mark.parametrize("profile", list(PROFILES))
def test_the_simulated_autopilots_ack_stream_requests(profile):
    link = AutopilotLink(load_scenario(SCENARIO), profile=profile)
    req = dialect.MAVLink_command_long_message(1, 1, dialect.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                                               dialect.MAVLINK_MSG_ID_HIGHRES_IMU, 20000, 0, 0, 0, 0, 0)
    (ack,) = link.parse(b"".join(link.answer(req)))
    assert ack.get_type() == "COMMAND_ACK" and ack.result == dialect.MAV_RESULT_ACCEPTED
