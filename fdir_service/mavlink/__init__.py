"""The fdir MAVLink dialect: common.xml plus FDIR_ESTIMATE (id 52500), and helpers around it.

`dialect` is the pymavlink-generated module (MAVLink 2); `new_mavlink()` makes a codec object
(robust parsing on, optional signing) that encodes and decodes without any socket.
"""

from __future__ import annotations

import struct
from pathlib import Path

from fdir_service.mavlink.generated import fdir as dialect

DIALECT_XML = Path(__file__).resolve().parent / "fdir.xml"
FDIR_ESTIMATE_ID = dialect.MAVLINK_MSG_ID_FDIR_ESTIMATE
MAX_FAULTS = 8
"""FDIR_ESTIMATE carries at most this many fault channels."""
MAV_COMP_ID_ONBOARD_COMPUTER = dialect.MAV_COMP_ID_ONBOARD_COMPUTER
FAULT_TYPE_BYTES = MAX_FAULTS // 2
"""FDIR_ESTIMATE.fault_type: FDIR_FAULT_TYPE codes packed two per byte (payload limit 255 bytes)."""


def pack_fault_types(codes: list[int]) -> list[int]:
    """FDIR_FAULT_TYPE codes (<= 8, each 0..15) -> FDIR_ESTIMATE.fault_type (4 bytes): channel i in
    the low nibble of byte i // 2 when i is even, the high nibble when odd; missing channels 0."""
    c = list(codes) + [0] * (MAX_FAULTS - len(codes))
    return [(c[2 * b] & 0xF) | (c[2 * b + 1] & 0xF) << 4 for b in range(FAULT_TYPE_BYTES)]


def unpack_fault_types(packed) -> list[int]:
    """FDIR_ESTIMATE.fault_type (4 bytes, or fewer/none from a sender without the extension) -> the
    8 channels' FDIR_FAULT_TYPE codes (0 = BIAS where absent)."""
    b = list(packed or []) + [0] * FAULT_TYPE_BYTES
    return [(b[i // 2] >> (4 * (i % 2))) & 0xF for i in range(MAX_FAULTS)]


def dialect_text() -> str:
    """The fdir.xml source (recorded as log metadata so a log is self-describing)."""
    return DIALECT_XML.read_text()


def new_mavlink(src_system: int, src_component: int, *, key: bytes | None = None,
                link_id: int = 0, initial_timestamp: int = 0,
                allow_unsigned: bool = False) -> dialect.MAVLink:
    """A MAVLink 2 codec (no file): robust parsing, and signing when `key` (32 bytes) is given.

    With a key, outgoing messages are signed and incoming unsigned or badly signed messages are
    rejected (pymavlink returns them as MAVLink_bad_data "Invalid signature") unless
    `allow_unsigned`. `initial_timestamp` (units of 10 us since 2015-01-01) is the signing clock's
    start: 0 keeps the codec deterministic (it then follows the timestamps it receives).
    """
    mav = dialect.MAVLink(None, srcSystem=src_system, srcComponent=src_component)
    mav.robust_parsing = True
    if key is not None:
        if len(key) != 32:
            raise ValueError("a MAVLink 2 signing key is 32 bytes")
        mav.signing.secret_key = key
        mav.signing.link_id = link_id
        mav.signing.timestamp = initial_timestamp
        mav.signing.sign_outgoing = True
        mav.signing.allow_unsigned_callback = (lambda _mav, _msgid: True) if allow_unsigned else None
    return mav


_HEADER = struct.Struct("<BBBBBBBHB")   # MAVLink 2: STX, len, incompat, compat, seq, sys, comp, msgid
_CRC = struct.Struct("<H")
try:  # pymavlink's generated code uses the same function when fastcrc is installed
    from fastcrc.crc16 import mcrf4xx as _mcrf4xx
except ImportError:  # pragma: no cover
    _mcrf4xx = None


def frame_payload(mav: dialect.MAVLink, msg_id: int, crc_extra: int, payload: bytes) -> bytes | None:
    """The MAVLink 2 frame pymavlink's `pack` builds around an already packed payload (same
    bytes: trailing-zero truncation, header with `mav.seq` and ids, CRC with crc_extra), without
    its per-message header objects and byte arrays. None when `mav` signs its output (then use
    pymavlink, which signs) or fastcrc is missing."""
    if _mcrf4xx is None or mav.signing.sign_outgoing:
        return None
    p = payload.rstrip(b"\0") or payload[:1]
    body = _HEADER.pack(253, len(p), 0, 0, mav.seq, mav.srcSystem, mav.srcComponent,
                        msg_id & 0xFFFF, msg_id >> 16) + p
    mav.seq = (mav.seq + 1) % 256
    return body + _CRC.pack(_mcrf4xx(body[1:] + bytes((crc_extra,)), 0xFFFF))


def pack(msg: dialect.MAVLink_message, mav: dialect.MAVLink) -> bytes:
    """`bytes(msg.pack(mav))`, cheaper for unsigned output: the message's own payload packing, then
    `frame_payload` (the message object's `_header` / `_msgbuf` are not filled in)."""
    if _mcrf4xx is None or mav.signing.sign_outgoing:
        frame = bytes(msg.pack(mav))
        mav.seq = (mav.seq + 1) % 256   # as MAVLink.send does: every frame out gets the next seq
        return frame
    got: list[bytes] = []

    def capture(_mav, _crc_extra, payload, force_mavlink1=False):
        got.append(payload)
        return b""

    msg._pack = capture          # the generated pack() hands its payload to self._pack
    try:
        msg.pack(mav)
    finally:
        del msg._pack
    cls = type(msg)   # class attributes: STATUSTEXT has a field named `id`
    out = frame_payload(mav, cls.id, cls.crc_extra, got[0])
    assert out is not None
    return out
