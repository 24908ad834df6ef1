"""Running a batch: what to do, who does it, and writing what comes back.

:func:`run_batch` decides which scenes need work (a scene whose content hash and
options hash match a finished row of the previous index is skipped, its row kept),
hands the rest to an executor and writes each result as it arrives: the scene's
outputs under ``OUT/scenes/``, the index ``OUT/index.csv`` (rewritten every few
seconds, so even a killed run keeps most of its progress) and, at the end, the gallery
``OUT/index.html``.

Executors, all running :func:`snapcore.batch.task.run_scene`:

- ``jobs=1``: in this process (no start-up cost; the renderer lives on this thread);
- ``jobs=N``: N worker processes (spawned: a fresh interpreter has no inherited GL or
  BLAS state), each with one GL renderer made by its initializer;
- ``scheduler="tcp://host:8786"``: an existing Dask distributed cluster, through a
  ``distributed.Client``; workers need the library at the same path.

Ctrl-C stops the executor, writes the index of the scenes that finished and the
gallery, and re-raises :class:`KeyboardInterrupt` as :class:`BatchInterrupted`
carrying the report.
"""

from __future__ import annotations

import signal
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from contextlib import closing, contextmanager
from dataclasses import dataclass, field
from pathlib import Path

from snapcore.batch.discover import BatchError, SceneSource, content_hash
from snapcore.batch.index import (
    COLUMNS,
    INDEX_NAME,
    atomic_write,
    read_index,
    validate_row,
    write_index,
)
from snapcore.batch.task import BatchOptions, SceneResult, SceneTask, error_result, run_scene

__all__ = ["BatchReport", "BatchInterrupted", "plan_batch", "prune_outputs", "run_batch",
           "output_paths",
           "SCENES_DIR", "INDEX_EVERY_S"]

SCENES_DIR = "scenes"
#: Seconds between two rewrites of the index while a batch runs.
INDEX_EVERY_S = 5.0
_SUFFIX = {"json": ".json", "thumb": ".png", "sheet": ".sheet.png"}


@dataclass
class BatchReport:
    """How a batch went.

    Attributes
    ----------
    rows : list of dict
        The index rows, sorted by path (done before and done now).
    done : int
        Scenes processed in this run (successes and errors).
    reused : int
        Scenes of this run skipped because an earlier run had done them with the same
        options (rows of other scenes kept from the index are not counted).
    errors : int
        Rows with status ``error`` (this run or kept).
    elapsed_s : float
        Wall-clock seconds of the processing (not discovery).
    interrupted : bool
        Stopped by Ctrl-C: ``rows`` holds what had finished.
    workers : list of dict
        ``pid``/``renderer`` of the worker behind each result of this run.
    """

    rows: list = field(default_factory=list)
    done: int = 0
    reused: int = 0
    errors: int = 0
    elapsed_s: float = 0.0
    interrupted: bool = False
    workers: list = field(default_factory=list)


class BatchInterrupted(KeyboardInterrupt):
    """Ctrl-C during a batch, after the index of what finished was written."""

    def __init__(self, report: BatchReport):
        super().__init__("batch interrupted")
        self.report = report


class _CtrlC:
    """Ctrl-C that waits while a result is being stored: the scene's outputs and its
    row go in together, so the index written on the way out lists exactly the scenes
    whose outputs are complete. Elsewhere (waiting for workers) it stops at once."""

    def __init__(self):
        self.storing = False
        self.pending = False
        self.previous = None

    def _handler(self, signum, frame):
        if self.storing:
            self.pending = True
        else:
            raise KeyboardInterrupt

    def __enter__(self):
        # signal handlers can only be set from the main thread; elsewhere Ctrl-C is not ours
        if threading.current_thread() is threading.main_thread():
            self.previous = signal.signal(signal.SIGINT, self._handler)
        return self

    def __exit__(self, *exc):
        if self.previous is not None:
            signal.signal(signal.SIGINT, self.previous)

    @contextmanager
    def storing_result(self):
        self.storing = True
        try:
            yield
        finally:
            self.storing = False
        if self.pending:
            raise KeyboardInterrupt


def output_paths(key: str) -> dict[str, str]:
    """Output files of a scene, relative to OUT: ``scenes/<key>.json``, ``.png``,
    ``.sheet.png`` (the key keeps its suffix, so ``a.bvh`` and ``a.glb`` do not clash)."""
    return {what: f"{SCENES_DIR}/{key}{suffix}" for what, suffix in _SUFFIX.items()}


