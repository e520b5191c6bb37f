"""Subcommands of `fdir`, one module each."""
