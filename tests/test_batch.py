"""`snapshot batch`: discovery, the task, resuming, errors as rows, processes, Dask, Ctrl-C.

Most properties are checked on a tiny library of short synthetic clips (1.5-2 s at
30 fps, no baseline views) so the module stays fast; the real folder is used where the
property is about it (the salsa manifests, a damaged copy of real clips). The gallery
is tested in a browser in tests/test_batch_gallery.py.
"""

from __future__ import annotations

import io
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from batch_helpers import make_library
from conftest import need

from snapcore.batch import BatchOptions, discover, run_batch
from snapcore.batch.discover import BatchError, content_hash
from snapcore.batch.index import COLUMNS, TIMING_COLUMNS, read_index, write_index
from snapcore.batch.run import plan_batch
from snapcore.batch.task import SceneTask, run_scene
from snapcore.cli.batch import snapshot_kwargs
from snapcore.cli.select import pose_options
from snapcore.motion import synth
from snapcore.motion.bvh import write_bvh
from snapcore.schema import load_schema, validate

REPO = Path(__file__).resolve().parents[1]
SNAPSHOT = str(Path(sys.executable).with_name("snapshot"))
SCENES = REPO / "snapcore" / "batch" / "scenes"


@pose_options
def _pose_defaults():
    """Carrier of `snapshot select`'s pose options (their defaults are read below)."""


#: `snapshot batch`'s defaults for the pipeline, as the command builds them.
POSE_DEFAULTS = {p.name: p.default for p in _pose_defaults.__click_params__}
#: Small and fast: no baseline views, small pictures.
FAST = BatchOptions(
    snapshot=snapshot_kwargs(POSE_DEFAULTS, baselines=False),
    size=(160, 180),
    sheet=True,
    sheet_size=(120, 135),
)
FAST_ARGS = ["--no-baselines", "--size", "160x180", "--sheet", "--sheet-size", "120x135", "-q"]


@pytest.fixture(scope="module")
def library(tmp_path_factory):
    return make_library(tmp_path_factory.mktemp("lib") / "lib")


@pytest.fixture(scope="module")
def local_run(library, tmp_path_factory):
    """The library done once in this process (jobs=1): (out folder, report)."""
    out = tmp_path_factory.mktemp("out") / "out"
    report = run_batch(discover([library]).scenes, out, FAST)
    return out, report


#: Scenes of the library run again by the parallel executors: one clip, the two-character
#: manifest and one error (a whole second library would only repeat the same path).
SUBSET = ("duo/duo.toml", "notes.bvh", "walks/walk.bvh")


def subset(library):
    return [s for s in discover([library]).scenes if s.key in SUBSET]


def strip_timings(rows, keys=None):
    return [
        {k: v for k, v in r.items() if k not in TIMING_COLUMNS}
        for r in rows
        if keys is None or r["path"] in keys
    ]


def test_discovery_takes_scenes_and_leaves_manifest_members_out(library):
    """Folders are walked; a manifest's members are not scenes of their own; a JSON
    that is not a manifest is skipped; keys are relative to the SOURCE."""
    found = discover([library])
    assert [s.key for s in found.scenes] == [
        "duo/duo.toml",
        "jumps/jump.bvh",
        "jumps/truncated.bvh",
        "model.glb",
        "notes.bvh",
        "walks/walk.bvh",
    ]
    kinds = {s.key: s.kind for s in found.scenes}
    assert kinds["duo/duo.toml"] == "manifest" and kinds["model.glb"] == "gltf"
    duo = next(s for s in found.scenes if s.kind == "manifest")
    assert [Path(m).name for m in duo.members] == ["a.bvh", "b.bvh"]
    skipped = {Path(p).name: why.split(" (")[0] for p, why in found.skipped}
    assert skipped == {
        "a.bvh": "part of a scene manifest",
        "b.bvh": "part of a scene manifest",
        "notes.json": "not a scene manifest",
    }


