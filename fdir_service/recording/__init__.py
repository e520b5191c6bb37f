"""Flight recording to MCAP: the `Recorder` observer, log reading, repair."""

from fdir_service.recording.logtools import McapLog, linear_scan, log_info, recover
from fdir_service.recording.recorder import (
    ESTIMATE_TOPIC,
    ITEMS_TOPIC,
    LOG_TOPIC,
    PARTICLES_TOPIC,
    RAW_IN_TOPIC,
    RAW_OUT_TOPIC,
    Recorder,
    default_record_path,
)

__all__ = [
    "ESTIMATE_TOPIC", "ITEMS_TOPIC", "LOG_TOPIC", "PARTICLES_TOPIC", "RAW_IN_TOPIC", "RAW_OUT_TOPIC",
    "McapLog", "Recorder", "default_record_path", "linear_scan", "log_info", "recover",
]
