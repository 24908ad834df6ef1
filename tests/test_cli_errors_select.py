"""`snapshot select`: bad command lines give one ``error:`` line, exit code 2, nothing
written and the input never overwritten (the runner and the rules: ``cli_helpers``)."""

from __future__ import annotations

import pytest
from cli_helpers import W, one_error_line, run_batch, walk_clip

#: Refused command lines: (args, what the one line names).
REFUSED = {
    "missing-folder": (
        ["select", W, "-o", "missing/s.json"],
        ["-o/--output missing/s.json: folder missing does not exist"],
    ),
    "smooth=inf": (["select", W, "--smooth", "inf"], ["'--smooth'", "finite"]),
    "min-separation=nan": (
        ["select", W, "--min-separation", "nan"],
        ["'--min-separation'", "finite"],
    ),
    # the paper's options with another method: refused by PoseParams, named as flags
    "paper-flags-with-story": (
        ["select", W, "--w-local", "0.5", "--smooth", "0", "-o", "s.json"],
        ["--pose-method", "--w-local, --smooth apply to --pose-method paper only, not story"],
    ),
}


@pytest.fixture(scope="module")
def walk(motions_dir):
    return walk_clip(motions_dir)


@pytest.fixture(scope="module")
def runs(walk, tmp_path_factory) -> dict:
    cases = {cid: (row[0], {}) for cid, row in REFUSED.items()}
    cases["input"] = (
        ["select", "walk.bvh", "-o", "walk.bvh", "--no-view"],
        {"walk.bvh": None},
    )  # None: a copy of the clip
    return run_batch(cases, walk, tmp_path_factory.mktemp("cli_errors_select"))


@pytest.mark.parametrize("cid", sorted(REFUSED))
def test_bad_option_values_are_one_line(runs, cid):
    r = runs[cid]
    one_error_line(r, *REFUSED[cid][1])
    assert r.files() == {}  # nothing written, and a missing folder is not created


def test_select_does_not_overwrite_its_input(runs, walk):
    r = runs["input"]
    one_error_line(r, "-o/--output walk.bvh: is one of the input files")
    assert r.files() == {"walk.bvh": walk.read_bytes()}