def test_discovery_globs_list_files_and_missing_sources(library, tmp_path):
    """A glob and a list file name the same scenes as the folder does; a SOURCE that
    does not exist is one error naming it."""
    by_glob = discover([str(library / "**" / "*.bvh")])
    assert {s.key for s in by_glob.scenes} == {
        "jumps/jump.bvh",
        "jumps/truncated.bvh",
        "notes.bvh",
        "walks/walk.bvh",
        "duo/a.bvh",
        "duo/b.bvh",
    }  # no manifest among them
    lst = library / "some.txt"
    lst.write_text("# two scenes\nwalks/walk.bvh\nduo/duo.toml\n", encoding="utf-8")
    try:
        assert [s.key for s in discover([lst]).scenes] == ["duo/duo.toml", "walks/walk.bvh"]
    finally:
        lst.unlink()
    with pytest.raises(BatchError, match=r"SOURCE .*nowhere: no such file or folder"):
        discover([tmp_path / "nowhere"])
    with pytest.raises(BatchError, match="matches no files"):
        discover([str(tmp_path / "*.bvh")])


def test_shared_library_with_the_salsa_manifests(motions_dir):
    """The shared folder plus the shipped salsa manifests: every BVH and GLB is a scene
    except the four salsa files, which are the two manifests' members."""
    found = discover([motions_dir, SCENES])
    keys = {s.key for s in found.scenes}
    files = {
        p.relative_to(motions_dir).as_posix()
        for p in motions_dir.rglob("*")
        if p.suffix in (".bvh", ".glb")
    }
    salsa = {f for f in files if f.startswith("two_person/")}
    assert len(salsa) == 4
    assert keys == (files - salsa) | {"two_person/salsa_01.toml", "two_person/salsa_12.toml"}
    assert {Path(p).relative_to(motions_dir).as_posix() for p, _ in found.skipped} == salsa


def test_content_hash_follows_every_file_of_a_scene(tmp_path):
    """Editing a manifest's member changes the manifest scene's hash."""
    root = make_library(tmp_path / "lib", broken=False)
    duo = next(s for s in discover([root]).scenes if s.kind == "manifest")
    before = content_hash(duo)
    with open(root / "duo" / "b.bvh", "a", encoding="utf-8") as fh:
        fh.write("\n")
    assert content_hash(duo) != before


def test_index_round_trips_and_the_schema_lists_its_columns(tmp_path):
    """The CSV reads back to the values written (nulls and lists included); the schema
    documents exactly the index's columns."""
    assert set(load_schema("batch_index")["properties"]) == set(COLUMNS)
    row = {c: None for c in COLUMNS} | {
        "path": "a/b c,d.bvh",
        "folder": "a",
        "name": "b c,d.bvh",
        "kind": "bvh",
        "status": "ok",
        "content_hash": "0" * 64,
        "options_hash": "f" * 64,
        "characters": 2,
        "n_frames": 10,
        "fps": 30.0,
        "frame": 3,
        "view_x": -0.5,
        "top_frames": [3, 7],
        "warnings": ["one, with a comma", 'two "quoted"'],
        "error": 'quote " and, comma',
    }
    write_index(tmp_path / "index.csv", [row])
    assert read_index(tmp_path / "index.csv") == [row]
    assert [p.name for p in tmp_path.iterdir()] == ["index.csv"]  # no temporary left


