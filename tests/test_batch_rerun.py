"""`snapshot batch` as an animator re-runs it: list files made by `find`, skipped files
reported, thumbnail choices kept as frames through --force and method changes, --sheet
toggled without redoing the selection, renamed clips, the sub-folder summary.

The gallery side of the same (choosing in the page, saving through `snapshot gallery`)
is tested in the browser in tests/test_batch_gallery.py.
"""

from __future__ import annotations

import subprocess
from pathlib import Path

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
