"""`snapshot video`: bad command lines give one ``error:`` line, exit code 2, nothing
written (the runner and the rules: ``cli_helpers``)."""

from __future__ import annotations

import pytest
from cli_helpers import W, alone, one_error_line, run_batch, walk_clip

#: Outputs the command cannot write: (args, output as given, what the line says).
SUFFIX_CASES = {
    "video-txt": (["video", W, "-o", "v.txt"], "-o/--output v.txt", "video writes .mp4"),
    "video-avi": (["video", W, "-o", "v.avi"], "-o/--output v.avi", "video writes .mp4"),
    "video-frame-map-txt": (
        ["video", W, "-o", "v.mp4", "--frame-map", "map.txt"],
        "--frame-map map.txt",
        "the frame map is written as .json",
    ),
}
#: Refused command lines: (args, what the one line names).
REFUSED = {
    "missing-folder": (
        ["video", W, "-o", "missing/v.mp4"],
        ["-o/--output missing/v.mp4: folder missing does not exist"],
    ),
    "motion-fps=0": (["video", W, "-o", "v.mp4", "--motion-fps", "0"], ["'--motion-fps'"]),
    "motion-fps=nan": (["video", W, "-o", "v.mp4", "--motion-fps", "nan"], ["'--motion-fps'"]),
    "scale=-1": (["video", W, "-o", "v.mp4", "--scale", "-1"], ["'--scale'"]),
    "fps=nan": (["video", W, "-o", "v.mp4", "--fps", "nan"], ["'--fps'", "finite"]),
}
#: A malformed vector (without --view the command would select the pose first).
VECTOR = (["video", W, "-o", "v.mp4", "--view", "1,2,x"], ["'--view'", "'1,2,x'"])


@pytest.fixture(scope="module")
def walk(motions_dir):
    return walk_clip(motions_dir)


@pytest.fixture(scope="module")
def runs(walk, tmp_path_factory) -> dict:
    cases = {cid: (row[0], {}) for table in (SUFFIX_CASES, REFUSED) for cid, row in table.items()}
    cases["vector"] = (VECTOR[0], {})
    return run_batch(cases, walk, tmp_path_factory.mktemp("cli_errors_video"))


@pytest.mark.parametrize("cid", sorted(SUFFIX_CASES))
def test_unsupported_output_suffix_is_refused_up_front(runs, cid):
    _, output, allowed = SUFFIX_CASES[cid]
    r = runs[cid]
    assert one_error_line(r, allowed) == f"error: {output}: {allowed}"
    assert r.files() == {}  # nothing written, not even the other outputs


def test_unsupported_suffix_alone_in_a_process(walk, tmp_path):
    """A case that printed ffmpeg's log after all the work."""
    r = alone("video", walk, "-o", "v.txt", cwd=tmp_path)
    one_error_line(r, "-o/--output v.txt: video writes .")
    assert r.files() == {}


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
