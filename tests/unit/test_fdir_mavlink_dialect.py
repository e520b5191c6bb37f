"""The fdir MAVLink dialect: FDIR_ESTIMATE round trip, id range, signing, committed module fresh."""

from __future__ import annotations

import math

import pytest

from fdir_service.mavlink import FDIR_ESTIMATE_ID, MAX_FAULTS, dialect, new_mavlink
from fdir_service.mavlink.regenerate import GENERATED, generate

KEY = bytes(range(32))


def _estimate():
    return dialect.MAVLink_fdir_estimate_message(
        12_345, 7, 2, 0b01, 0, 0b111111, [-500.0, 40.0, 1.9, 0.05, 0.0], [1.0] * 5,
        [50.0, -1.0] + [math.nan] * 6, [0.5] * 8, [0.99, 0.01] + [math.nan] * 6,
        [math.nan] * 8, [math.nan] * 8, 812.5)


def test_estimate_id_in_the_private_range_and_fits_a_mavlink2_frame():
    assert 52100 <= FDIR_ESTIMATE_ID <= 59999
    b = _estimate().pack(new_mavlink(1, 191))
    assert len(b) <= 280 and MAX_FAULTS == 8


def test_estimate_round_trip():
    b = bytes(_estimate().pack(new_mavlink(1, 191)))
    (msg,) = new_mavlink(255, 0).parse_buffer(b)
    assert msg.get_type() == "FDIR_ESTIMATE" and msg.get_srcComponent() == 191
    assert msg.time_boot_ms == 12_345 and msg.fault[0] == pytest.approx(50.0)
    assert msg.p_fault[0] == pytest.approx(0.99) and math.isnan(msg.pfa[0])


def test_signed_stream_rejects_unsigned_and_wrong_key():
    rx = new_mavlink(255, 0, key=KEY)
    good = bytes(_estimate().pack(new_mavlink(1, 191, key=KEY)))
    unsigned = bytes(_estimate().pack(new_mavlink(1, 191)))
    wrong = bytes(_estimate().pack(new_mavlink(1, 191, key=bytes(32))))
    types = [m.get_type() for m in rx.parse_buffer(good + unsigned + wrong)]
    assert types == ["FDIR_ESTIMATE", "BAD_DATA", "BAD_DATA"]


def test_committed_module_matches_a_fresh_mavgen_run(tmp_path):
    fresh = generate(tmp_path / "fdir.py")
    assert fresh.read_bytes() == GENERATED.read_bytes()
