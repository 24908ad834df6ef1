"""One BLAS thread in every local batch worker (issue 41).

A BLAS reads its thread count when it loads; NumPy and SciPy each bring an OpenBLAS,
loaded by a worker's first scene, after its initializer ran. ``threadpool_limits(1)``
in the initializer (before either was loaded) did nothing: both reported 2 threads on
this 2-core machine and the helper threads took a quarter of each worker's CPU.
"""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from snapcore.batch.discover import SceneSource, discover
from snapcore.batch.run import run_batch
from snapcore.batch.task import BatchOptions, worker_env
from snapcore.motion import synth
from snapcore.motion.bvh import write_bvh

# a machine with one core would give one thread anyway: the test would prove nothing
pytestmark = pytest.mark.skipif((os.cpu_count() or 1) < 2, reason="needs 2+ cores")


def _clean_env() -> dict:
    """This environment without any thread setting (as a user's shell would be)."""
    drop = set(worker_env(1))
    return {k: v for k, v in os.environ.items() if k not in drop}


def test_a_plain_process_has_several_blas_threads():
    """The premise: without a setting, NumPy's and SciPy's OpenBLAS start a thread per
    core, so the checks below can fail."""
    code = (
        "import numpy, scipy.linalg\n"
        "from snapcore.batch.task import blas_threads\n"
        "print(max(blas_threads().values()))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], env=_clean_env(), capture_output=True, text=True, check=True
    )
    assert int(out.stdout) >= 2


def test_init_worker_limits_libraries_loaded_after_it():
    """A process set up by ``init_worker`` (as a Dask worker is) before NumPy and SciPy
    load: every BLAS they bring has one thread."""
    code = (
        "from snapcore.batch.task import init_worker, blas_threads\n"
        "init_worker(ignore_sigint=False, threads=1, renderer=False)\n"
        "import numpy, scipy.linalg, scipy.sparse\n"
        "numpy.ones((50, 50)) @ numpy.ones((50, 50))\n"
        "print(blas_threads())\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], env=_clean_env(), capture_output=True, text=True, check=True
    )
    threads = eval(out.stdout)  # a dict literal printed above
    assert len(threads) >= 2 and set(threads.values()) == {1}, threads


@pytest.mark.slow
def test_every_local_worker_runs_one_blas_thread(tmp_path, monkeypatch):
    """``--jobs 2``: in each worker, after its scenes (NumPy, SciPy, the renderer all
    loaded), every BLAS library reports one thread, and Mesa one rasteriser thread;
    this process's environment is as it was."""
    for var in worker_env(1):
        monkeypatch.delenv(var, raising=False)
    lib = tmp_path / "lib"
    lib.mkdir()
    for name in ("walk", "jump"):  # two short scenes: one for each worker
        write_bvh(synth.humanoid_document(name, seconds=1.0), lib / f"{name}.bvh")
    opts = BatchOptions(size=(96, 108), sheet=False)
    report = run_batch(discover([lib]).scenes, tmp_path / "out", opts, jobs=2)
    assert report.workers and all(os.getpid() != w["pid"] for w in report.workers)
    for w in report.workers:
        assert w["lp_threads"] == "1"
        assert len(w["blas_threads"]) >= 2, w  # NumPy's and SciPy's
        assert set(w["blas_threads"].values()) == {1}, w
    assert not set(worker_env(1)) & set(os.environ)


def test_idle_workers_get_their_next_scenes_before_the_results_are_written(monkeypatch):
    """With ``--jobs N``, the scenes that finished are handed back (and written by the
    caller) only after the idle workers have their next scenes: a worker once waited
    for the main process to write every scene's files before it got another."""
    from concurrent.futures import Future

    import snapcore.batch.run as run

    submitted = []

    class Pool:
        def __init__(self, jobs, size):
            pass

        def submit(self, task, back_to=None):
            submitted.append(task)
            f = Future()
            f.set_result(task)  # finished at once
            return f

        def close(self):
            pass

    class Options:
        size = (64, 72)

    class Task:
        options = Options()
        scene = SceneSource(key="a.bvh", kind="bvh", path=__file__)

    monkeypatch.setattr(run, "_Pool", Pool)
    tasks = [Task() for _ in range(6)]
    seen = []
    for _result in run._local(tasks, 2, print):
        # when a result is handed back, every worker has a scene again (or none is left)
        seen.append(len(submitted))
        assert len(submitted) - len(seen) >= min(2, len(tasks) - len(seen))
    assert sorted(map(id, submitted)) == sorted(map(id, tasks))
    assert len(seen) == 6


def test_scenes_run_in_this_process_with_one_blas_thread_and_the_limits_come_back(tmp_path):
    """``--jobs 1`` runs the scenes in the calling process: one BLAS thread while they
    run, as in a worker (a second spins on small products: a glTF character's load took
    2.3x the CPU), and the caller's own thread counts afterwards. Run in a fresh
    process without thread settings, where OpenBLAS starts a thread per core."""
    lib = tmp_path / "lib"
    lib.mkdir()
    write_bvh(synth.humanoid_document("walk", seconds=0.5), lib / "a.bvh")
    code = (
        "import sys, numpy, scipy.linalg\n"
        "from snapcore.batch.discover import discover\n"
        "from snapcore.batch.run import run_batch\n"
        "from snapcore.batch.task import BatchOptions, blas_threads\n"
        "before = blas_threads()\n"
        "opts = BatchOptions(snapshot={'baselines': False}, size=(64, 72), preview=2)\n"
        f"r = run_batch(discover([{str(lib)!r}]).scenes, {str(tmp_path / 'out')!r}, opts)\n"
        "print(repr((before, r.workers[0]['blas_threads'], blas_threads())))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], env=_clean_env(), capture_output=True, text=True, check=True
    )
    before, during, after = eval(out.stdout.strip().splitlines()[-1])
    assert max(before.values()) >= 2
    assert set(during.values()) == {1}, during
    assert after == before


def test_workers_take_the_largest_scenes_first(tmp_path, monkeypatch):
    """With ``--jobs N`` the scenes are handed out from the largest source files to the
    smallest (a manifest counts its members), equal sizes in the library's order, so a
    run does not end on one worker loading a large clip while the other waits; a file
    that cannot be read goes first (its error row costs nothing)."""
    from concurrent.futures import Future
    from dataclasses import dataclass

    import snapcore.batch.run as run

    submitted: list[str] = []

    class Pool:
        def __init__(self, jobs, size):
            pass

        def submit(self, task, back_to=None):
            submitted.append(task.scene.key)
            f = Future()
            f.set_result(task)
            return f

        def close(self):
            pass

    class Options:
        size = (64, 72)

    @dataclass
    class Task:
        scene: SceneSource
        options = Options()

    def scene(key: str, n_bytes: int, members: tuple[str, ...] = ()) -> Task:
        path = tmp_path / key
        path.write_bytes(b"x" * n_bytes)
        return Task(SceneSource(key=key, kind="bvh", path=str(path), members=members))

    small, big, tie1, tie2 = (
        scene(k, n) for k, n in (("s", 10), ("b", 900), ("t1", 50), ("t2", 50))
    )
    pair = scene("m", 5, members=(big.scene.path, small.scene.path))  # 5 + 900 + 10 bytes
    gone = Task(SceneSource(key="gone", kind="bvh", path=str(tmp_path / "missing.bvh")))
    monkeypatch.setattr(run, "_Pool", Pool)
    done = [r.scene.key for r in run._local([small, tie1, big, gone, tie2, pair], 2, print)]
    assert submitted == ["gone", "m", "b", "t1", "t2", "s"]
    assert sorted(done) == sorted(submitted)
