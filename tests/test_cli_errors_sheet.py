"""`snapshot sheet`: bad command lines give one ``error:`` line, exit code 2, nothing
written (the runner and the rules: ``cli_helpers``); ``--columns`` lays out view
comparisons too."""

from __future__ import annotations

import pytest
from cli_helpers import W, alone, one_error_line, run_batch, walk_clip
from click.testing import CliRunner

from snapcore.cli.main import cli

#: Malformed vectors (without --frame the command would select the pose first).
VECTOR_CASES = {
    "sheet-zero": (["sheet", W, "-o", "x.png", "--view", "0,0,0"], ["'--view'", "'0,0,0'"]),
    "sheet-views": (
        ["sheet", W, "-o", "x.png", "--views", "a=0,0,1", "--views", "b=1,2"],
        ["'--views'", "'1,2'"],
    ),
    "sheet-views-no-name": (
        ["sheet", W, "-o", "x.png", "--views", "a0,0,1"],
        ["'--views'", "NAME=x,y,z"],
    ),
}


@pytest.fixture(scope="module")
def walk(motions_dir):
    return walk_clip(motions_dir)


@pytest.fixture(scope="module")
def runs(walk, tmp_path_factory) -> dict:
    cases = {cid: (row[0], {}) for cid, row in VECTOR_CASES.items()}
    cases["sheet-txt"] = (["sheet", W, "-o", "sh.txt"], {})
    return run_batch(cases, walk, tmp_path_factory.mktemp("cli_errors_sheet"))


def test_unsupported_output_suffix_is_refused_up_front(runs):
    r = runs["sheet-txt"]
    assert one_error_line(r, "sheet writes .png") == "error: -o/--output sh.txt: sheet writes .png"
    assert r.files() == {}


def test_unsupported_suffix_alone_in_a_process(walk, tmp_path):
    """A case that printed a traceback after all the work."""
    r = alone("sheet", walk, "-o", "sh.txt", cwd=tmp_path)
    one_error_line(r, "-o/--output sh.txt: sheet writes .")
    assert r.files() == {}


@pytest.mark.parametrize("cid", sorted(VECTOR_CASES))
def test_bad_vector_is_refused_before_pose_selection(runs, cid):
    """Without --frame sheet first selects the poses and says so on stderr; a bad
    vector stops it before."""
    r = runs[cid]
    one_error_line(r, *VECTOR_CASES[cid][1])
    assert "selected pose" not in r.output and "view [" not in r.output
    assert r.files() == {}


def test_sheet_columns_apply_to_view_comparisons(walk, tmp_path):
    from PIL import Image

    from snapcore.render.composites import PANEL_GAP

    def size(name, *args):
        out = tmp_path / name
        r = CliRunner().invoke(
            cli, ["sheet", str(walk), "-o", str(out), "--size", "64x80", "--frame", "10", *args]
        )
        assert r.exit_code == 0, r.output
        return Image.open(out).size

    views = ["--views", "a=0,0,1", "--views", "b=1,0,0"]
    w1, h1 = size("one.png", *views, "--columns", "1")
    w2, h2 = size("row.png", *views)
    assert w1 == 64 + 2 * PANEL_GAP and w2 == 2 * 64 + 3 * PANEL_GAP
    assert h1 > h2 + 80  # two rows
    w3, h3 = size("compare.png", "--compare", "--columns", "1")
    assert w3 == 64 + 2 * PANEL_GAP and h3 > h1  # three rows
