"""`runtime.params.ParamRequester`: which parameters are asked for, how they are paced and
retried, the channel follow-up, completion and the report; the profile's `[parameter_requests]`
validation. Time is passed in (s); the autopilot's answers are PARAM_VALUE message objects."""

from __future__ import annotations

import dataclasses
import math

import pytest

from fdir_service.autopilot_profile import apply_profile, profile_path
from fdir_service.errors import ConfigError
from fdir_service.mavlink import dialect
from fdir_service.runtime.events import ParametersRequested
from fdir_service.runtime.params import ParamRequester, expand, first_requests
from fdir_service.service_config import ServiceConfig, StreamConfig, load_service_config

ARDUPILOT = apply_profile(load_service_config(), "ardupilot")
PX4 = apply_profile(load_service_config(), "px4")
STREAMS = StreamConfig(ack_timeout_s=1.0, retries=2, parameters_in_flight=4)
DEFAULT_FUNCTIONS = {1: 4, 2: 19, 3: 70, 4: 21}


def value(name: str, v: float, ptype: int = dialect.MAV_PARAM_TYPE_INT16):
    """The autopilot's PARAM_VALUE of `name` = v (ArduPilot: an integer cast to float)."""
    return dialect.MAVLink_param_value_message(name.encode("ascii"), float(v), ptype, 80, 0)


def names(msgs: list) -> list[str]:
    """The param_ids of PARAM_REQUEST_READs (each checked: by name, to system 1 component 1)."""
    assert all(m.get_type() == "PARAM_REQUEST_READ" and m.param_index == -1
               and (m.target_system, m.target_component) == (1, 1) for m in msgs)
    return [m.param_id.decode() if isinstance(m.param_id, bytes) else m.param_id for m in msgs]


class Autopilot:
    """Answers each request from `params` (name -> value); a missing name is never answered."""

    def __init__(self, params: dict[str, float]) -> None:
        self.params = params
        self.asked: list[str] = []

    def run(self, req: ParamRequester, first: list, now: float = 0.0) -> None:
        """Answer until nothing more is sent; unanswered ones are polled out second by second."""
        pending = names(first)
        while not req.done:
            while pending:
                name = pending.pop(0)
                self.asked.append(name)
                if name in self.params:
                    pending += names(req.on_value(value(name, self.params[name]), now))
            now += 1.0
            pending += names(req.poll(now))


def arduplane(**changes: float) -> dict[str, float]:
    """A stock ArduPlane's SERVOn_* (all 16 outputs) with some changed."""
    p = {f"SERVO{n}_FUNCTION": float(DEFAULT_FUNCTIONS.get(n, 0)) for n in range(1, 17)}
    for n in range(1, 17):
        p.update({f"SERVO{n}_MIN": 1100.0, f"SERVO{n}_TRIM": 1500.0, f"SERVO{n}_MAX": 1900.0,
                  f"SERVO{n}_REVERSED": 0.0})
    return {**p, **changes}


def test_the_first_requests_are_the_profiles_parameters_then_every_servo_function():
    first = first_requests(ARDUPILOT)
    assert first[:12] == [name for name, _ in ARDUPILOT.parameters]
    assert first[12:] == [f"SERVO{n}_FUNCTION" for n in range(5, 17)]   # 1..4 are among the defaults
    assert expand("CA_SV_CS{i}_TYPE") == [f"CA_SV_CS{i}_TYPE" for i in range(8)]
    assert first_requests(PX4) == [name for name, _ in PX4.parameters]


def test_requests_are_paced_a_few_in_flight_and_each_answer_releases_the_next():
    req = ParamRequester(STREAMS, ARDUPILOT)
    first = names(req.start(1, 1, 0.0))
    assert first == ["SERVO1_FUNCTION", "SERVO2_FUNCTION", "SERVO3_FUNCTION", "SERVO4_FUNCTION"]
    assert req.start(1, 1, 0.0) == []                                    # only the first HEARTBEAT
    assert names(req.on_value(value("SERVO2_FUNCTION", 19), 0.1)) == ["SERVO2_MIN"]
    assert req.poll(0.5) == []                                           # nothing timed out yet
    assert names(req.on_value(value("NOT_ASKED", 1), 0.2)) == []         # an unasked one frees nothing
    assert not req.done and req.report is None


def test_unanswered_requests_are_sent_again_then_given_up_and_reported_at_the_default():
    req = ParamRequester(dataclasses.replace(STREAMS, retries=1), ARDUPILOT)
    first = names(req.start(1, 1, 0.0))
    assert names(req.poll(0.9)) == []
    assert names(req.poll(1.0)) == first                                 # the same 4 again
    given_up = names(req.poll(2.0))
    assert given_up == ["SERVO2_MIN", "SERVO2_TRIM", "SERVO2_MAX", "SERVO2_REVERSED"]   # next 4
    assert not req.done and {"SERVO1_FUNCTION", "SERVO4_FUNCTION"} <= set(req.unanswered)


