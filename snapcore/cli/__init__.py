"""Subcommands of ``snapshot`` that live in snapcore, one module per command family.

Each module is thin: parse options, call the library, print. Shared option helpers are
in :mod:`snapcore.cli.common`.
"""
