"""What the service sends (HEARTBEAT, NAMED_VALUE_FLOAT, STATUSTEXT, FDIR_ESTIMATE): now
`fdir_service.runtime.publishing`; re-exported here for existing importers."""

from fdir_service.runtime.publishing import FaultChannel, Publisher, RateLimit, sensor_notice, statustext_for

__all__ = ["FaultChannel", "Publisher", "RateLimit", "sensor_notice", "statustext_for"]
