"""`snapshot batch` at library scale: memory, dead workers, sub-folder runs, stray JSON,
signals to the main process, Dask set-up, the Parquet index and the thumbnail choice.

The run-time at scale (2,500 clips, scenes per minute, RSS per worker) is a bench case
(`snapshot bench batch_library`), not a test.
"""

from __future__ import annotations

import gc
import json
import os
import signal
import subprocess
import time
import weakref
from pathlib import Path

import pytest
from test_batch import FAST, FAST_ARGS, SNAPSHOT

from snapcore.batch import discover, run_batch
from snapcore.batch.index import read_index
from snapcore.motion import synth
from snapcore.motion.bvh import write_bvh


def test_a_processed_scene_is_freed_with_its_bodies(tmp_path):
    """A scene that was selected, rendered and dropped leaves nothing behind: the body
    cache once kept every scene alive (its values, the bodies, hold the scene), 10-18
    MB a scene in a batch worker."""
    from snapcore.motion.load import load_scene
    from snapcore.pipeline import ViewParams, take_snapshot
    from snapcore.render.renderer import render_still

    path = tmp_path / "walk.bvh"
    write_bvh(synth.humanoid_document("walk", seconds=1.0), path)
    scene = load_scene([str(path)])
    snap = take_snapshot(scene, view=ViewParams(baselines=False))
    render_still(scene, snap.source_frame, snap.view, size=(80, 90))
    alive = weakref.ref(scene)
    del scene, snap
    gc.collect()
    assert alive() is None


# -- a dead worker, signals to the main process -----------------------------------------


def _small_library(root: Path, n: int, seconds: float = 1.5) -> Path:
    root.mkdir(parents=True)
    for i in range(n):
        write_bvh(
            synth.humanoid_document(("walk", "jump", "punch")[i % 3], seconds=seconds, seed=i),
            root / f"c{i}.bvh",
        )
    return root


@pytest.mark.slow
def test_a_killed_worker_leaves_no_good_scene_marked_as_an_error(tmp_path):
    """SIGKILL to one of two workers after the first result: every scene still ends
    ok (the scenes in flight are run again), the run says a worker died, and a re-run
    has nothing to do. (It once gave 22 good scenes a cached BrokenProcessPool.)"""
    import psutil

    lib = _small_library(tmp_path / "lib", 6)
    messages, killed = [], []

    def progress(total):
        def tick(row):
            if not killed:
                workers = [
                    p
                    for p in psutil.Process().children()
                    if "resource_tracker" not in " ".join(p.cmdline())
                ]
                assert len(workers) == 2
                workers[0].send_signal(signal.SIGKILL)
                killed.append(workers[0].pid)

        return tick

    report = run_batch(
        discover([lib]).scenes,
        tmp_path / "out",
        FAST,
        jobs=2,
        progress=progress,
        notify=messages.append,
    )
    assert killed
    rows = read_index(tmp_path / "out" / "index.csv")
    assert [r["status"] for r in rows] == ["ok"] * 6, [r["error"] for r in rows]
    assert report.done == 6 and report.errors == 0
    assert any("worker process died (killed by signal 9" in m for m in messages), messages
    again = run_batch(discover([lib]).scenes, tmp_path / "out", FAST, jobs=2)
    assert (again.done, again.reused) == (0, 6)


def _children_of(pid: int) -> list:
    import psutil

    return psutil.Process(pid).children(recursive=True)


