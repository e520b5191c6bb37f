"""Issue 17, service side: an estimator with a stuck entry on q (besides q's bias) publishes
FDIR_ESTIMATE with the item's type and value in the extension fields, a decoder built from the
dialect before the extensions still parses it, the STATUSTEXT says "stuck", and the recording
(per-entry ft_/fv_, /fdir/items) replays bit for bit."""

from __future__ import annotations

import importlib.util
import math
import re

import numpy as np
import pytest

from fdir_service.estimation.base import StepOutput
from fdir_service.estimator_config import estimator_document
from fdir_service.mavlink import DIALECT_XML, dialect, new_mavlink, unpack_fault_types
from fdir_service.mavlink.regenerate import generate
from fdir_service.pipeline import Pipeline
from fdir_service.recording import ITEMS_TOPIC, McapLog, Recorder
from fdir_service.replay import item_summary, replay
from fdir_service.runtime.events import FaultDeclared
from fdir_service.service_config import ServiceConfig, default_config_path
from tests.helpers.service import autopilot_stream
from tests.helpers.streams import Events

HELD = math.radians(3.2)   # the stuck gyro's held reading, rad/s
ONSET_S = 2.0


def typed_config() -> ServiceConfig:
    """The default service with aerosonde's estimator plus `q_stk` (type stuck, target q)."""
    doc, _ = estimator_document("aerosonde")
    doc["faults"].append({"id": "q_stk", "target": "q", "unit": "deg/s", "sigma_f": 0.005,
                          "amplitude_max": 30.0, "type": "stuck"})
    return ServiceConfig.from_toml_text(default_config_path().read_text(), estimator_doc=doc)


class StuckFake:
    """From ONSET_S on, q_stk is in mode 1 (P 0.97, value HELD) and q's bias entry holds the rest
    (P 0.02); types and values are reported only when `report_types` (else the pipeline fills
    the types in from the config and the value falls back to the estimate)."""

    name = "STUCKFAKE"

    def __init__(self, estimator, report_types: bool = True) -> None:
        self.fault_ids = tuple(f.id for f in estimator.faults)
        self.types = tuple(f.fault_type for f in estimator.faults) if report_types else ()
        self.report_types = report_types

    def step(self, t, y, mask, u) -> StepOutput:
        nf = len(self.fault_ids)
        x = np.zeros(5 + nf)
        x[0] = -y[1] if mask[1] else -500.0
        x[1] = 40.0
        on = t >= ONSET_S
        p = np.full(nf, 0.001)
        f = np.zeros(nf)
        j, q = self.fault_ids.index("q_stk"), self.fault_ids.index("q")
        if on:
            p[j], p[q], f[j], f[q] = 0.97, 0.02, HELD - 0.001, 0.01
        value = f.copy()
        value[j] = HELD if on else 0.0
        return StepOutput(t, x, np.eye(5 + nf), self.fault_ids, f, p, 100.0, False, fault_types=self.types,
                          fault_value=value if self.report_types else None)

    def top_particles(self, k: int = 20):
        return np.zeros((k, 5 + len(self.fault_ids))), np.full(k, 1.0 / k)


def factory(report_types: bool = True):
    def make(name, estimator, rng, particles):
        return StuckFake(estimator, report_types)
    return make


def fly(observers, report_types: bool = True, seconds: float = 4.0) -> bytes:
    pipe = Pipeline(typed_config(), filter_factory=factory(report_types), observers=observers)
    sent = bytearray()
    for k, (_, s, a) in enumerate(autopilot_stream(seconds)):
        sent += b"".join(pipe.feed(b"".join(s + a), 1_000_000_000 + k * 50_000_000))
    return bytes(sent)