def test_a_batch_writes_outputs_index_and_gallery(local_run, library):
    """Every scene has a row; good ones have the snapshot JSON (select's document),
    a thumbnail and a sheet; bad ones a one-line error; the rows follow the schema."""
    out, report = local_run
    rows = {r["path"]: r for r in read_index(out / "index.csv")}
    assert set(rows) == {s.key for s in discover([library]).scenes}
    assert report.done == 6 and report.reused == 0 and not report.interrupted
    for r in rows.values():
        validate(r, "batch_index", source=r["path"])
    ok = {k for k, r in rows.items() if r["status"] == "ok"}
    assert ok == {"duo/duo.toml", "jumps/jump.bvh", "walks/walk.bvh"}
    for k in ok:
        r = rows[k]
        doc = json.loads((out / r["json"]).read_text())
        validate(doc, "snapshot", source=k)
        assert (r["frame"], r["n_frames"], r["fps"]) == (doc["frame"], doc["n_frames"], doc["fps"])
        assert [r["view_x"], r["view_y"], r["view_z"]] == pytest.approx(doc["view"], abs=1e-6)
        assert (out / r["thumb"]).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert (out / r["sheet"]).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert r["t_total_s"] > 0 and r["error"] is None
    assert rows["duo/duo.toml"]["characters"] == 2
    errors = {k: r["error"] for k, r in rows.items() if r["status"] == "error"}
    assert re.search(r"jumps/truncated\.bvh:\d+: .*truncated", errors["jumps/truncated.bvh"])
    assert errors["notes.bvh"].startswith("notes.bvh:")
    # a GLB header with no JSON chunk: the glTF reader's one line, named by the scene
    assert re.fullmatch(
        r".*model\.glb: not a readable glTF/GLB file \(a damaged GLB container\)",
        errors["model.glb"],
    ), errors["model.glb"]
    assert all("\n" not in e and str(library) not in e for e in errors.values())
    assert not any(rows[k][c] for k in errors for c in ("json", "thumb", "sheet"))
    assert (out / "index.html").is_file()
    assert not list(out.rglob(".*.tmp"))


def test_the_json_is_what_select_prints(local_run, library):
    """The batch's JSON equals `snapshot select --json` with the same options, apart
    from timings."""
    out, _ = local_run
    r = subprocess.run(
        [SNAPSHOT, "select", str(library / "jumps" / "jump.bvh"), "--json", "--no-baselines"],
        capture_output=True,
        text=True,
        check=True,
    )
    cli_doc = json.loads(r.stdout)
    batch_doc = json.loads((out / "scenes" / "jumps" / "jump.bvh.json").read_text())
    for d in (cli_doc, batch_doc):
        d.pop("timings_s")
    assert batch_doc == cli_doc


def test_a_rerun_does_no_work_and_an_edit_redoes_one_scene(local_run, library, tmp_path):
    """Second run: nothing processed, the same index; an edited file and only it is
    redone; --force redoes everything."""
    src, _ = local_run
    out = tmp_path / "out"
    shutil.copytree(src, out)
    lib = tmp_path / "lib"
    shutil.copytree(library, lib)
    scenes = discover([lib]).scenes
    first = read_index(out / "index.csv")
    again = run_batch(scenes, out, FAST)
    assert (again.done, again.reused) == (0, len(first))
    assert read_index(out / "index.csv") == first
    write_bvh(synth.humanoid_document("walk", seconds=1.6), lib / "walks" / "walk.bvh")
    edited = run_batch(discover([lib]).scenes, out, FAST)
    assert edited.done == 1 and edited.rows[-1]["path"] == "walks/walk.bvh"
    assert sum(r["status"] == "ok" for r in edited.rows) == 3
    # other options: every scene is to be redone (a thumbnail size is part of them)
    bigger = BatchOptions(**{**FAST.__dict__, "size": (200, 220)})
    tasks, kept = plan_batch(scenes, out, bigger)
    assert (len(tasks), kept) == (len(scenes), [])
    # a deleted output makes its scene run again
    thumb = out / "scenes" / "jumps" / "jump.bvh.png"
    thumb.unlink()
    redo = run_batch(discover([lib]).scenes, out, FAST)
    assert redo.done == 1 and thumb.is_file()


