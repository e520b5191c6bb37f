"""The fdir MAVLink dialect: common.xml plus FDIR_ESTIMATE (id 52500), and helpers around it.

`dialect` is the pymavlink-generated module (MAVLink 2); `new_mavlink()` makes a codec object
(robust parsing on, optional signing) that encodes and decodes without any socket.
"""

from __future__ import annotations

from pathlib import Path

from fdir_service.mavlink.generated import fdir as dialect

DIALECT_XML = Path(__file__).resolve().parent / "fdir.xml"
FDIR_ESTIMATE_ID = dialect.MAVLINK_MSG_ID_FDIR_ESTIMATE
MAX_FAULTS = 8
"""FDIR_ESTIMATE carries at most this many fault channels."""
MAV_COMP_ID_ONBOARD_COMPUTER = dialect.MAV_COMP_ID_ONBOARD_COMPUTER


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
