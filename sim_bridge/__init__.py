"""sim-bridge: the Aerosonde world (airframe truth, sensors, faults, autopilot) and campaigns."""
