"""`snapshot plot-entropy` and `snapshot plot-views`: bad command lines give one
``error:`` line, exit code 2, nothing written (the runner and the rules:
``cli_helpers``)."""

from __future__ import annotations

import pytest
from cli_helpers import W, alone, one_error_line, run_batch, walk_clip

#: Outputs the commands cannot write: (args, output as given, what the line says).
SUFFIX_CASES = {
    "plot-entropy-txt": (
        ["plot-entropy", W, "-o", "ent.txt"],
        "-o/--output ent.txt",
        "plot-entropy writes .png, .pdf or .svg",
    ),
    "plot-views-txt": (
        ["plot-views", W, "-o", "pv.txt"],
        "-o/--output pv.txt",
        "plot-views writes .png, .pdf or .svg",
    ),
}
#: Refused command lines: (args, what the one line names).
REFUSED = {
    "plot-entropy-missing-folder": (
        ["plot-entropy", W, "-o", "missing/e.pdf"],
        ["-o/--output missing/e.pdf: folder missing does not exist"],
    ),
    "plot-views-window=nan": (
        ["plot-views", W, "-o", "v.png", "--window", "nan"],
        ["'--window'", "finite"],
    ),
}


@pytest.fixture(scope="module")
def walk(motions_dir):
    return walk_clip(motions_dir)


@pytest.fixture(scope="module")
def runs(walk, tmp_path_factory) -> dict:
    cases = {cid: (row[0], {}) for table in (SUFFIX_CASES, REFUSED) for cid, row in table.items()}
    return run_batch(cases, walk, tmp_path_factory.mktemp("cli_errors_plots"))


@pytest.mark.parametrize("cid", sorted(SUFFIX_CASES))
def test_unsupported_output_suffix_is_refused_up_front(runs, cid):
    _, output, allowed = SUFFIX_CASES[cid]
    r = runs[cid]
    assert one_error_line(r, allowed) == f"error: {output}: {allowed}"
    assert r.files() == {}


def test_unsupported_suffix_alone_in_a_process(walk, tmp_path):
    """A case that printed a traceback after all the work."""
    r = alone("plot-entropy", walk, "-o", "ent.txt", cwd=tmp_path)
    one_error_line(r, "-o/--output ent.txt: plot-entropy writes .")
    assert r.files() == {}


@pytest.mark.parametrize("cid", sorted(REFUSED))
def test_bad_option_values_are_one_line(runs, cid):
    r = runs[cid]
    one_error_line(r, *REFUSED[cid][1])
    assert r.files() == {}  # nothing written, and a missing folder is not created
