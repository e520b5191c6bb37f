"""The service runtime in parts: screening, frames, health, events, publishing."""