def old_dialect(tmp_path):
    """The dialect module as it was before the extensions (fdir.xml without them), via mavgen."""
    xml = re.sub(r"\s*<extensions/>.*?(?=\s*</message>)", "", DIALECT_XML.read_text(), flags=re.S)
    xml = re.sub(r'\s*<enum name="FDIR_FAULT_TYPE">.*?</enum>', "", xml, flags=re.S)
    assert 'name="fault_value"' not in xml and 'name="n_eff"' in xml
    path = generate(tmp_path / "fdir_old.py", xml)
    spec = importlib.util.spec_from_file_location("fdir_old", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.mark.parametrize("report_types", [True, False])
def test_a_stuck_gyro_is_published_typed(report_types):
    ev = Events()
    sent = fly([ev], report_types)
    msgs = new_mavlink(255, 0).parse_buffer(sent)
    est = [m for m in msgs if m.get_type() == "FDIR_ESTIMATE"]
    names = ("gnss", "baro", "theta", "q")                  # q_stk joins item q
    assert {m.fault_count for m in est} == {len(names)}
    late = [m for m in est if m.time_boot_ms >= 3000]
    first = est[0]
    assert unpack_fault_types(first.fault_type)[:4] == [dialect.FDIR_FAULT_TYPE_BIAS] * 4
    for m in late:
        assert unpack_fault_types(m.fault_type)[:4] == [0, 0, 0, dialect.FDIR_FAULT_TYPE_STUCK]
        assert m.p_fault[3] == pytest.approx(0.99, abs=1e-6)
        want = HELD if report_types else HELD - 0.001          # without values: the estimate
        assert m.fault_value[3] == pytest.approx(want, rel=1e-6) and m.fault[3] == pytest.approx(HELD - 0.001)
        assert m.declared == 0b1000 and math.isnan(m.fault_value[4])
    text = [m.text for m in msgs if m.get_type() == "STATUSTEXT" and m.text.startswith("FDIR q")]
    value = "3.2" if report_types else "3.1"
    assert text == [f"FDIR q stuck at {value} deg/s p=0.99"]
    decl = ev.of(FaultDeclared)
    assert [(e.fault_id, e.fault_type) for e in decl] == [("q", "stuck")]


def test_an_old_decoder_parses_the_extended_message_and_plain_output_has_no_extension(tmp_path):
    old = old_dialect(tmp_path)
    assert not hasattr(old, "FDIR_FAULT_TYPE_STUCK")
    assert old.MAVLink_fdir_estimate_message.fieldnames[-1] == "n_eff"
    sent = fly([])
    mav = old.MAVLink(None, srcSystem=255, srcComponent=0)
    mav.robust_parsing = True
    est = [m for m in mav.parse_buffer(sent) if m.get_type() == "FDIR_ESTIMATE"]
    new = [m for m in new_mavlink(255, 0).parse_buffer(sent) if m.get_type() == "FDIR_ESTIMATE"]
    assert len(est) == len(new) > 70
    for a, b in zip(est, new, strict=True):
        assert (a.time_boot_ms, a.fault_count, a.declared) == (b.time_boot_ms, b.fault_count, b.declared)
        assert a.p_fault[:4] == b.p_fault[:4] and not hasattr(a, "fault_value")
    # an all-bias estimator sends no extension bytes: the frames of before (payload <= 216 bytes)
    from tests.helpers.experiments import ch4_service
    from tests.helpers.service import fake_factory

    pipe = Pipeline(ch4_service(), filter_factory=fake_factory([]))
    out = b"".join(b"".join(pipe.feed(b"".join(s + a), k * 50_000_000))
                   for k, (_, s, a) in enumerate(autopilot_stream(1.0)))
    lengths = [m.get_msgbuf()[1] for m in new_mavlink(255, 0).parse_buffer(out)
               if m.get_type() == "FDIR_ESTIMATE"]
    assert lengths and max(lengths) <= 216


def test_recording_holds_types_values_and_items_and_replays_them(tmp_path):
    log = tmp_path / "typed.mcap"
    rec = Recorder(log)
    fly([rec], report_types=True)
    rec.close()
    m = McapLog(log)
    est = [o for _, o in m.iter_json("/fdir/estimate")]
    items = [o for _, o in m.iter_json(ITEMS_TOPIC)]
    assert len(items) == len(est) > 70
    last = est[-1]
    assert (last["ft_q"], last["ft_q_stk"], last["ft_gnss"]) == (0, 1, 0)
    assert last["fv_q_stk"] == pytest.approx(HELD)
    it = items[-1]
    assert set(k.removeprefix("type_") for k in it if k.startswith("type_")) == {"gnss", "baro", "theta", "q"}
    assert (it["type_q"], it["declared_q"], it["declared_gnss"]) == (1, 1, 0)
    assert it["v_q"] == pytest.approx(HELD) and it["p_q"] == pytest.approx(0.99)
    assert items[0]["type_q"] == 0 and items[0]["declared_q"] == 0
    summary = item_summary(items)
    assert summary["q"]["type"] == "stuck" and summary["gnss"]["type"] == "bias"
    assert 0.3 < summary["q"]["declared_fraction"] < 0.6
    r = replay(log, filter_factory=factory(True))
    assert r.identity.identical, r.identity.describe()
    assert r.items_identity.identical and r.replayed_items == items
    # a replay with another filter reports the items' types too
    r2 = replay(log, filter_factory=factory(False), seed=99)
    assert not r2.same_setup and item_summary(r2.replayed_items)["q"]["type"] == "stuck"
