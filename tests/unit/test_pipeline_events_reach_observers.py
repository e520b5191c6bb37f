"""The pipeline composed of the runtime parts: every event reaches observers both as the logged
(level, text) and, for observers that want it, as the typed object; link supervision events."""

from __future__ import annotations

from fdir_service.mavlink import dialect, new_mavlink
from fdir_service.runtime.events import LinkLost, LinkRegained, PipelineClosed, Rejected, RejectionSummary
from tests.helpers.streams import PACKETS, fake_pipeline, feed_all, v1_frame


def test_typed_and_logged_events_agree():
    pipe, filt, ev = fake_pipeline()
    feed_all(pipe, PACKETS[:100] + [v1_frame(PACKETS[3])] + PACKETS[100:300])
    pipe.close(0)
    assert len(ev.typed) == len(ev.events) > 0
    assert [(e.level, e.text) for e in ev.typed] == ev.events
    assert ev.of(Rejected) == [Rejected("mavlink1")]
    summary = ev.of(RejectionSummary)[-1]
    assert summary.total == 1 and summary.counts == (("mavlink1", 1),)
    (closed,) = ev.of(PipelineClosed)
    assert closed.frames == pipe.frames == len(filt[0].calls) and dict(closed.counts) == pipe.rejected_counts


def test_link_lost_and_regained():
    pipe, _, ev = fake_pipeline()
    feed_all(pipe, PACKETS[:70])
    lost = new_mavlink(255, 0).parse_buffer(b"".join(pipe.set_link_lost(True, 2.04, 0)))
    assert [m.get_type() for m in lost] == ["STATUSTEXT", "HEARTBEAT"]
    assert lost[0].severity == dialect.MAV_SEVERITY_CRITICAL
    assert lost[1].system_status == dialect.MAV_STATE_CRITICAL
    assert pipe.set_link_lost(True, 3.0, 0) == []                  # no change: nothing said
    back = new_mavlink(255, 0).parse_buffer(b"".join(pipe.set_link_lost(False, 2.5, 0)))
    assert [m.text for m in back] == ["FDIR link restored after 2.5 s"]
    assert ev.of(LinkLost) == [LinkLost(2.04)] and ev.of(LinkRegained) == [LinkRegained(2.5)]
    assert pipe.link_lost is False
