"""Running a batch: what to do, who does it, and writing what comes back.

:func:`run_batch` decides which scenes need work (a scene whose content hash and
options hash match a finished row of the previous index is skipped, its row kept),
hands the rest to an executor and writes each result as it arrives: the scene's
outputs under ``OUT/scenes/``, the index ``OUT/index.csv`` (rewritten every few
seconds, so even a killed run keeps most of its progress) and, at the end, the gallery
``OUT/index.html``.

Executors, all running :func:`snapcore.batch.task.run_scene`:

- ``jobs=1``: in this process (no start-up cost; the renderer lives on this thread;
  one BLAS thread while the scenes run, the caller's limits back afterwards);
- ``jobs=N``: N worker processes (spawned: a fresh interpreter has no inherited GL or
  BLAS state), each with one GL renderer made by its initializer;
- ``scheduler="tcp://host:8786"``: an existing Dask distributed cluster, through a
  ``distributed.Client``; workers need the library at the same path.

Ctrl-C stops the executor, writes the index of the scenes that finished and the
gallery, and re-raises :class:`KeyboardInterrupt` as :class:`BatchInterrupted`
carrying the report.
"""

from __future__ import annotations

import json
import os
import signal
import threading
import time
from collections.abc import Callable, Generator, Iterable, Iterator
from concurrent.futures.process import BrokenProcessPool
from contextlib import closing, contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path

from snapcore.batch.choices import choices_for
from snapcore.batch.discover import BatchError, SceneSource, content_hash
from snapcore.batch.index import (
    COLUMNS,
    INDEX_NAME,
    PARQUET_NAME,
    atomic_write,
    read_index,
    validate_row,
    write_index,
    write_parquet,
)
from snapcore.batch.task import (
    BatchOptions,
    SceneResult,
    SceneTask,
    error_result,
    run_scene,
    worker_env,
)

__all__ = [
    "BatchReport",
    "BatchInterrupted",
    "plan_batch",
    "prune_outputs",
    "run_batch",
    "output_paths",
    "library_root",
    "LIBRARY_NAME",
    "SCENES_DIR",
    "INDEX_EVERY_S",
]