@pytest.mark.slow
def test_worker_processes_give_the_same_index_with_one_renderer_each(
    local_run, library, tmp_path, monkeypatch
):
    """--jobs 2: the index equals the in-process run apart from timings, and each
    worker process made exactly one GL renderer for all its scenes. The caller's main
    module is not run in the workers (here one that would fail, as a Streamlit page
    left as __main__ by an earlier test once did)."""
    import types

    script = tmp_path / "page.py"
    script.write_text("raise SystemExit('the caller's main module ran in a worker')\n")
    fake_main = types.ModuleType("__main__")
    fake_main.__file__ = str(script)
    monkeypatch.setitem(sys.modules, "__main__", fake_main)
    src, _ = local_run
    died = []
    report = run_batch(subset(library), tmp_path / "out", FAST, jobs=2, notify=died.append)
    assert died == []  # no worker ran the caller's main module and died of it
    assert strip_timings(read_index(tmp_path / "out" / "index.csv")) == strip_timings(
        read_index(src / "index.csv"), SUBSET
    )
    pids = {w["pid"] for w in report.workers}
    assert 1 <= len(pids) <= 2 and os.getpid() not in pids
    per_pid = {p: {w["renderer"] for w in report.workers if w["pid"] == p} for p in pids}
    assert all(len(ids) == 1 and None not in ids for ids in per_pid.values()), per_pid


def _dask_cluster(tmp_path, n_workers=2):
    """A local Dask scheduler and ``n_workers`` workers as real processes."""
    dask = shutil.which("dask", path=str(Path(sys.executable).parent))
    need(dask is not None, "no dask CLI in the venv")
    sched_file = tmp_path / "scheduler.json"
    logs = [open(tmp_path / f"dask{i}.log", "w") for i in range(n_workers + 1)]  # noqa: SIM115
    procs = [
        subprocess.Popen(
            [
                dask,
                "scheduler",
                "--host",
                "127.0.0.1",
                "--port",
                "0",
                "--no-dashboard",
                "--scheduler-file",
                str(sched_file),
            ],
            stdout=logs[0],
            stderr=subprocess.STDOUT,
        )
    ]
    deadline = time.monotonic() + 60
    while not sched_file.exists() and time.monotonic() < deadline:
        time.sleep(0.2)
    address = json.loads(sched_file.read_text())["address"]
    for i in range(n_workers):
        procs.append(
            subprocess.Popen(
                [
                    dask,
                    "worker",
                    address,
                    "--nthreads",
                    "1",
                    "--no-nanny",
                    "--no-dashboard",
                    "--host",
                    "127.0.0.1",
                    "--name",
                    f"w{i}",
                    "--memory-limit",
                    "0",
                    "--local-directory",
                    str(tmp_path / f"w{i}"),
                ],
                stdout=logs[i + 1],
                stderr=subprocess.STDOUT,
            )
        )
    return address, procs, logs


@pytest.mark.slow
def test_a_dask_cluster_gives_the_same_index(local_run, library, tmp_path):
    """Through a local Dask scheduler and two worker processes, the index equals the
    local run's apart from timings."""
    pytest.importorskip("distributed")
    from distributed import Client

    src, _ = local_run
    address, procs, logs = _dask_cluster(tmp_path)
    try:
        with Client(address, timeout="60s") as c:
            c.wait_for_workers(2, timeout=120)
        report = run_batch(subset(library), tmp_path / "out", FAST, scheduler=address)
        assert strip_timings(read_index(tmp_path / "out" / "index.csv")) == strip_timings(
            read_index(src / "index.csv"), SUBSET
        )
        assert report.done == len(SUBSET)
        assert os.getpid() not in {w["pid"] for w in report.workers}
        # the local pool's set-up reached the Dask workers: one Mesa rasteriser thread
        assert {w["lp_threads"] for w in report.workers} == {"1"}
    finally:
        # workers first, each gone before the scheduler is stopped: a worker told to
        # stop while its scheduler goes too can hang in its close (distributed's rpc
        # close is cancelled) until it is killed, 20 s later
        for p in reversed(procs):
            p.terminate()
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()
        for f in logs:
            f.close()