def _gone(pids, within_s: float) -> bool:
    import psutil

    deadline = time.monotonic() + within_s
    while time.monotonic() < deadline:
        if not [
            p
            for p in pids
            if psutil.pid_exists(p) and psutil.Process(p).status() != psutil.STATUS_ZOMBIE
        ]:
            return True
        time.sleep(0.2)
    return False


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL])
def test_no_worker_outlives_a_killed_main_process(tmp_path, sig):
    """SIGTERM or SIGKILL to the main process of `--jobs 2` (not its group, as `kill
    PID` does): its workers are gone within seconds instead of running on under PID 1;
    SIGTERM also writes the index of what finished, like Ctrl-C."""
    lib = _small_library(tmp_path / "lib", 6)
    out = tmp_path / "out"
    proc = subprocess.Popen(
        [SNAPSHOT, "batch", str(lib), "-o", str(out), "--jobs", "2", *FAST_ARGS],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    try:
        deadline = time.monotonic() + 240
        while not list((out / "scenes").glob("*.sheet.png")) and time.monotonic() < deadline:
            assert proc.poll() is None, proc.communicate()
            time.sleep(0.1)
        workers = [
            p.pid for p in _children_of(proc.pid) if "resource_tracker" not in " ".join(p.cmdline())
        ]
        assert len(workers) == 2
        os.kill(proc.pid, sig)
        _, stderr = proc.communicate(timeout=60)
        assert _gone(workers, 10), "workers still running after the main process ended"
        if sig == signal.SIGTERM:
            assert proc.returncode == 130 and "interrupted:" in stderr, stderr
            assert "Traceback" not in stderr
            rows = read_index(out / "index.csv")
            assert rows and all((out / r["thumb"]).is_file() for r in rows)
    finally:
        try:  # whatever is left of the run's session (its workers too, were they there)
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass


# -- what is a scene, and what it is called ----------------------------------------------


def test_a_json_with_a_characters_list_is_not_taken_for_a_manifest(tmp_path):
    """In a folder, an old gallery's rows, a `select --json` document or any JSON with a
    `characters` list is skipped with the schema's reason; a real manifest (JSON or
    TOML) is a scene. (Every such JSON once became an error row.)"""
    lib = _small_library(tmp_path / "lib", 2)
    (lib / "select.json").write_text(
        json.dumps({"frame": 3, "characters": [{"name": "c0", "joints": 31}]}), encoding="utf-8"
    )
    (lib / "gallery.json").write_text(json.dumps({"characters": []}), encoding="utf-8")
    (lib / "pair.json").write_text(
        json.dumps(
            {
                "name": "pair",
                "characters": [{"file": "c0.bvh"}, {"file": "c1.bvh", "offset": [0, 0, 1]}],
            }
        ),
        encoding="utf-8",
    )
    found = discover([lib])
    assert [(s.key, s.kind) for s in found.scenes] == [("pair.json", "manifest")]
    why = {Path(p).name: w for p, w in found.skipped}
    assert why["select.json"].startswith("not a scene manifest (select.json: ")
    assert why["gallery.json"].startswith("not a scene manifest (gallery.json: characters")
    assert why["c0.bvh"] == "part of a scene manifest"
    # named explicitly, a non-manifest is still a scene, so its error is reported
    assert [s.kind for s in discover([lib / "select.json"]).scenes] == ["manifest"]


@pytest.mark.slow
def test_a_sub_folder_run_updates_its_rows_of_the_library_index(tmp_path):
    """`snapshot batch LIB/sub -o OUT` after `snapshot batch LIB -o OUT`: the sub-folder's
    scenes keep their keys (`sub/...`), their rows are updated in place (no copies
    beside them), the other rows stay, and the closing line suggests no --prune. The
    same holds for an output written before the library root was recorded."""
    from snapcore.batch.run import LIBRARY_NAME, library_root

    lib = tmp_path / "lib"
    _small_library(lib / "walks", 2)
    _small_library(lib / "more" / "deep", 1)
    out = tmp_path / "out"
    r = subprocess.run(
        [SNAPSHOT, "batch", str(lib), "-o", str(out), *FAST_ARGS], capture_output=True, text=True
    )
    assert r.returncode == 0, r.stderr
    keys = ["more/deep/c0.bvh", "walks/c0.bvh", "walks/c1.bvh"]
    assert [row["path"] for row in read_index(out / "index.csv")] == keys
    write_bvh(synth.humanoid_document("jump", seconds=1.2, seed=9), lib / "walks" / "c1.bvh")
    r = subprocess.run(
        [SNAPSHOT, "batch", str(lib / "walks"), "-o", str(out), *FAST_ARGS],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, r.stderr
    assert "1 processed" in r.stdout and "1 already done" in r.stdout, r.stdout
    assert "--prune" not in r.stdout + r.stderr
    rows = read_index(out / "index.csv")
    assert [row["path"] for row in rows] == keys
    assert rows[2]["n_frames"] < rows[1]["n_frames"]  # 1.2 s, not 1.5: the edited clip redone
    # an output from before library.json: the root is found from the index's keys
    (out / LIBRARY_NAME).unlink()
    assert library_root(out, [lib / "more" / "deep"]) == lib.resolve()
    assert library_root(tmp_path / "new", [lib / "walks"]) == (lib / "walks").resolve()


def test_the_parquet_index_holds_the_csv_rows_with_the_schema_types(tmp_path):
    """OUT/index.parquet has the CSV's columns in the same order, the same rows, and
    typed columns (integers, floats, strings, lists of frames; nulls as nulls)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from snapcore.batch.index import COLUMNS, read_parquet

    lib = _small_library(tmp_path / "lib", 1)
    (lib / "bad.bvh").write_text("not a bvh\n", encoding="utf-8")
    run_batch(discover([lib]).scenes, tmp_path / "out", FAST)
    table = pq.read_table(tmp_path / "out" / "index.parquet")
    assert tuple(table.column_names) == COLUMNS
    assert table.schema.field("n_frames").type == pa.int64()
    assert table.schema.field("duration_s").type == pa.float64()
    assert table.schema.field("path").type == pa.string()
    # frame lists and warnings are lists, not ';'-joined strings
    assert table.schema.field("top_frames").type == pa.list_(pa.int64())
    assert table.schema.field("preview_frames").type == pa.list_(pa.int64())
    assert table.schema.field("warnings").type == pa.list_(pa.string())
    good = next(r for r in read_parquet(tmp_path / "out" / "index.parquet") if r["status"] == "ok")
    assert isinstance(good["top_frames"], list) and good["frame"] == good["top_frames"][0]
    assert read_parquet(tmp_path / "out" / "index.parquet") == read_index(
        tmp_path / "out" / "index.csv"
    )


def test_lost_dask_workers_are_reported():
    """The Dask executor's watch says how many workers were lost and how many are left
    (the bar once froze for 90 s without a word), and how many joined."""
    from snapcore.batch.run import _watch_workers

    class Client:
        def __init__(self, names):
            self.names = names

        def scheduler_info(self):
            return {"workers": {n: {} for n in self.names}}

    said = []
    now = _watch_workers(Client(["tcp://a", "tcp://b"]), {"tcp://a", "tcp://b"}, said.append)
    assert now == {"tcp://a", "tcp://b"} and said == []
    now = _watch_workers(Client(["tcp://b"]), now, said.append)
    assert said == [
        "Dask: 1 worker(s) lost (tcp://a); their scenes run again on the others; 1 left"
    ]
    now = _watch_workers(Client([]), now, said.append)
    assert "none left: waiting for a worker to join" in said[-1]
    # the first to come back after none were left is reported too (it once was not)
    _watch_workers(Client(["tcp://c", "tcp://d"]), now, said.append)
    assert said[-1] == "Dask: 2 worker(s) joined; 2 now"
