"""Key-moment annotations and `snapshot keymoments`: reading (TSV and JSON), refusing bad
files with one line naming file, line and field, the measures, and the outputs."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from snapcore.cli.main import cli
from snapcore.schema import validate
from snapcore.select.keymoments import (
    KeymomentsError,
    chance_rate,
    distance_to_intervals,
    hits,
    keymoments_to_json,
    read_keymoments,
)

HEADER = "scene\tfiles\tfps\tintervals\twhat\n"


def _run(args):
    return CliRunner().invoke(cli, args, catch_exceptions=False)


def _write(tmp_path, text, name="km.tsv"):
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


def test_measures_known_answers():
    """Hits use intervals widened by 0.1 s; distances are to the unwidened interval."""
    iv = [(100, 120), (300, 310)]
    assert hits([88, 89, 95, 133, 200, 305], iv, fps=100).tolist() == [
        False,
        False,
        True,
        False,
        False,
        True,
    ]
    np.testing.assert_allclose(
        distance_to_intervals([90, 110, 200, 320], iv, fps=100), [0.1, 0.0, 0.8, 0.1]
    )
    # frames 0..999; widened [90, 130] and [290, 320]: 41 + 31 frames
    assert chance_rate(iv, first=0, last=999, fps=100) == pytest.approx(72 / 1000)


def test_tsv_and_json_hold_the_same_content(tmp_path):
    """A TSV read, written as JSON (schema-valid) and read back gives the same entries."""
    p = _write(
        tmp_path, HEADER + "a\tx/1.bvh, x/2.bvh\t60\t1-5;10-12\ttwo people\nb\ty.bvh\t\t7-7\t\n"
    )
    entries = read_keymoments(p)
    assert entries[0].files == ["x/1.bvh", "x/2.bvh"] and entries[0].fps == 60
    assert entries[0].intervals == [(1, 5), (10, 12)] and entries[1].fps is None
    doc = keymoments_to_json(entries)
    validate(doc, "keymoments")
    q = tmp_path / "km.json"
    q.write_text(json.dumps(doc))
    again = read_keymoments(q)
    assert [(e.scene, e.files, e.fps, e.intervals, e.what) for e in again] == [
        (e.scene, e.files, e.fps, e.intervals, e.what) for e in entries
    ]


@pytest.mark.parametrize(
    "text, line, field",
    [
        (HEADER + "a\tx.bvh\t\t9-3\t\n", 2, "intervals"),  # a > b
        (HEADER + "a\tx.bvh\t\t1-3;oops\t\n", 2, "intervals"),  # malformed
        (HEADER + "a\tx.bvh\tfast\t1-3\t\n", 2, "fps"),  # not a number
        (HEADER + "a\tx.bvh\t\t1-3\t\n\tx.bvh\t\t1-3\t\n", 3, "scene"),  # empty scene
        ("scene\tfiles\tintervals\tcolour\n", 1, "colour"),  # unknown column
        ("scene\tfps\tintervals\n", 1, "files"),  # missing column
    ],
)
def test_bad_annotations_one_line_exit_2(tmp_path, text, line, field):
    """A bad file: exit 2, one stderr line naming the file, line and field, no traceback."""
    p = _write(tmp_path, text)
    with pytest.raises(KeymomentsError, match=f"{p}:{line}: {field}:"):
        read_keymoments(p)
    r = _run(["keymoments", str(p), "--data", str(tmp_path)])
    assert r.exit_code == 2
    err = r.stderr.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"error: {p}:{line}: {field}:"), r.stderr
    assert "Traceback" not in r.output


def test_missing_file_and_interval_outside_the_clip(tmp_path, motions_dir):
    """A listed file that is not there, and an interval past the clip's last frame."""
    p = _write(tmp_path, HEADER + "a\tnope/none.bvh\t\t1-3\t\n")
    r = _run(["keymoments", str(p), "--data", str(motions_dir)])
    assert r.exit_code == 2 and f"{p}:2: files:" in r.stderr
    p = _write(tmp_path, HEADER + "a\twalk_run/dataset-2_run_normal_001.bvh\t\t10-20;60-500\t\n")
    r = _run(["keymoments", str(p), "--data", str(motions_dir), "--methods", "middle"])
    assert r.exit_code == 2 and f"{p}:2: intervals: 60-500 is outside the clip" in r.stderr
    r = _run(["keymoments", str(p), "--methods", "middle,best"])
    assert r.exit_code == 2 and "best" in r.stderr


@pytest.mark.slow  # over 10 s on 2 cores
def test_keymoments_outputs(tmp_path, motions_dir):
    """Table on stdout; CSV, Markdown, schema-valid JSON and the timeline PNG in -o;
    the middle baseline's pick on a 68-frame clip is frame 33 (hit: 30-40)."""
    p = _write(tmp_path, HEADER + "run\twalk_run/dataset-2_run_normal_001.bvh\t\t30-40\trun\n")
    out = tmp_path / "res"
    r = _run(
        [
            "keymoments",
            str(p),
            "--data",
            str(motions_dir),
            "--methods",
            "middle,story",
            "-o",
            str(out),
        ]
    )
    assert r.exit_code == 0, r.output
    assert "ALL" in r.stdout and "middle" in r.stdout
    doc = json.loads((out / "keymoments.json").read_text())
    validate(doc, "keymoments_evaluation")
    row = next(x for x in doc["rows"] if x["method"] == "middle")
    assert row["frames"][0] == 33 and row["top1_hit"] and row["distance_s"] == 0
    assert (out / "keymoments.csv").read_text().startswith("scene,method,top1,top3")
    assert "| middle |" in (out / "keymoments.md").read_text()
    from PIL import Image

    img = np.asarray(Image.open(out / "keymoments_timeline.png").convert("L"), dtype=float)
    assert img.std() > 10
    j = _run(["keymoments", str(p), "--data", str(motions_dir), "--methods", "middle", "--json"])
    validate(json.loads(j.stdout), "keymoments_evaluation")
