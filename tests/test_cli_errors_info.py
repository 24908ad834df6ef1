"""`snapshot info`: bad numbers and options give one ``error:`` line, exit code 2 (the
runner and the rules: ``cli_helpers``); only "positive and finite" is enforced."""

from __future__ import annotations

import json

import pytest
from cli_helpers import W, alone, one_error_line, run_batch, walk_clip
from click.testing import CliRunner

from snapcore.cli.main import cli

#: Refused command lines: (args, what the one line names).
REFUSED = {
    f"{opt}={v}": (["info", W, opt, v], [f"'{opt}'", "positive finite number", f"'{v}'"])
    for opt in ("--fps", "--scale")
    for v in ("nan", "inf", "0", "-1")
} | {
    "unknown-option": (["info", W, "--frame", "3"], ["No such option", "--frame"]),
    "misspelt-option": (["info", W, "--fpz", "3"], ["No such option", "--fpz", "--fps"]),
    "missing-argument": (["info"], ["Missing argument", "PATHS"]),
}


@pytest.fixture(scope="module")
def walk(motions_dir):
    return walk_clip(motions_dir)


@pytest.fixture(scope="module")
def runs(walk, tmp_path_factory) -> dict:
    cases = {cid: (row[0], {}) for cid, row in REFUSED.items()}
    return run_batch(cases, walk, tmp_path_factory.mktemp("cli_errors_info"))


@pytest.mark.parametrize("cid", sorted(REFUSED))
def test_bad_numbers_and_options_are_one_line(runs, cid):
    r = runs[cid]
    one_error_line(r, *REFUSED[cid][1])
    assert r.files() == {}


def test_number_error_alone_in_a_process(walk, tmp_path):
    """`info --fps nan` crashed with a traceback in scene.py."""
    one_error_line(alone("info", walk, "--fps", "nan", cwd=tmp_path), "'--fps'", "'nan'")


def test_tiny_positive_numbers_are_the_users_call(walk):
    """Only 'positive and finite' is enforced: no invented plausibility limits."""
    r = CliRunner().invoke(cli, ["info", str(walk), "--fps", "1e-3", "--json"])
    assert r.exit_code == 0, r.output
    assert json.loads(r.stdout)["fps"] == 0.001
