"""Service config validation: defaults load; unknown key, wrong type, impossible value -> ConfigError
naming the key; `fdir run` maps it to exit status 2."""

from __future__ import annotations

import math
import re

import pytest

from fdir_service.atmosphere import pressure_from_altitude
from fdir_service.cli import main
from fdir_service.errors import ConfigError
from fdir_service.service_config import ServiceConfig, default_config_path, load_service_config

BASE = default_config_path().read_text()
DEFAULT_LINE = next(line for line in BASE.splitlines() if line.startswith("estimator = "))
"""The default config's `service.estimator` line (the tests add keys after it)."""


def test_default_config():
    c = load_service_config()
    assert (c.estimator.id, c.filter, c.particles, c.seed) == ("aerosonde-robust", "RJMRPF", 1000, 0)
    assert [m.name for m in c.measurements] == list(c.estimator.measurements)
    assert c.component == 191 and c.frame_period_us == 50_000
    baro = c.measurements[1]
    # hPa -> m (barometric formula)
    assert baro.convert(pressure_from_altitude(500.0) / 100.0) == pytest.approx(500.0, abs=1e-6)
    assert c.measurements[0].convert(500_123) == pytest.approx(500.123)


@pytest.mark.parametrize(("old", "new", "key"), [
    (DEFAULT_LINE, DEFAULT_LINE + '\nparticels = 3', "service.particels"),
    (DEFAULT_LINE, DEFAULT_LINE + '\nparticles = "many"', "service.particles"),
    (DEFAULT_LINE, DEFAULT_LINE + '\nparticles = 0', "service.particles"),
    (DEFAULT_LINE, DEFAULT_LINE + '\nfilter = "XPF"', "service.filter"),
    (DEFAULT_LINE, 'estimator = "no-such-estimator"', "no such estimator file"),
    ('rate_hz = 20.0', 'rate_hz = 50.0', "frames.rate_hz"),
    ('p_clear = 0.5', 'p_clear = 0.95', "publish.declare.p_clear"),
    ('field = "alt"', 'field = "altitude"', "measurements.gnss_alt.field"),
    ('message = "GPS_RAW_INT"', 'message = "GPS_RAW"', "measurements.gnss_alt.message"),
    ('field = "actuator[0]"', 'field = "actuator"', "inputs.delta_e.field"),
    ('transform = "pressure_to_altitude"', 'transform = "magic"', "measurements.baro_alt.transform"),
])
def test_bad_values_name_the_key(old, new, key):
    assert old in BASE
    with pytest.raises(ConfigError, match=key.replace(".", r"\.").replace("[", r"\[")):
        ServiceConfig.from_toml_text(BASE.replace(old, new, 1))


def test_missing_measurement_mapping_is_named():
    text = BASE.replace("[measurements.theta]", "[unused_theta]")
    with pytest.raises(ConfigError, match="unknown key|measurements.theta"):
        ServiceConfig.from_toml_text(text)


def test_pwm_mapping_and_clipping():
    text = BASE.replace('''[inputs.delta_e]
message = "ACTUATOR_OUTPUT_STATUS"
field = "actuator[0]"''', '''[inputs.delta_e]
message = "SERVO_OUTPUT_RAW"
field = "servo2_raw"
transform = "pwm"
min = -0.5235988
max = 0.5235988''')
    text = re.sub(r"valid_min = -1\.0 .*\nvalid_max = 1\.0\n", "", text)
    de = ServiceConfig.from_toml_text(text).inputs[0]
    assert de.convert(1500) == pytest.approx(0.0)
    assert de.convert(1501) == pytest.approx(math.radians(0.06), rel=1e-6)
    assert de.convert(2500) == pytest.approx(math.radians(30.0))


def test_cli_exit_status_2_on_bad_config(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text(BASE.replace(DEFAULT_LINE, DEFAULT_LINE + '\nseed = -1'))
    assert main(["run", "--config", str(bad), "--duration", "0"]) == 2
    assert "service.seed" in capsys.readouterr().err


def test_signing_key_file_checked(tmp_path):
    kf = tmp_path / "key"
    kf.write_text("00" * 31)
    c = ServiceConfig.from_toml_text(BASE.replace('key_file = ""', f'key_file = "{kf}"'))
    with pytest.raises(ConfigError, match="signing.key_file"):
        c.signing_key()
    kf.write_text("ab" * 32)
    assert c.signing_key() == bytes([0xAB]) * 32


def test_scenario_and_service_share_one_reader():
    """Both files go through `fdir_service.tomltable.TomlTable`: same types, coercions and messages."""
    import tomllib

    from sim_bridge.scenario import parse_scenario, scenario_path

    scen = tomllib.loads(scenario_path("ch4").read_text())
    # an int is accepted where a number is expected, and becomes a float
    scen["experiment"]["duration_s"] = 50
    assert type(parse_scenario(scen).duration_s) is float
    c = ServiceConfig.from_toml_text(BASE.replace("max_gap_s = 2.0", "max_gap_s = 3", 1))
    assert c.max_gap_s == 3.0 and type(c.max_gap_s) is float
    # a bool is not a number, and a non-finite number is refused: same message form in both files
    for bad, shown in (("true", "True"), ("inf", "inf")):
        scen["experiment"]["duration_s"] = tomllib.loads(f"v = {bad}")["v"]
        with pytest.raises(ConfigError,
                           match=rf"^experiment\.duration_s: expected a finite number, got {shown}$"):
            parse_scenario(scen)
        with pytest.raises(ConfigError, match=rf"frames\.max_gap_s: expected a finite number, got {shown}$"):
            ServiceConfig.from_toml_text(BASE.replace("max_gap_s = 2.0", f"max_gap_s = {bad}", 1))
