"""Project-wide exception types."""


class ConfigError(ValueError):
    """A configuration or scenario file is invalid; the message names the key and what was expected."""
