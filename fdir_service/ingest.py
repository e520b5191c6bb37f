"""Decoded MAVLink messages -> filter frames: now `fdir_service.runtime.frames` (assembly) and
`fdir_service.runtime.screening` (value checks). Re-exported here for existing importers."""

from fdir_service.runtime.frames import (
    JUMP_CONFIRM_MESSAGES,
    LATE_WINDOW_FRAMES,
    AssembledFrame,
    FrameAssembler,
)
from fdir_service.runtime.screening import message_time_us, read_value

__all__ = ["JUMP_CONFIRM_MESSAGES", "LATE_WINDOW_FRAMES", "AssembledFrame", "FrameAssembler",
           "message_time_us", "read_value"]