@pytest.mark.slow
def test_cli_runs_resumes_and_refuses_bad_input(library, tmp_path):
    """The command: a summary line, exit 0 with scene errors in the index; a re-run
    does nothing; a missing SOURCE or an output that is a file is one line, exit 2."""
    lib = tmp_path / "lib"
    lib.mkdir()
    shutil.copy(library / "walks" / "walk.bvh", lib / "walk.bvh")
    shutil.copy(library / "notes.bvh", lib / "notes.bvh")
    out = tmp_path / "out"
    r = subprocess.run(
        [SNAPSHOT, "batch", str(lib), "-o", str(out), *FAST_ARGS], capture_output=True, text=True
    )
    assert r.returncode == 0, r.stderr
    assert "2 scenes: 2 processed" in r.stdout and "1 with errors" in r.stdout
    # the re-run has nothing to do and loads none of the heavy libraries (that is what
    # keeps a no-work run of a whole library under two seconds)
    heavy = ("trimesh", "pyrender", "OpenGL", "scipy", "snapcore.pipeline")
    r = subprocess.run(
        [
            sys.executable,
            "-c",
            "import sys; from snapcore.cli.main import main; code = main(sys.argv[1:]);"
            f"print(sorted(m for m in {heavy!r} if m in sys.modules)); sys.exit(code)",
            "batch",
            str(lib),
            "-o",
            str(out),
            *FAST_ARGS,
        ],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, r.stderr
    assert "0 processed" in r.stdout and "2 already done" in r.stdout
    assert r.stdout.splitlines()[-1] == "[]"
    for args, msg in (
        (["nowhere"], "no such file or folder"),
        ([str(lib), "-o", str(lib / "walk.bvh")], "is a file"),
        ([str(lib), "--scheduler", "localhost"], "tcp://HOST:8786"),
    ):
        argv = args if "-o" in args else [*args, "-o", str(tmp_path / "o2")]
        r = subprocess.run([SNAPSHOT, "batch", *argv], capture_output=True, text=True, cwd=tmp_path)
        assert r.returncode == 2 and msg in r.stderr, r.stderr
        assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr


@pytest.mark.slow
def test_ctrl_c_stops_cleanly_with_the_index_of_what_finished(tmp_path):
    """Ctrl-C (SIGINT to the whole process group, as a terminal sends it) while worker
    processes run: exit 130, one line, no traceback, the index lists exactly the scenes
    whose outputs are complete, and no temporary file is left."""
    lib = tmp_path / "lib"
    lib.mkdir()
    for i in range(5):
        write_bvh(synth.humanoid_document("walk", seconds=1.5, seed=i), lib / f"w{i}.bvh")
    out = tmp_path / "out"
    proc = subprocess.Popen(
        [SNAPSHOT, "batch", str(lib), "-o", str(out), "--jobs", "2", *FAST_ARGS],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    deadline = time.monotonic() + 240
    # a scene's sheet is its last output
    while not list((out / "scenes").glob("*.sheet.png")) and time.monotonic() < deadline:
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.1)
    os.killpg(proc.pid, signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 130, (stdout, stderr)
    assert "Traceback" not in stderr and "KeyboardInterrupt" not in stderr
    assert "interrupted:" in stderr
    rows = read_index(out / "index.csv")
    assert 1 <= len(rows) < 5
    assert all((out / r["json"]).is_file() and (out / r["thumb"]).is_file() for r in rows)
    assert not list(out.rglob(".*.tmp"))
    # and the next run finishes the rest
    report = run_batch(discover([lib]).scenes, out, FAST)
    assert report.reused == len(rows) and report.done == 5 - len(rows)


def test_a_damaged_copy_of_the_real_folder(motions_dir, tmp_path):
    """Real clips with a truncated BVH and a non-motion file dropped in: both are rows
    with their error, every other scene completes."""
    lib = tmp_path / "motions"
    for rel in ("basketball/06_15_jumpshot_excerpt.bvh", "walk_run/dataset-2_run_normal_001.bvh"):
        need((motions_dir / rel).exists(), f"{rel} missing")
        (lib / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(motions_dir / rel, lib / rel)
    text = (motions_dir / "walk_run" / "02_03.bvh").read_text()
    (lib / "walk_run" / "02_03_truncated.bvh").write_text(text[: len(text) // 2])
    shutil.copy(
        REPO / "docs" / "images" / sorted(os.listdir(REPO / "docs" / "images"))[0],
        lib / "walk_run" / "picture.bvh",
    )
    report = run_batch(discover([lib]).scenes, tmp_path / "out", FAST)
    status = {r["path"]: (r["status"], r["error"]) for r in report.rows}
    assert status["basketball/06_15_jumpshot_excerpt.bvh"] == ("ok", None)
    assert status["walk_run/dataset-2_run_normal_001.bvh"] == ("ok", None)
    assert status["walk_run/02_03_truncated.bvh"][0] == "error"
    assert "truncated" in status["walk_run/02_03_truncated.bvh"][1]
    assert status["walk_run/picture.bvh"] == (
        "error",
        "walk_run/picture.bvh: not a text file (contains NUL bytes)",
    )


def test_a_subset_run_keeps_the_other_rows_and_prune_drops_them(local_run, library, tmp_path):
    """A run over one folder of the library updates that folder's rows and keeps the
    rest of the index (and their outputs); --prune makes the index exactly this run's
    scenes and deletes the outputs of the rows it drops."""
    src, _ = local_run
    out = tmp_path / "out"
    shutil.copytree(src, out)
    first = read_index(out / "index.csv")
    walks = discover([library / "walks"]).scenes  # keys relative to that SOURCE...
    assert [s.key for s in walks] == ["walk.bvh"]
    walks = [s for s in discover([library]).scenes if s.folder == "walks"]  # ...or the root
    again = run_batch(walks, out, FAST)
    assert (again.done, again.reused) == (0, 1)
    assert strip_timings(read_index(out / "index.csv")) == strip_timings(first)
    pruned = run_batch(walks, out, FAST, prune=True)
    assert [r["path"] for r in pruned.rows] == ["walks/walk.bvh"]
    assert [r["path"] for r in read_index(out / "index.csv")] == ["walks/walk.bvh"]
    assert not (out / "scenes" / "jumps" / "jump.bvh.png").exists()
    assert not (out / "scenes" / "duo" / "duo.toml.json").exists()
    assert (out / "scenes" / "walks" / "walk.bvh.png").is_file()


def test_the_body_option_reaches_the_thumbnail(library):
    """--body mannequin draws capsules: the thumbnail is the one `render_still` gives
    with ``body="mannequin"``, and not the human body's; the scene is not told."""
    from PIL import Image

    from snapcore.motion.load import load_scene
    from snapcore.render.renderer import render_still

    walk = next(s for s in discover([library]).scenes if s.key == "walks/walk.bvh")
    opts = {
        b: BatchOptions(**{**FAST.__dict__, "sheet": False, "body": b})
        for b in ("mannequin", "human")
    }
    assert opts["mannequin"].key() != opts["human"].key()
    thumbs = {}
    for b, o in opts.items():
        task = SceneTask(scene=walk, options=o, content_hash="0" * 64, options_hash=o.key())
        result = run_scene(task)
        assert result.row["status"] == "ok", result.row["error"]
        thumbs[b] = np.asarray(Image.open(io.BytesIO(result.outputs["thumb"])).convert("RGB"))
    doc = json.loads(
        run_scene(
            SceneTask(
                scene=walk, options=opts["mannequin"], content_hash="0" * 64, options_hash="0" * 64
            )
        ).outputs["json"]
    )
    scene = load_scene([walk.path])
    expected = render_still(
        scene,
        doc["frame"],
        np.asarray(doc["view"]),
        size=FAST.size,
        body="mannequin",
    )
    assert np.abs(thumbs["mannequin"].astype(int) - expected[..., :3]).max() <= 1
    assert np.abs(thumbs["human"].astype(int) - thumbs["mannequin"]).mean() > 1.0