SCENES_DIR = "scenes"
#: ``OUT/library.json``: the library root the index's keys are relative to.
LIBRARY_NAME = "library.json"
#: Seconds between two rewrites of the index while a batch runs.
INDEX_EVERY_S = 5.0
_SUFFIX = {"json": ".json", "thumb": ".png", "sheet": ".sheet.png", "preview": ".preview.png"}


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
        Scenes of this run (processed or skipped as done) with status ``error``.
    errors_elsewhere : int
        Rows with status ``error`` kept from earlier runs of other scenes.
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
    errors_elsewhere: int = 0
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
        # signal handlers can only be set from the main thread; elsewhere Ctrl-C is not ours.
        # SIGTERM (kill, a job scheduler's stop) is handled as Ctrl-C: the index of what
        # finished is written and the workers are stopped before this process goes.
        if threading.current_thread() is threading.main_thread():
            self.previous = {
                sig: signal.signal(sig, self._handler) for sig in (signal.SIGINT, signal.SIGTERM)
            }
        return self

    def __exit__(self, *exc):
        for sig, handler in (self.previous or {}).items():
            signal.signal(sig, handler)

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
    ``.sheet.png``, ``.preview.png`` (the key keeps its suffix, so ``a.bvh`` and
    ``a.glb`` do not clash)."""
    return {what: f"{SCENES_DIR}/{key}{suffix}" for what, suffix in _SUFFIX.items()}


def library_root(out, sources) -> Path | None:
    """The folder the scenes of a run into ``out`` are keyed relative to.

    The root recorded in ``OUT/library.json`` by an earlier run, when every SOURCE
    lies under it: a run over ``LIB/walk_run`` into the output of a run over ``LIB``
    then keys its scenes ``walk_run/...`` and updates their rows instead of adding
    copies beside them. With no recorded root (a new output, or one from before this
    file existed): a folder above the single SOURCE folder under which that folder's
    files have the keys of rows already in the index, else that folder itself. None
    when the SOURCEs are not one folder (globs, lists, files: keyed as they are).
    """
    out = Path(out)
    dirs = [Path(s).expanduser().resolve() for s in sources]
    try:
        doc = json.loads((out / LIBRARY_NAME).read_text(encoding="utf-8"))
        recorded = Path(doc["root"])
    except (OSError, ValueError, KeyError, TypeError):
        recorded = None
    if recorded is not None and all(d.is_dir() and d.is_relative_to(recorded) for d in dirs):
        return recorded
    if len(dirs) != 1 or not dirs[0].is_dir():
        return None
    here = dirs[0]
    prev = _previous(out)
    if prev:
        for n, child in enumerate(sorted(here.rglob("*"))):
            if n > 500:
                break
            if child.is_file() and not any(
                p.startswith(".") for p in child.relative_to(here).parts
            ):
                for above in (here, *here.parents):
                    if child.relative_to(above).as_posix() in prev:
                        return above
    return here


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


def plan_batch(
    scenes: Iterable[SceneSource],
    out,
    options: BatchOptions,
    *,
    force: bool = False,
    retry_errors: bool = False,
    prune: bool = False,
) -> tuple[list[SceneTask], list[dict]]:
    """Split scenes into tasks to run and rows to keep from the previous index.

    A previous row of one of ``scenes`` is kept when its content hash and options hash
    match and it is finished: ``ok`` with its outputs still there, or ``error`` (the same
    file with the same options fails the same way) unless ``retry_errors``. ``force``
    redoes them all. A finished row that lacks only a picture (a thumbnail choice made
    since, a sheet or preview asked for now) becomes a task that renders just that.

    The thumbnail choices (:func:`~snapcore.batch.choices.choices_for`) come from the
    previous index and ``OUT/thumb-choices.csv``, with ``force`` too.

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
    choices = choices_for(out, prev.values())
    keys = {s.key for s in scenes}
    tasks = []
    kept = [] if prune else [r for k, r in prev.items() if k not in keys]
    if force:
        prev = {}
    opt_hash = options.key()
    for s in scenes:
        h = content_hash(s)
        row = prev.get(s.key)
        task = SceneTask(
            scene=s,
            options=options,
            content_hash=h,
            options_hash=opt_hash,
            thumb_choice=choices.get(s.key),
        )
        if row and row["content_hash"] == h and row["options_hash"] == opt_hash:
            if row["status"] == "error" and not retry_errors:
                kept.append(row)
                continue
            todo = _missing(out, row, task)
            if todo == ():
                kept.append(row)
                continue
            if todo is not None:
                captions = _captions(out, row) if "sheet" in todo else ()
                if captions is not None:
                    task = replace(task, reuse=row, render=todo, captions=captions)
        tasks.append(task)
    return tasks, kept


def _missing(out: Path, row: dict, task: SceneTask) -> tuple[str, ...] | None:
    """The pictures a finished ``ok`` row lacks for ``task`` (``()``: none), or None
    when the row cannot be reused (not ``ok``, its document or thumbnail gone)."""
    if row["status"] != "ok" or not row["json"] or not (out / row["json"]).is_file():
        return None
    todo = []
    if row["thumb_choice"] != task.thumb_choice or not (
        row["thumb"] and (out / row["thumb"]).is_file()
    ):
        todo.append("thumb")
    for extra in task.options.extras():
        if not row[extra] or not (out / row[extra]).is_file():
            todo.append(extra)
    return tuple(todo)


def _captions(out: Path, row: dict) -> tuple[str, ...] | None:
    """The sheet captions of a row's top poses, from its snapshot document (None: the
    document does not give them, so the scene is redone)."""
    from snapcore.select.pose_selection import score_caption

    try:
        ps = json.loads((out / row["json"]).read_text(encoding="utf-8"))["pose_scores"]
        return tuple(
            score_caption(ps["method"], ps["unit"], ps["total"][f - ps["first_frame"]])
            for f in row["top_frames"]
        )
    except (OSError, ValueError, KeyError, IndexError, TypeError):
        return None


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
    key = row["path"]
    if not isinstance(key, str):
        raise BatchError(f"internal: a scene result has no path key (got {key!r})")
    paths = output_paths(key)
    for what, rel in paths.items():
        target = out / rel
        if what in result.kept:  # a partial re-render: the earlier file stays
            row[what] = rel if target.is_file() else None
            continue
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


