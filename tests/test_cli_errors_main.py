"""`snapshot` itself (unknown commands and options, help, version) and the study
commands' help: one ``error:`` line and exit code 2 for a bad command line, the help
unchanged (the runner and the rules: ``cli_helpers``)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from cli_helpers import one_error_line, run_batch, walk_clip

#: Refused command lines: (args, what the one line names).
REFUSED = {
    "unknown-command": (["nope"], ["No such command", "nope"]),
    "unknown-group-option": (["--bogus"], ["No such option", "--bogus"]),
    "unknown-subcommand": (["stimuli", "bogus"], ["No such command", "bogus"]),
}
HELP = {
    "none": [],
    "--help": ["--help"],
    "--version": ["--version"],
    "study": ["study", "--help"],
}


@pytest.fixture(scope="module")
def runs(motions_dir, tmp_path_factory) -> dict:
    cases = {cid: (row[0], {}) for cid, row in REFUSED.items()}
    cases |= {f"help:{cid}": (args, {}) for cid, args in HELP.items()}
    return run_batch(cases, walk_clip(motions_dir), tmp_path_factory.mktemp("cli_errors_main"))


@pytest.mark.parametrize("cid", sorted(REFUSED))
def test_usage_errors_are_one_line(runs, cid):
    r = runs[cid]
    one_error_line(r, *REFUSED[cid][1])
    assert r.files() == {}


def test_help_version_and_no_arguments_are_unchanged(runs):
    r = runs["help:none"]  # `snapshot` alone: the help, as before
    assert r.output.startswith("Usage: snapshot [OPTIONS] COMMAND")
    assert "Commands:" in r.output and "render" in r.output and "error:" not in r.output
    r = runs["help:--help"]
    assert r.rc == 0 and r.stdout.startswith("Usage: snapshot [OPTIONS] COMMAND")
    assert "Commands:" in r.stdout
    r = runs["help:--version"]
    assert r.rc == 0 and r.stdout.startswith("snapshot, version ")


def test_study_help_shows_prolific_placeholders_with_double_braces(runs):
    r = runs["help:study"]
    assert r.rc == 0, r.output
    url = "?PROLIFIC_PID={{%PROLIFIC_PID%}}&STUDY_ID={{%STUDY_ID%}}&SESSION_ID={{%SESSION_ID%}}"
    assert any(line.strip() == url for line in r.stdout.splitlines()), r.stdout


def test_readme_shows_export_table_options_with_their_paths():
    """README: --participants and --events take a path, as `snapshot export` wants."""
    readme = (Path(__file__).resolve().parents[1] / "README.md").read_text()
    # the export command's lines (select's --events, the paper's event mode, is another option)
    text = "\n".join(ln for ln in readme.splitlines() if "export" in ln)
    for opt in ("--participants", "--events"):
        uses = [text[m.start() : m.start() + 40] for m in re.finditer(re.escape(opt), text)]
        assert uses and all(re.match(rf"{opt} (PATH|\S+\.(csv|jsonl))", u) for u in uses), uses
