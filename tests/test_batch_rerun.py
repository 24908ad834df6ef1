"""`snapshot batch` as an animator re-runs it: list files made by `find`, skipped files
reported, thumbnail choices kept as frames through --force and method changes, --sheet
toggled without redoing the selection, renamed clips, the sub-folder summary.

The gallery side of the same (choosing in the page, saving through `snapshot gallery`)
is tested in the browser in tests/test_batch_gallery.py.
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest
from test_batch import FAST_ARGS, SNAPSHOT

from snapcore.batch import discover
from snapcore.motion import synth
from snapcore.motion.bvh import write_bvh


def _clips(root: Path, names=("walk", "jump"), seconds: float = 1.5) -> Path:
    root.mkdir(parents=True, exist_ok=True)
    for i, name in enumerate(names):
        write_bvh(synth.humanoid_document(name, seconds=seconds, seed=i), root / f"{name}.bvh")
    return root


def test_a_find_made_list_of_absolute_paths_given_by_a_relative_path(tmp_path, monkeypatch):
    """`find $PWD/lib -name '*.bvh' > clips.txt; snapshot batch clips.txt`: absolute
    entries in a list named by a relative path are keyed relative to the list's folder
    (this crashed with `... is not in the subpath of ''`)."""
    lib = _clips(tmp_path / "lib" / "walks")
    lst = tmp_path / "clips.txt"
    lst.write_text("".join(f"{p.resolve()}\n" for p in sorted(lib.glob("*.bvh"))))
    monkeypatch.chdir(tmp_path)
    assert [s.key for s in discover(["clips.txt"]).scenes] == [
        "lib/walks/jump.bvh",
        "lib/walks/walk.bvh",
    ]
    # entries outside the list's folder are keyed by their own folder's name
    elsewhere = tmp_path / "sub"
    elsewhere.mkdir()
    (elsewhere / "clips.txt").write_text(lst.read_text())
    monkeypatch.chdir(elsewhere)
    assert [s.key for s in discover(["clips.txt"]).scenes] == ["jump.bvh", "walk.bvh"]


@pytest.mark.slow
def test_the_cli_runs_a_find_made_list(tmp_path):
    """The same through the command, from the list's folder: exit 0, both clips done."""
    lib = _clips(tmp_path / "lib")
    (tmp_path / "clips.txt").write_text(
        "".join(f"{p.resolve()}\n" for p in sorted(lib.glob("*.bvh")))
    )
    r = subprocess.run(
        [SNAPSHOT, "batch", "clips.txt", "-o", "out", *FAST_ARGS],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )
    assert r.returncode == 0, r.stderr
    assert "2 scenes: 2 processed" in r.stdout


# -- thumbnail choices are frames, kept ----------------------------------------------------


def _thumb_is_frame(out: Path, row: dict, clip: Path, frame: int, size) -> bool:
    """The row's thumbnail is the still of source ``frame`` from the row's view."""
    import io

    import numpy as np
    from PIL import Image

    from snapcore.motion.load import load_scene
    from snapcore.render.renderer import render_still

    scene = load_scene([str(clip)])
    expected = render_still(
        scene,
        frame,
        np.array([row["view_x"], row["view_y"], row["view_z"]]),
        size=size,
    )[..., :3]
    thumb = np.asarray(Image.open(io.BytesIO((out / row["thumb"]).read_bytes())).convert("RGB"))
    return thumb.shape == expected.shape and np.abs(thumb.astype(int) - expected).max() <= 1


def _row(out: Path, key: str) -> dict:
    from snapcore.batch.index import read_index

    return next(r for r in read_index(out / "index.csv") if r["path"] == key)