@contextmanager
def _environ(values: dict[str, str]):
    """This process's environment with ``values`` set, for processes started meanwhile.

    A spawned worker starts with its parent's environment and imports NumPy and SciPy
    (each with its own OpenBLAS) before its initializer could set anything: their
    thread counts must be in the environment it starts with. The parent's own
    libraries, loaded already, are not affected.
    """
    import os

    before = {k: os.environ.get(k) for k in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for k, v in before.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _local(
    tasks: list[SceneTask], jobs: int, notify: Callable[[str], None]
) -> Iterator[SceneResult]:
    """Results as they finish, from this process (``jobs=1``) or ``jobs`` processes.

    A worker that dies (killed, out of memory, a crash in a native library) breaks a
    ``ProcessPoolExecutor`` and fails every future it holds. So at most ``jobs`` tasks are
    handed out at a time, and when the pool breaks, a new pool is started: the scenes
    that were in flight are run again one at a time (a scene that kills its worker then
    is the culprit and becomes an error row naming that), then the rest go on as before.
    No good scene is recorded as an error because another process died.
    """
    from snapcore.batch.task import init_worker

    size = tasks[0].options.size
    if jobs == 1:
        from threadpoolctl import threadpool_limits

        init_worker(size, ignore_sigint=False, threads=None)
        # one BLAS thread while the scenes run here, as in a worker: a second one only
        # spins on a scene's small products (a glTF character's load took 2.3x the CPU
        # with two); the caller's own limits come back after
        with threadpool_limits(1):
            for t in tasks:
                yield run_scene(t)
        return
    from concurrent.futures import FIRST_COMPLETED, wait

    queue = _largest_last(tasks)  # pop() from the end: the largest scenes first
    suspects: list[SceneTask] = []  # in flight when a worker died: re-run one by one
    pool = _Pool(jobs, size)
    try:
        while queue or suspects:
            alone = bool(suspects)
            running = {}
            try:
                if alone:
                    t = suspects.pop()
                    running[pool.submit(t)] = t
                while running or (queue and not alone):
                    while not alone and queue and len(running) < jobs:
                        t = queue.pop()
                        running[pool.submit(t, back_to=queue)] = t
                    done, _ = wait(running, return_when=FIRST_COMPLETED)
                    ready, broken = [], None
                    for f in done:
                        try:
                            ready.append(f.result())
                        except BrokenProcessPool as err:  # f stays in running
                            broken = err
                            break
                        del running[f]
                    # the idle workers get their next scenes before this process writes
                    # the finished ones' files (a worker waited for that on every scene)
                    try:
                        while broken is None and not alone and queue and len(running) < jobs:
                            t = queue.pop()
                            running[pool.submit(t, back_to=queue)] = t
                    except BrokenProcessPool as err:
                        broken = err
                    yield from ready
                    if broken is not None:
                        raise broken
                    if alone:
                        break
            except BrokenProcessPool:
                lost = list(running.values())
                pool.close()  # joins every worker: their exit codes are known after it
                code = pool.exit_codes()
                if alone:
                    yield error_result(
                        lost[0],
                        RuntimeError(
                            f"the worker process died while running this scene alone ({code})"
                        ),
                    )
                else:
                    notify(
                        f"a worker process died ({code}); {len(lost)} scene(s) it may "
                        "have been running are run again, one at a time"
                    )
                    suspects = list(reversed(lost))
                pool = _Pool(jobs, size)
    finally:
        pool.close()


def _largest_last(tasks: list[SceneTask]) -> list[SceneTask]:
    """The tasks from the smallest source files to the largest (a stable sort: equal
    sizes keep their order, reversed).

    Workers popping from the end take the largest scenes first, so the run ends on
    small ones: a large clip handed out last (a glTF character, ~1 s against ~0.13 s
    for a typical clip) kept the other worker idle until it finished. The files' bytes
    stand for a scene's cost (frames x channels for BVH; mesh and keys for glTF)."""

    def size(t: SceneTask) -> int:
        total = 0
        for path in (t.scene.path, *t.scene.members):
            try:
                total += os.stat(path).st_size
            except OSError:  # missing or unreadable: its error row comes soon, first
                total += 1 << 40
        return total

    return sorted(reversed(tasks), key=size)


class _Pool:
    """A ``ProcessPoolExecutor`` of spawned workers, each set up by
    :func:`~snapcore.batch.task.init_worker` (one GL renderer, one thread, and a watch
    on this process so that no worker outlives it)."""

    def __init__(self, jobs: int, size):
        import multiprocessing
        import os
        from concurrent.futures import ProcessPoolExecutor

        from snapcore.batch.task import init_worker

        self.ex = ProcessPoolExecutor(
            max_workers=jobs,
            mp_context=multiprocessing.get_context("spawn"),
            initializer=init_worker,
            initargs=(size, True, 1, os.getpid()),
        )
        self.procs: dict = {}

    def submit(self, task: SceneTask, back_to: list | None = None):
        """The future of ``task``; a pool already broken puts it back on ``back_to``."""
        try:
            # every submit may start a worker (the pool spawns them one per submit, up to
            # max_workers, while none is idle), so each is made without __main__
            with _plain_main(), _environ(worker_env(1)):
                future = self.ex.submit(run_scene, task)
            # kept: a broken executor forgets its processes, and how they ended
            self.procs.update(getattr(self.ex, "_processes", None) or {})
            return future
        except BrokenProcessPool:
            if back_to is not None:
                back_to.append(task)
            raise

    def exit_codes(self) -> str:
        """How the pool's dead workers ended, e.g. ``killed by signal 9``."""
        for p in self.procs.values():
            if p.exitcode is None:
                p.join(timeout=2)
        codes = [p.exitcode for p in self.procs.values() if p.exitcode not in (None, 0)]
        # SIGTERM is what a broken pool sends the workers that were still alive
        codes = [c for c in codes if c != -15] or codes
        if not codes:
            return "exit code unknown"
        return ", ".join(f"killed by signal {-c}" if c < 0 else f"exit code {c}" for c in codes)

    def close(self):
        # scenes still running are abandoned: their outputs only ever reach disk
        # through this process, so stopping a worker leaves no half-written file
        for p in list((getattr(self.ex, "_processes", None) or {}).values()):
            p.terminate()
        self.ex.shutdown(wait=True, cancel_futures=True)


def _dask(
    tasks: list[SceneTask], scheduler: str, notify: Callable[[str], None]
) -> Iterator[SceneResult]:
    """Results as they finish, from the Dask cluster at ``scheduler``.

    Every worker gets the local pool's set-up (one BLAS and one Mesa rasteriser thread,
    see :func:`~snapcore.batch.task.init_worker`) through a worker plugin, also on
    workers that join later. Workers that leave or join are reported through
    ``notify`` as they happen (the scheduler re-runs a lost worker's scenes elsewhere;
    with no worker left the run waits for one).
    """
    try:
        from distributed import Client, as_completed
    except ImportError as err:
        raise BatchError(f"--scheduler needs dask[distributed] ({err})") from err
    from snapcore.batch.dask_setup import DaskWorkerSetup

    try:
        client = Client(scheduler, timeout="20s")
    except (OSError, TimeoutError) as err:
        raise BatchError(f"cannot reach the Dask scheduler at {scheduler} ({err})") from err
    futures = []
    try:
        client.register_plugin(DaskWorkerSetup(tasks[0].options.size), name="snapshot-setup")
        futures = client.map(run_scene, tasks, pure=False)
        by_key = {f.key: t for f, t in zip(futures, tasks)}
        pending = as_completed(futures)
        workers = set(client.scheduler_info()["workers"])
        checked = time.monotonic()
        while not pending.is_empty():
            if not pending.has_ready():
                time.sleep(0.05)
                if time.monotonic() - checked > 2.0:
                    workers = _watch_workers(client, workers, notify)
                    checked = time.monotonic()
                continue
            f = next(pending)
            try:
                yield f.result()
            except Exception as err:  # a task that could not run (KilledWorker...)
                yield error_result(by_key[f.key], err)
    finally:
        if futures:
            client.cancel(futures)
        client.close()


def _watch_workers(client, before: set, notify: Callable[[str], None]) -> set:
    """The cluster's workers now; a message when some left or joined since ``before``."""
    try:
        now = set(client.scheduler_info()["workers"])
    except Exception:  # noqa: BLE001 - a scheduler that does not answer is retried later
        return before
    lost, joined = before - now, now - before
    if lost:
        left = (
            f"{len(now)} left"
            if now
            else "none left: waiting for a worker to join (Ctrl-C stops, keeping what finished)"
        )
        notify(
            f"Dask: {len(lost)} worker(s) lost ({', '.join(sorted(lost))}); their scenes "
            f"run again on the others; {left}"
        )
    if joined:  # also the first to come back after none were left
        notify(f"Dask: {len(joined)} worker(s) joined; {len(now)} now")
    return now


def _executor(tasks, jobs, scheduler, notify) -> Generator[SceneResult, None, None]:
    """The results of ``tasks`` from the chosen executor (none started for no task)."""
    if tasks:
        yield from (_dask(tasks, scheduler, notify) if scheduler else _local(tasks, jobs, notify))


def _warn(message: str) -> None:
    import warnings

    warnings.warn(message, stacklevel=2)


def run_batch(
    scenes: list[SceneSource],
    out,
    options: BatchOptions,
    *,
    jobs: int = 1,
    scheduler: str | None = None,
    force: bool = False,
    retry_errors: bool = False,
    prune: bool = False,
    progress: Callable[[int], Callable[[dict], None]] | None = None,
    title: str = "Action Snapshot gallery",
    root=None,
    notify: Callable[[str], None] | None = None,
    skipped: Iterable[tuple[str, str]] = (),
) -> BatchReport:
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
    root : path-like, optional
        The library root the scenes' keys are relative to (from :func:`library_root`),
        recorded in ``OUT/library.json`` so that later runs over a sub-folder key their
        scenes the same way.
    notify : callable, optional
        Called with a one-line message when the executor loses (or gains) workers
        (default: a warning).
    skipped : iterable of (str, str)
        Files the discovery left out and why (``Discovery.skipped``): the gallery lists
        them beside the run's summary.

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
        raise BatchError(f"jobs must be at least 1, got {jobs}")
    skipped = list(skipped)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    if prune:
        prune_outputs(out, (s.key for s in scenes))
    tasks, kept = plan_batch(
        scenes, out, options, force=force, retry_errors=retry_errors, prune=prune
    )
    keys = {s.key for s in scenes}
    report = BatchReport(rows=list(kept), reused=sum(r["path"] in keys for r in kept))
    index = out / INDEX_NAME
    if prune:
        write_index(index, report.rows)  # no row left behind whose outputs are gone
    tick = progress(len(tasks)) if progress else None
    t0 = last = time.perf_counter()

    def finish():
        report.rows.sort(key=lambda r: r["path"])
        failed = [r["path"] in keys for r in report.rows if r["status"] == "error"]
        report.errors, report.errors_elsewhere = sum(failed), failed.count(False)
        report.elapsed_s = time.perf_counter() - t0
        write_index(index, report.rows)
        write_parquet(out / PARQUET_NAME, report.rows)
        write_gallery(out, report.rows, title=title, size=options.size, skipped=skipped, root=root)
        if root is not None:
            atomic_write(out / LIBRARY_NAME, json.dumps({"root": str(Path(root).resolve())}) + "\n")

    try:
        with (
            _CtrlC() as ctrl_c,
            closing(_executor(tasks, jobs, scheduler, notify or _warn)) as results,
        ):
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
