"""The service's processing core, `Pipeline`: now `fdir_service.runtime.pipeline`, composed of the
runtime parts (`fdir_service.runtime`: screening, frames, health, events, publishing). Re-exported
here for existing importers."""

from fdir_service.runtime.events import OPERATOR_REASONS
from fdir_service.runtime.frames import AssembledFrame, FrameAssembler
from fdir_service.runtime.health import MEASURED_STATE, STATE_LABELS
from fdir_service.runtime.pipeline import (
    LATENCY_WINDOW,
    PARTICLES_TOP_K,
    SIGNING_EPOCH_UNIX_S,
    FilterFactory,
    MAVLink_message,
    Pipeline,
    PipelineObserver,
    trim_input,
)
from fdir_service.runtime.publishing import Publisher
from fdir_service.runtime.screening import COMMAND_MESSAGES, DUPLICATE_MEMORY

__all__ = ["COMMAND_MESSAGES", "DUPLICATE_MEMORY", "LATENCY_WINDOW", "MEASURED_STATE", "OPERATOR_REASONS",
           "PARTICLES_TOP_K", "SIGNING_EPOCH_UNIX_S", "STATE_LABELS", "AssembledFrame", "FilterFactory",
           "FrameAssembler", "MAVLink_message", "Pipeline", "PipelineObserver", "Publisher", "trim_input"]
