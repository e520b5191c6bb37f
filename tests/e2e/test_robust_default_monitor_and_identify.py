"""End to end through loopback UDP: `fdir run` with its defaults (the robust monitor,
config/estimators/aerosonde-robust.toml) next to `sim-bridge fly` in a real-sky world: it declares
the faults it should and nothing else, and `fdir identify` fits an airframe to the recording of a
fault-free flight."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from fdir_service.airframe.params import load_airframe
from sim_bridge.demo import GroundStation
from tests.helpers.loopback import ROBUST_SPEED, ROOT, fly_into_service


def fly(tmp_path: Path, scenario: str, duration: float) -> tuple[GroundStation, Path]:
    """`sim-bridge fly` at ROBUST_SPEED x real time, the default `fdir run` recording; the ground
    station's view."""
    log = tmp_path / f"{scenario}.mcap"
    f = fly_into_service(["--record", str(log)],
                         [scenario, "--speed", ROBUST_SPEED, "--nav", "truth", "--duration", str(duration),
                          "--wait", "60"])
    assert f.service_rc == 0 and "aerosonde-robust" in f.service_err, f.service_err
    assert f.sim_rc == 0, f.sim_err
    return f.gs, log


def declared(gs: GroundStation) -> list[str]:
    return [txt for _, _, txt in gs.statustexts if txt.startswith("FDIR") and "fault" in txt]


def test_default_monitor_declares_the_attitude_fault_in_turbulence_and_nothing_else(tmp_path):
    gs, _ = fly(tmp_path, "real-turbulence", 45.0)      # theta fault drawn in 15-30 s for 8-15 s
    texts = declared(gs)
    assert texts and all(t.startswith("FDIR theta fault") for t in texts), texts


def test_identify_fits_an_airframe_to_a_fault_free_recording(tmp_path):
    gs, log = fly(tmp_path, "real-calm-faultfree", 60.0)
    assert declared(gs) == []
    out = tmp_path / "identified.toml"
    r = subprocess.run([sys.executable, "-m", "fdir_service.cli", "identify", str(log), "--out", str(out)],
                       cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert "frames used: 1" in r.stdout and "pitch q'" in r.stdout
    fitted = load_airframe(out)
    assert fitted.m == 25.0 and fitted.C_mde < 0           # geometry kept, the elevator still pitches down
    assert "throttle:  not fitted" in r.stdout             # calm air: the throttle hardly moves ...
    assert fitted.k_motor == 80.0                          # ... and the file's propeller is kept
