"""A biased pitot in an 8 m/s headwind, flown by the simulator speaking as a stock ArduPlane (its
VFR_HUD airspeed), into `fdir run` with the fault catalogue (config/estimators/aerosonde-catalogue.toml),
reaches a stock ground station as a STATUSTEXT on the pitot, while the wind alone raised nothing."""

from __future__ import annotations

from tests.helpers.loopback import fly_into_service

SECONDS = 25.0      # real-pitot: the pitot reads 2.5-6 m/s off from 8-20 s for 8-15 s


def test_a_pitot_bias_is_announced_and_the_wind_before_it_raises_nothing():
    f = fly_into_service(["--autopilot", "auto", "--estimator", "aerosonde-catalogue"],
                         ["real-pitot", "--profile", "ardupilot", "--speed", "20", "--nav", "truth",
                          "--duration", str(SECONDS), "--wait", "60"])
    assert f.service_rc == 0 and "aerosonde-catalogue" in f.service_err, f.service_err
    texts = [(t, txt) for t, _, txt in f.gs.statustexts if txt.startswith("FDIR ")
             and not txt.startswith(("FDIR autopilot", "FDIR estimator", "FDIR rejected"))]
    pitot = [(t, txt) for t, txt in texts if txt.startswith("FDIR pitot ")]
    assert pitot, f.gs.statustexts
    first = pitot[0][0]
    assert first >= 8.0                                       # not before the fault's earliest onset
    assert not [txt for t, txt in texts if t < first], texts  # the wind alone raised nothing