def test_a_stock_arduplane_confirms_every_parameter_and_the_channels_follow_the_defaults():
    req = ParamRequester(STREAMS, ARDUPILOT)
    ap = Autopilot(arduplane())
    ap.run(req, req.start(1, 1, 0.0))
    report = req.report
    assert isinstance(report, ParametersRequested)
    assert report.defaulted == () and report.unknown == () and report.level == "info"
    assert len(report.confirmed) == 24 and len(ap.asked) == 24           # the channel ones were asked already
    assert report.text.startswith("parameters confirmed by the autopilot: SERVO1_FUNCTION, SERVO2_FUNCTION")
    req.report = None                                                    # the caller took it
    assert req.on_value(value("SERVO2_TRIM", 1510), 30.0) == [] and req.poll(31.0) == []
    assert req.report is None                                            # reported once only


def test_a_non_default_elevator_output_is_found_and_its_limits_asked_for():
    req = ParamRequester(STREAMS, ARDUPILOT)
    ap = Autopilot(arduplane(SERVO2_FUNCTION=0, SERVO5_FUNCTION=19, SERVO5_REVERSED=1))
    ap.run(req, req.start(1, 1, 0.0))
    assert ap.asked[-4:] == ["SERVO5_MIN", "SERVO5_TRIM", "SERVO5_MAX", "SERVO5_REVERSED"]
    assert req.cache.servo_channel(19) == 5 and req.cache.params["SERVO5_REVERSED"] == 1
    assert "SERVO5_REVERSED" in req.report.confirmed


def test_a_parameter_never_answered_is_reported_as_the_profiles_default():
    req = ParamRequester(STREAMS, ARDUPILOT)
    params = arduplane()
    del params["SERVO3_MAX"], params["SERVO9_FUNCTION"]
    ap = Autopilot(params)
    ap.run(req, req.start(1, 1, 0.0))
    assert ap.asked.count("SERVO3_MAX") == 3                             # sent, then retried twice
    report = req.report
    assert report.defaulted == ("SERVO3_MAX",) and report.unknown == ("SERVO9_FUNCTION",)
    assert report.level == "warning"
    assert ("at the profile's default (no answer): SERVO3_MAX; no answer, no default: SERVO9_FUNCTION"
            in report.text)
    assert "SERVO3_MAX" not in report.confirmed


def test_px4_integers_sent_bytewise_are_confirmed():
    import struct

    req = ParamRequester(STREAMS, PX4)
    first = names(req.start(1, 1, 0.0))
    bytewise = struct.unpack("<f", struct.pack("<i", 3))[0]
    req.on_value(value(first[2], bytewise, dialect.MAV_PARAM_TYPE_INT32), 0.1)
    assert req.confirmed == {"CA_SV_CS2_TYPE": 3.0}


@pytest.mark.parametrize(("table", "wrong"), [
    ('names = ["SERVO{n}_FUNCTION_TOO_LONG"]', "up to 16 characters"),
    ('names = ["SERVO{k}_MIN"]', "optionally with one {n}"),
    ('channel = ["SERVO_MIN"]', "with {n}"),
    ('channel = ["CA_SV_CS{i}_TYPE"]', "with {n}"),
    ('bogus = 1', "bogus"),
])
def test_the_profiles_parameter_requests_are_validated(table, wrong):
    text = profile_path("ardupilot").read_text()
    text = text[:text.index("[parameter_requests]")] + f"[parameter_requests]\n{table}\n"
    with pytest.raises(ConfigError, match="parameter_requests") as err:
        apply_profile(load_service_config(), "ardupilot", {"ardupilot": text})
    assert wrong in str(err.value)


@pytest.mark.parametrize("value_text", ["0", "33", "true"])
def test_parameters_in_flight_is_validated(value_text):
    text = load_service_config().text.replace("parameters_in_flight = 4",
                                              f"parameters_in_flight = {value_text}")
    with pytest.raises(ConfigError, match="parameters_in_flight"):
        ServiceConfig.from_toml_text(text)


def test_the_simulated_arduplane_outputs_and_answers_follow_its_parameters():
    from sim_bridge.profiles import ARDUPLANE_SERVO_PARAMS, ArduPlaneMessages, make_message_set
    from sim_bridge.scenario import load_scenario

    scenario = load_scenario("real-calm-faultfree")
    moved = ArduPlaneMessages(scenario, params={"SERVO2_FUNCTION": 4, "SERVO5_FUNCTION": 19,
                                                "SERVO5_REVERSED": 1})
    stock = ArduPlaneMessages(scenario)
    up = math.radians(-12.5)                                   # trailing edge up: half the travel nose-up
    assert stock._servos(up, 0.5)[:5] == [1500, 1700, 1500, 1500, 0]
    assert moved._servos(up, 0.5)[:5] == [1500, 1500, 1500, 1500, 1300]   # reversed on output 5
    assert moved.PARAMS["SERVO5_FUNCTION"] == (19, ARDUPLANE_SERVO_PARAMS["SERVO5_FUNCTION"][1])
    with pytest.raises(ValueError, match="SERVO17_MIN"):
        ArduPlaneMessages(scenario, params={"SERVO17_MIN": 1000})
    with pytest.raises(ValueError, match="only the ardupilot profile"):
        make_message_set("px4", scenario, params={"PWM_MAIN_REV": 4})
