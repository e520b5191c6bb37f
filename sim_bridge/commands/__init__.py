"""Subcommands of `sim-bridge`, one module each."""