def _previous(out: Path) -> dict[str, dict]:
    """The previous index by path (none, or an unreadable one: everything is redone)."""
    path = out / INDEX_NAME
    if not path.exists():
        return {}
    try:
        return {r["path"]: r for r in read_index(path)}
    except (OSError, ValueError) as err:
        import warnings

        warnings.warn(f"{path}: ignored, every scene is redone ({err})", stacklevel=3)
        return {}


def plan_batch(scenes: Iterable[SceneSource], out, options: BatchOptions, *,
               force: bool = False, retry_errors: bool = False,
               prune: bool = False) -> tuple[list[SceneTask], list[dict]]:
    """Split scenes into tasks to run and rows to keep from the previous index.

    A previous row of one of ``scenes`` is kept when its content hash and options hash
    match and it is finished: ``ok`` with its outputs still there, or ``error`` (the same
    file with the same options fails the same way) unless ``retry_errors``. ``force``
    redoes them all.

    Rows of scenes that are not in ``scenes`` are kept too (a run over one folder of a
    library leaves the rest of its index alone), unless ``prune``: then the index
    becomes exactly this run's scenes (see :func:`prune_outputs` for their files).

    Returns
    -------
    tasks : list of SceneTask
    kept : list of dict
    """
    out = Path(out)
    scenes = list(scenes)
    prev = _previous(out)
    keys = {s.key for s in scenes}
    tasks = []
    kept = [] if prune else [r for k, r in prev.items() if k not in keys]
    if force:
        prev = {}
    opt_hash = options.key()
    for s in scenes:
        h = content_hash(s)
        row = prev.get(s.key)
        if row and row["content_hash"] == h and row["options_hash"] == opt_hash:
            outputs = [row[c] for c in ("json", "thumb", "sheet") if row[c]]
            finished = (row["status"] == "ok" and row["json"] and row["thumb"]
                        and all((out / p).is_file() for p in outputs))
            if finished or (row["status"] == "error" and not retry_errors):
                kept.append(row)
                continue
        tasks.append(SceneTask(scene=s, options=options, content_hash=h, options_hash=opt_hash))
    return tasks, kept


def prune_outputs(out, keep: Iterable[str]) -> list[str]:
    """Delete the outputs of the previous index's scenes whose key is not in ``keep``.

    Returns
    -------
    list of str
        The keys whose rows (and files) are gone.
    """
    out = Path(out)
    keep = set(keep)
    gone = sorted(k for k in _previous(out) if k not in keep)
    for key in gone:
        for rel in output_paths(key).values():
            (out / rel).unlink(missing_ok=True)
    return gone


def _store(out: Path, result: SceneResult) -> dict:
    """Write a result's outputs (atomically) and return its complete index row."""
    row = {c: result.row.get(c) for c in COLUMNS}  # every column, as read back from the CSV
    paths = output_paths(row["path"])
    for what, rel in paths.items():
        target = out / rel
        data = result.outputs.get(what)
        if data is None:
            # a scene that fails now, or has no sheet this time, keeps no stale picture
            target.unlink(missing_ok=True)
            row[what] = None
            continue
        target.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(target, data)
        row[what] = rel
    validate_row(row)
    return row


@contextmanager
def _plain_main():
    """Start worker processes without the caller's ``__main__``.

    A spawned child re-runs the parent's main module before it does anything (so that
    functions defined there can be unpickled). The task functions live in snapcore, so
    that is never needed, and it is harmful when the main module is not a script
    guarded by ``if __name__ == "__main__"``: a Streamlit page or a notebook would run
    again in every worker. An empty stand-in during the start avoids that.
    """
    import sys
    import types

    real = sys.modules["__main__"]
    sys.modules["__main__"] = types.ModuleType("__main__")
    try:
        yield
    finally:
        sys.modules["__main__"] = real


def _local(tasks: list[SceneTask], jobs: int) -> Iterator[SceneResult]:
    """Results as they finish, from this process (``jobs=1``) or ``jobs`` processes."""
    from snapcore.batch.task import init_worker

    size = tasks[0].options.size
    if jobs == 1:
        init_worker(size, ignore_sigint=False, threads=None)
        for t in tasks:
            yield run_scene(t)
        return
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor, as_completed

    ex = ProcessPoolExecutor(max_workers=jobs, mp_context=multiprocessing.get_context("spawn"),
                             initializer=init_worker, initargs=(size,))
    with _plain_main():  # every worker is started by the first submit
        futures = {ex.submit(run_scene, t): t for t in tasks}
    try:
        for f in as_completed(futures):
            try:
                yield f.result()
            except Exception as err:  # the worker died (BrokenProcessPool): record it
                yield error_result(futures[f], err)
    finally:
        for f in futures:
            f.cancel()
        # scenes still running are abandoned: their outputs only ever reach disk
        # through this process, so stopping a worker leaves no half-written file
        for p in list((getattr(ex, "_processes", None) or {}).values()):
            p.terminate()
        ex.shutdown(wait=True, cancel_futures=True)


