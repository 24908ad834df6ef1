"""Help texts name what the commands compute by default (story information, not pose entropy)."""

from __future__ import annotations

import re

import pytest
from click.testing import CliRunner

from snapcore.cli.main import _commands, cli

# The paper's pose entropy is still a method (--pose-method paper); a help text may name it
# only beside "paper" or a paper figure ("Fig. 6") (the default is the story information since issue 33).
_ENTROPY = re.compile(r"pose[ -]entropy", re.IGNORECASE)


def _help(*args: str) -> str:
    res = CliRunner().invoke(cli, [*args, "--help"], terminal_width=200)
    assert res.exit_code == 0, res.output
    return res.output


@pytest.mark.parametrize("command", [None, *sorted(_commands())])
def test_help_never_calls_the_default_pose_pose_entropy(command):
    """Every mention of pose entropy in a help text says it is the paper's method."""
    text = _help() if command is None else _help(command)
    for line in text.splitlines():
        if _ENTROPY.search(line):
            assert "paper" in line or "Fig." in line, f"{command or 'snapshot'}: {line.strip()}"
