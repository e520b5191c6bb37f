"""An engine that quits, flown by the simulator speaking as a stock ArduPlane, into `fdir run` with
the fault catalogue (config/estimators/aerosonde-catalogue.toml), reaches a stock ground station
as a typed STATUSTEXT ("FDIR dt engine out, thrust 2% ...") and a typed FDIR_ESTIMATE item."""

from __future__ import annotations

from fdir_service.mavlink import dialect, unpack_fault_types
from tests.helpers.loopback import CATALOGUE_SPEED, fly_into_service

SECONDS = 45.0      # real-engine: the engine quits between 20 and 40 s


def test_an_engine_loss_is_announced_in_words_and_typed_on_the_estimate():
    f = fly_into_service(["--autopilot", "auto", "--estimator", "aerosonde-catalogue"],
                         ["real-engine", "--profile", "ardupilot", "--speed", CATALOGUE_SPEED,
                          "--nav", "truth", "--duration", str(SECONDS), "--wait", "60"])
    assert f.service_rc == 0 and "aerosonde-catalogue" in f.service_err, f.service_err
    texts = [txt for _, _, txt in f.gs.statustexts if txt.startswith("FDIR dt ")]
    assert any(txt.startswith("FDIR dt engine out, thrust ") for txt in texts), f.gs.statustexts
    typed = [unpack_fault_types(m.fault_type) for _, m in f.gs.estimates if getattr(m, "fault_type", None)]
    assert any(dialect.FDIR_FAULT_TYPE_ENGINE in codes for codes in typed)
