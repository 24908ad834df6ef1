"""Subcommands of ``snapshot`` that belong to the study app (registered as entry points)."""
