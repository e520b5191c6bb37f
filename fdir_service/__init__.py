"""fdir-service: onboard fault detection, isolation and estimation for fixed-wing UAVs."""

__version__ = "0.1.0"
