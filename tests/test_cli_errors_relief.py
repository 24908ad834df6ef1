"""`snapshot relief`: bad command lines give one ``error:`` line, exit code 2, nothing
written and nothing already there overwritten (the runner and the rules:
``cli_helpers``)."""

from __future__ import annotations

import pytest
from cli_helpers import W, one_error_line, run_batch, walk_clip
from click.testing import CliRunner

from snapcore.cli.main import cli

#: Outputs the command cannot write: (args, output as given, what the line says).
SUFFIX_CASES = {
    "relief-png": (["relief", W, "-o", "r.png"], "-o/--output r.png", "relief writes .stl"),
    "relief-preview-jpg": (
        ["relief", W, "-o", "r.stl", "--preview", "p.jpg"],
        "--preview p.jpg",
        "relief writes its preview as .png",
    ),
}
#: Refused command lines: (args, what the one line names).
REFUSED = {
    "missing-folder": (
        ["relief", W, "-o", "missing/r.stl"],
        ["-o/--output missing/r.stl: folder missing does not exist"],
    ),
    "preview-missing-folder": (
        ["relief", W, "--preview", "missing/p.png"],
        ["--preview missing/p.png: folder missing does not exist"],
    ),
    "depth=0": (["relief", W, "--depth", "0"], ["'--depth'"]),
    "base=inf": (["relief", W, "--base", "inf"], ["'--base'"]),
}
#: A malformed vector (without --view the command would select the pose first).
VECTOR = (["relief", W, "--view", "1,2"], ["'--view'", "'1,2'"])

#: Files that exist before a case runs, and must be unchanged after it.
OLD_PNG, OLD_STL = b"an older picture", b"an older STL"
OVERWRITE_CASES = {
    "png-output": (["relief", W, "-o", "r4.png"], ["-o/--output r4.png", "relief writes .stl"]),
    "preview-is-output": (
        ["relief", W, "-o", "r5.stl", "--preview", "r5.stl"],
        ["--preview r5.stl", "relief writes its preview as .png"],
    ),
}
OLD_FILES = {"r4.png": OLD_PNG, "r5.stl": OLD_STL}


@pytest.fixture(scope="module")
def walk(motions_dir):
    return walk_clip(motions_dir)


@pytest.fixture(scope="module")
def runs(walk, tmp_path_factory) -> dict:
    cases = {cid: (row[0], {}) for table in (SUFFIX_CASES, REFUSED) for cid, row in table.items()}
    cases["vector"] = (VECTOR[0], {})
    cases |= {f"overwrite:{cid}": (row[0], OLD_FILES) for cid, row in OVERWRITE_CASES.items()}
    return run_batch(cases, walk, tmp_path_factory.mktemp("cli_errors_relief"))


@pytest.mark.parametrize("cid", sorted(SUFFIX_CASES))
def test_unsupported_output_suffix_is_refused_up_front(runs, cid):
    _, output, allowed = SUFFIX_CASES[cid]
    r = runs[cid]
    assert one_error_line(r, allowed) == f"error: {output}: {allowed}"
    assert r.files() == {}  # nothing written, not even the other output


@pytest.mark.parametrize("cid", sorted(REFUSED))
def test_bad_option_values_are_one_line(runs, cid):
    r = runs[cid]
    one_error_line(r, *REFUSED[cid][1])
    assert r.files() == {}  # nothing written, and a missing folder is not created


def test_bad_vector_is_refused_before_pose_selection(runs):
    r = runs["vector"]
    one_error_line(r, *VECTOR[1])
    assert "selected pose" not in r.output and "view [" not in r.output
    assert r.files() == {}


@pytest.mark.parametrize("cid", sorted(OVERWRITE_CASES))
def test_relief_never_overwrites_the_stl_with_its_preview(runs, cid):
    """-o must be .stl and --preview .png: existing files of either name are untouched."""
    r = runs[f"overwrite:{cid}"]
    one_error_line(r, *OVERWRITE_CASES[cid][1])
    assert r.files() == OLD_FILES


def test_relief_writes_stl_and_preview_where_asked(walk, tmp_path):
    r = CliRunner().invoke(
        cli,
        [
            "relief",
            str(walk),
            "--frame",
            "10",
            "--view",
            "0,0,1",
            "--resolution",
            "16",
            "-o",
            str(tmp_path / "a.stl"),
            "--preview",
            str(tmp_path / "look.png"),
            "-q",
        ],
    )
    assert r.exit_code == 0, r.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.stl", "look.png"]
    assert (tmp_path / "look.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
