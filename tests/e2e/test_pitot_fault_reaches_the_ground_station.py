"""A pitot that steps by 5.9 m/s in the wind of real-pitot (seed 2: at 12.1 s), flown by the
simulator speaking as a stock ArduPlane (VFR_HUD airspeed) into `fdir run` with the fault
catalogue (config/estimators/aerosonde-catalogue.toml): the ground station reads it on the pitot,
in words ("FDIR pitot fault ...") and typed on FDIR_ESTIMATE, and nothing else is declared."""

from __future__ import annotations

from fdir_service.mavlink import dialect, unpack_fault_types
from tests.helpers.loopback import CATALOGUE_SPEED, fly_into_service

ONSET_S = 12.1      # real-pitot, --seed 2: the pitot's 5.94 m/s step, 12.1-24.7 s
SECONDS = 24.0


def test_a_pitot_step_is_announced_on_the_pitot_and_typed_on_the_estimate():
    f = fly_into_service(["--autopilot", "auto", "--estimator", "aerosonde-catalogue"],
                         ["real-pitot", "--seed", "2", "--profile", "ardupilot", "--speed", CATALOGUE_SPEED,
                          "--nav", "truth", "--duration", str(SECONDS), "--wait", "60"])
    assert f.service_rc == 0 and "aerosonde-catalogue" in f.service_err, f.service_err
    declared = [(t, txt) for t, _, txt in f.gs.statustexts
                if txt.startswith("FDIR ") and " cleared" not in txt and " p=" in txt]
    assert declared and all(txt.startswith("FDIR pitot ") for _, txt in declared), f.gs.statustexts
    assert ONSET_S <= declared[0][0] < ONSET_S + 2.0
    typed = [unpack_fault_types(m.fault_type) for _, m in f.gs.estimates if getattr(m, "fault_type", None)]
    assert any(dialect.FDIR_FAULT_TYPE_BIAS in codes for codes in typed)