@pytest.mark.slow
def test_a_chosen_frame_survives_force_and_another_pose_method(tmp_path):
    """A frame written into thumb-choices.csv (not one of the top poses) becomes the
    thumbnail, and stays it through a re-run, --force, --pose-method paper and the file
    being deleted: the choice is a source frame kept in the index, not a rank (the rank
    once pointed at another frame under another method, and --force dropped it)."""
    from snapcore.batch.choices import CHOICES_NAME

    lib = _clips(tmp_path / "lib", ("walk",), seconds=2.0)
    out = tmp_path / "out"
    base = [SNAPSHOT, "batch", str(lib), "-o", str(out), *FAST_ARGS]
    assert subprocess.run(base, capture_output=True, text=True).returncode == 0
    row = _row(out, "walk.bvh")
    chosen = next(f for f in range(row["first_frame"] + 5, 60) if f not in row["top_frames"])
    (out / CHOICES_NAME).write_text(f"path,frame\nwalk.bvh,{chosen}\n")
    for extra in ([], ["--force"], ["--pose-method", "paper"], ["--pose-method", "paper"]):
        r = subprocess.run(base + extra, capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
        row = _row(out, "walk.bvh")
        assert (row["thumb_choice"], row["thumb_frame"]) == (chosen, chosen), extra
        assert _thumb_is_frame(out, row, lib / "walk.bvh", chosen, (160, 180)), extra
        (out / CHOICES_NAME).unlink(missing_ok=True)  # the index keeps it from now on
    assert "1 already done" in r.stdout  # the last run: nothing to do


def test_a_choice_the_clip_no_longer_has_is_reported_and_kept(tmp_path):
    """A chosen frame past the end of a clip that got shorter: the thumbnail shows the
    chosen pose, the row's warnings say why, and the choice stays in the index, also
    while the file is broken, so the longer take coming back shows it again; a cleared
    entry (empty frame) removes it."""
    from snapcore.batch import BatchOptions, run_batch
    from snapcore.batch.choices import write_choices

    opts = BatchOptions(snapshot={"baselines": False}, size=(80, 90), preview=0)
    lib = _clips(tmp_path / "lib", ("walk",), seconds=2.0)
    out = tmp_path / "out"
    run_batch(discover([lib]).scenes, out, opts)
    write_choices(out, {"walk.bvh": 55})
    run_batch(discover([lib]).scenes, out, opts)
    assert _row(out, "walk.bvh")["thumb_frame"] == 55
    _clips(tmp_path / "lib", ("walk",), seconds=1.0)  # 31 frames now
    run_batch(discover([lib]).scenes, out, opts)
    row = _row(out, "walk.bvh")
    assert row["thumb_choice"] == 55 and row["thumb_frame"] == row["frame"]
    assert any(
        "thumbnail frame 55 chosen in the gallery is not in the clip" in w for w in row["warnings"]
    )
    (out / "thumb-choices.csv").unlink()  # from here on the index alone holds it
    (lib / "walk.bvh").write_text("broken for a while\n")
    run_batch(discover([lib]).scenes, out, opts)
    row = _row(out, "walk.bvh")
    assert row["status"] == "error" and row["thumb_choice"] == 55
    _clips(tmp_path / "lib", ("walk",), seconds=2.0)  # the long take is back
    run_batch(discover([lib]).scenes, out, opts)
    assert _row(out, "walk.bvh")["thumb_frame"] == 55
    write_choices(out, {"walk.bvh": None})
    run_batch(discover([lib]).scenes, out, opts)
    row = _row(out, "walk.bvh")
    assert row["thumb_choice"] is None and not row["warnings"]


def test_an_older_file_of_ranks_is_read_through_the_index(tmp_path):
    """A `path,pose` file from before choices were frames is read as the frames of those
    ranks in the index, so its choices are not lost; a rank the index lacks is one
    error naming the line."""
    from snapcore.batch.choices import CHOICES_NAME, read_choices
    from snapcore.batch.discover import BatchError

    rows = [{"path": "a.bvh", "top_frames": [40, 12, 77]}]
    (tmp_path / CHOICES_NAME).write_text('path,pose\n"a.bvh",2\n')
    assert read_choices(tmp_path, rows) == {"a.bvh": 12}
    (tmp_path / CHOICES_NAME).write_text("path,pose\na.bvh,5\n")
    with pytest.raises(BatchError, match=r"thumb-choices.csv:2: pose #5 of a.bvh"):
        read_choices(tmp_path, rows)
    (tmp_path / CHOICES_NAME).write_text("path,frame\na.bvh,-3\n")
    with pytest.raises(BatchError, match=r"thumb-choices.csv:2: expected 'path,frame'"):
        read_choices(tmp_path, rows)


# -- what a re-run redoes ----------------------------------------------------------------------


@pytest.mark.slow
def test_adding_sheets_renders_only_them_and_dropping_them_redoes_nothing(tmp_path):
    """--sheet is outside the options hash: added, every scene gets its sheet without a
    new selection (the same document, no selection time); dropped, nothing runs."""
    from snapcore.batch import BatchOptions, run_batch

    lib = _clips(tmp_path / "lib")
    out = tmp_path / "out"
    plain = BatchOptions(
        snapshot={"baselines": False}, size=(80, 90), preview=4, sheet_size=(60, 70)
    )
    first = run_batch(discover([lib]).scenes, out, plain)
    docs = {r["path"]: (out / r["json"]).read_bytes() for r in first.rows}
    sheets = BatchOptions(
        snapshot={"baselines": False}, size=(80, 90), preview=4, sheet=True, sheet_size=(60, 70)
    )
    again = run_batch(discover([lib]).scenes, out, sheets)
    assert again.done == 2
    for r in again.rows:
        assert r["sheet"] and (out / r["sheet"]).is_file() and r["t_select_s"] == 0.0
        assert (out / r["json"]).read_bytes() == docs[r["path"]]
        assert r["options_hash"] == first.rows[0]["options_hash"]
    assert run_batch(discover([lib]).scenes, out, plain).done == 0
    # a changed option that does change the numbers is still noticed
    other = BatchOptions(
        snapshot={"baselines": False, "k": 2}, size=(80, 90), preview=4, sheet_size=(60, 70)
    )
    assert run_batch(discover([lib]).scenes, out, other).done == 2


def test_the_preview_strip_holds_the_whole_motion(tmp_path):
    """The preview strip is N panels side by side of the preview size, at source frames
    from the first to the last analysed frame, evenly spaced."""
    from PIL import Image

    from snapcore.batch import BatchOptions, run_batch
    from snapcore.batch.task import preview_size

    lib = _clips(tmp_path / "lib", ("jump",), seconds=2.0)
    opts = BatchOptions(snapshot={"baselines": False}, size=(160, 180), preview=6)
    row = run_batch(discover([lib]).scenes, tmp_path / "out", opts).rows[0]
    frames = row["preview_frames"]
    last = row["first_frame"] + row["n_frames"] - 1
    assert len(frames) == 6 and frames[0] == row["first_frame"] and frames[-1] == last
    steps = [b - a for a, b in zip(frames, frames[1:])]
    assert max(steps) - min(steps) <= 1
    w, h = preview_size((160, 180))
    assert Image.open(tmp_path / "out" / row["preview"]).size == (6 * w, h)


@pytest.mark.slow
def test_a_renamed_clip_gets_a_prune_hint_and_the_summary_counts_this_runs_errors(tmp_path):
    """After renaming a clip the run says its old row is stale and that --prune drops
    it; a sub-folder run counts only its own scenes' errors (errors of other folders are
    said to be among the kept rows); a JSON that does not parse reaches the gallery."""
    lib = tmp_path / "lib"
    _clips(lib / "walks")
    (lib / "broken").mkdir()
    (lib / "broken" / "bad.bvh").write_text("not a bvh\n")
    (lib / "broken" / "scene.json").write_text('{"characters": [')
    out = tmp_path / "out"
    base = [SNAPSHOT, "batch", "-o", str(out), *FAST_ARGS, "--preview", "0"]
    r = subprocess.run([*base, str(lib)], capture_output=True, text=True)
    assert "1 with errors" in r.stdout, r.stdout
    # the JSON that does not parse goes to the gallery's summary (the page's data)
    page = (out / "index.html").read_text()
    meta = json.loads(
        page.split('<script id="meta" type="application/json">')[1].split("</script>")[0]
    )
    assert [(Path(p).name, why) for p, why in meta["skipped"]] == [
        ("scene.json", "not a scene manifest (does not parse)")
    ]
    (lib / "walks" / "walk.bvh").rename(lib / "walks" / "walk_v2.bvh")
    r = subprocess.run([*base, str(lib / "walks")], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "0 with errors" in r.stdout and "1 of them with errors" in r.stdout, r.stdout
    assert "walks/walk.bvh" in r.stderr and "--prune drops them" in r.stderr, r.stderr
    assert "broken/bad.bvh" not in r.stderr  # a folder this run did not walk


def test_snapshot_gallery_refuses_a_folder_without_a_gallery(tmp_path):
    """`snapshot gallery` on a folder that holds no batch output: one line naming the
    folder, exit code 2, no server."""
    r = subprocess.run(
        [SNAPSHOT, "gallery", str(tmp_path), "--port", "0"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert r.returncode == 2, r.stderr
    assert r.stderr.strip().count("\n") == 0 and "no batch gallery here" in r.stderr
    assert str(tmp_path) in r.stderr