def _dask(tasks: list[SceneTask], scheduler: str) -> Iterator[SceneResult]:
    """Results as they finish, from the Dask cluster at ``scheduler``."""
    try:
        from distributed import Client, as_completed
    except ImportError as err:
        raise BatchError(f"--scheduler needs dask[distributed] ({err})") from err
    try:
        client = Client(scheduler, timeout="20s")
    except (OSError, TimeoutError) as err:
        raise BatchError(f"cannot reach the Dask scheduler at {scheduler} ({err})") from err
    futures = []
    try:
        futures = client.map(run_scene, tasks, pure=False)
        by_key = {f.key: t for f, t in zip(futures, tasks)}
        for f in as_completed(futures):
            try:
                yield f.result()
            except Exception as err:  # a worker lost, a task that could not run
                yield error_result(by_key[f.key], err)
    finally:
        if futures:
            client.cancel(futures)
        client.close()


def _executor(tasks, jobs, scheduler) -> Iterator[SceneResult]:
    """The results of ``tasks`` from the chosen executor (none started for no task)."""
    if tasks:
        yield from _dask(tasks, scheduler) if scheduler else _local(tasks, jobs)


def run_batch(scenes: list[SceneSource], out, options: BatchOptions, *, jobs: int = 1,
              scheduler: str | None = None, force: bool = False, retry_errors: bool = False,
              prune: bool = False, progress: Callable[[int], Callable[[dict], None]] | None = None,
              title: str = "Action Snapshot gallery") -> BatchReport:
    """Process a library's scenes into ``out``: outputs, index and gallery.

    Parameters
    ----------
    scenes : list of SceneSource
        From :func:`snapcore.batch.discover.discover`.
    out : path-like
        Output folder (created).
    options : BatchOptions
    jobs : int
        Worker processes on this machine (1: in this process).
    scheduler : str, optional
        Address of a Dask distributed scheduler; overrides ``jobs``.
    force : bool
        Redo every scene.
    retry_errors : bool
        Redo scenes that failed before (e.g. after installing a reader).
    prune : bool
        Drop the rows (and outputs) of earlier scenes that are not among ``scenes``
        (default: keep them, so a run over part of a library updates only that part).
    progress : callable, optional
        ``progress(n_tasks)`` returns a callback called with each finished row.
    title : str
        The gallery's title.

    Returns
    -------
    BatchReport

    Raises
    ------
    BatchInterrupted
        On Ctrl-C, after writing the index of what finished and the gallery.
    BatchError
        The Dask scheduler cannot be reached.
    """
    from snapcore.batch.gallery import write_gallery

    if jobs < 1:
        raise ValueError(f"jobs must be at least 1, got {jobs}")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    if prune:
        prune_outputs(out, (s.key for s in scenes))
    tasks, kept = plan_batch(scenes, out, options, force=force, retry_errors=retry_errors,
                             prune=prune)
    keys = {s.key for s in scenes}
    report = BatchReport(rows=list(kept), reused=sum(r["path"] in keys for r in kept))
    index = out / INDEX_NAME
    if prune:
        write_index(index, report.rows)  # no row left behind whose outputs are gone
    tick = progress(len(tasks)) if progress else None
    t0 = last = time.perf_counter()

    def finish():
        report.rows.sort(key=lambda r: r["path"])
        report.errors = sum(r["status"] == "error" for r in report.rows)
        report.elapsed_s = time.perf_counter() - t0
        write_index(index, report.rows)
        write_gallery(out, report.rows, title=title, size=options.size)

    try:
        with _CtrlC() as ctrl_c, closing(_executor(tasks, jobs, scheduler)) as results:
            # closing(): on Ctrl-C the executor's clean-up (stop the workers, cancel
            # what is queued) runs now, not whenever the generator is collected
            for result in results:
                with ctrl_c.storing_result():
                    row = _store(out, result)
                    report.rows.append(row)
                    report.workers.append(result.worker)
                    report.done += 1
                if tick:
                    tick(row)
                if time.perf_counter() - last > INDEX_EVERY_S:
                    write_index(index, report.rows)
                    last = time.perf_counter()
    except KeyboardInterrupt:
        report.interrupted = True
        finish()
        raise BatchInterrupted(report) from None
    finish()
    return report
