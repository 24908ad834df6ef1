"""`snapshot render`: bad command lines give one ``error:`` line, exit code 2, nothing
written (the runner and the rules: ``cli_helpers``)."""

from __future__ import annotations

import pytest
from cli_helpers import W, one_error_line, run_batch, walk_clip

#: Outputs the command cannot write: (args, output as given, what the line says).
SUFFIX_CASES = {
    "render-txt": (["render", W, "-o", "r.txt"], "-o/--output r.txt", "render writes .png"),
    "render-noext": (["render", W, "-o", "noext"], "-o/--output noext", "render writes .png"),
    "render-jpg": (["render", W, "-o", "x.jpg"], "-o/--output x.jpg", "render writes .png"),
}
#: Refused command lines: (args, what the one line names).
REFUSED = {
    "missing-folder": (
        ["render", W, "-o", "missing/x.png"],
        ["-o/--output missing/x.png: folder missing does not exist"],
    ),
    "fps=inf": (["render", W, "-o", "x.png", "--fps", "inf"], ["'--fps'"]),
    "not-an-integer": (["render", W, "--frame", "x", "-o", "x.png"], ["'--frame'", "'x'"]),
    "bad-choice": (["render", W, "--fit", "bad", "-o", "x.png"], ["'--fit'", "'bad'"]),
    "bad-size": (["render", W, "--size", "3x3", "-o", "x.png"], ["'--size'", "3x3"]),
    "frame-outside-scene": (
        ["render", W, "--frame", "99999", "--view", "0,0,1", "-o", "x.png"],
        ["--frame", "frame 99999 is not in this scene"],
    ),
}
#: Malformed vectors (without --frame the command would select the pose first).
VECTOR_CASES = {
    "render-two-numbers": (["render", W, "-o", "x.png", "--view", "1,2"], ["'--view'", "'1,2'"]),
    "render-letters": (["render", W, "-o", "x.png", "--view", "a,b,c"], ["'--view'", "'a,b,c'"]),
    "render-nan": (["render", W, "-o", "x.png", "--view", "nan,1,0"], ["'--view'", "'nan,1,0'"]),
}


@pytest.fixture(scope="module")
def walk(motions_dir):
    return walk_clip(motions_dir)


@pytest.fixture(scope="module")
def runs(walk, tmp_path_factory) -> dict:
    cases = {
        cid: (row[0], {})
        for table in (SUFFIX_CASES, REFUSED, VECTOR_CASES)
        for cid, row in table.items()
    }
    cases["help"] = (["render", "--help"], {})
    return run_batch(cases, walk, tmp_path_factory.mktemp("cli_errors_render"))


@pytest.mark.parametrize("cid", sorted(SUFFIX_CASES))
def test_unsupported_output_suffix_is_refused_up_front(runs, cid):
    _, output, allowed = SUFFIX_CASES[cid]
    r = runs[cid]
    assert one_error_line(r, allowed) == f"error: {output}: {allowed}"
    assert r.files() == {}  # nothing written


@pytest.mark.parametrize("cid", sorted(REFUSED))
def test_bad_option_values_are_one_line(runs, cid):
    r = runs[cid]
    one_error_line(r, *REFUSED[cid][1])
    assert r.files() == {}  # nothing written, and a missing folder is not created


@pytest.mark.parametrize("cid", sorted(VECTOR_CASES))
def test_bad_vector_is_refused_before_pose_selection(runs, cid):
    """Without --frame render first selects the pose and says so on stderr
    ('frame N (selected pose)', then 'view [...]'); a bad vector stops it before."""
    r = runs[cid]
    one_error_line(r, *VECTOR_CASES[cid][1])
    assert "selected pose" not in r.output and "view [" not in r.output
    assert r.files() == {}


def test_help_is_unchanged(runs):
    r = runs["help"]
    assert r.rc == 0 and r.stdout.startswith("Usage: snapshot render [OPTIONS] PATHS...")
    assert "PNG file to write (.png)." in r.stdout
