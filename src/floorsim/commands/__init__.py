"""Subcommands of the floorsim CLI (see floorsim.cli)."""
