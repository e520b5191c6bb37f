"""`fdir run` records by default (issue 6 loose end): [record] directory and rotation, --record FILE,
--no-record."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from fdir_service.commands.run import recording_path
from fdir_service.recording import McapLog
from fdir_service.service_config import default_config_path
from tests.helpers.experiments import ch4_service

ROOT = Path(__file__).resolve().parents[2]
BASE = default_config_path().read_text()


def test_record_section_defaults_and_choices(tmp_path):
    cfg = ch4_service()
    assert (cfg.record.enabled, cfg.record.directory, cfg.record.rotate_mb, cfg.record.rotate_s) == (
        True, "recordings", 100.0, 3600.0)
    p = recording_path(cfg, None, False)
    assert p.parent == Path("recordings") and p.name.startswith("fdir-") and p.suffix == ".mcap"
    assert recording_path(cfg, tmp_path / "x.mcap", False) == tmp_path / "x.mcap"
    assert recording_path(cfg, None, True) is None
    off = ch4_service(BASE.replace("enabled = true", "enabled = false"))
    assert recording_path(off, None, False) is None


def run(args, cwd):
    return subprocess.run([sys.executable, "-m", "fdir_service.cli", "run", "--master",
                           "udpin:127.0.0.1:0", *args], cwd=cwd, capture_output=True, text=True, timeout=60)


def test_fdir_run_records_by_default_into_the_configured_directory(tmp_path):
    cfg = tmp_path / "service.toml"
    cfg.write_text(BASE.replace('directory = "recordings"', f'directory = "{tmp_path / "logs"}"')
                   .replace('estimator = "aerosonde"',
                            f'estimator = "{ROOT / "config/estimators/aerosonde.toml"}"'))
    r = run(["--config", str(cfg), "--duration", "0.2"], tmp_path)
    assert r.returncode == 0, r.stderr
    files = list((tmp_path / "logs").glob("fdir-*.mcap"))
    assert len(files) == 1 and f"recorded {files[0]}" in r.stderr
    log = McapLog(files[0])
    assert log.mode == "indexed" and log.metadata["config"]["filter"] == "RJMRPF"
    # --no-record: nothing new; --record FILE: that file
    assert run(["--config", str(cfg), "--duration", "0.2", "--no-record"], tmp_path).returncode == 0
    assert len(list((tmp_path / "logs").glob("*.mcap"))) == 1
    r = run(["--config", str(cfg), "--duration", "0.2", "--record", str(tmp_path / "mine.mcap")], tmp_path)
    assert r.returncode == 0 and McapLog(tmp_path / "mine.mcap").mode == "indexed"


def test_rotation_settings_reach_the_recorder(tmp_path):
    from fdir_service.pipeline import Pipeline
    from fdir_service.recording import Recorder
    from tests.helpers.service import autopilot_stream, fake_factory

    cfg = ch4_service(BASE.replace("rotate_s = 3600.0", "rotate_s = 2.0"))
    rec = Recorder(tmp_path / "r.mcap", rotate_bytes=int(cfg.record.rotate_mb * 1e6) or None,
                   rotate_seconds=cfg.record.rotate_s or None)
    pipe = Pipeline(cfg, filter_factory=fake_factory([]), observers=[rec])
    for k, (_, s, a) in enumerate(autopilot_stream(5.0)):
        pipe.feed(b"".join(s + a), k * 50_000_000)
    rec.close()
    assert [p.name for p in rec.paths] == ["r.mcap", "r.001.mcap", "r.002.mcap"]
    assert all(McapLog(p).mode == "indexed" for p in rec.paths)
