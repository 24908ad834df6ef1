"""Benchmark cases of issue 41 ("pictures at the speed of the hardware") that the other
case modules do not time: the CLI's start-up as whole processes, and a library's CPU
per scene and its speed-up from a second worker.

The issue's other rows are cases of :mod:`snapcore.bench.cases` and
:mod:`snapcore.bench.cases_bodies` (skinning, video, viewpoint entropy, still, parse+FK,
pose selection, view PMA), with the issue's targets.

The CLI cases start ``snapshot`` as a new process each run (imports, data loading and
the work itself, as a user waits for them) with the bytecode cache warm (the warm-up
run). The library cases are skipped unless ``SNAPSHOT_BENCH_SCALE`` names a number of
scenes (300: the issue's batch); each repeat (``-n``) is a ``--jobs 1`` run followed by a
``--jobs 2`` run, about a minute for 300 scenes on two cores.
"""

from __future__ import annotations

import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from snapcore.bench.registry import BenchContext, Measured, case

#: The clip of the CLI cases (CMU 02_01, a walk and a run: 343 frames).
CLI_CLIP = "walk_run/02_01.bvh"


def _snapshot() -> list[str]:
    """The ``snapshot`` command of this environment."""
    exe = Path(sys.executable).with_name("snapshot")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "snapcore.cli.main"]


def _cli(ctx: BenchContext, *args: str):
    clip = ctx.path(CLI_CLIP)
    if clip is None:
        return None
    out = Path(tempfile.mkdtemp(prefix="snapcore-bench-cli-"))
    cmd = [*_snapshot(), *args]
    cmd = [
        str(clip) if a == "FILE" else str(out / a[4:]) if a.startswith("OUT/") else a for a in cmd
    ]

    def work():
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)

    return work


@case(
    "`snapshot select FILE` (whole process, warm bytecode cache)",
    target_ms=1200.0,
    note=f"{CLI_CLIP}: imports + load + pose + view + the three baseline views",
    max_repeats=5,
)
def _cli_select(ctx: BenchContext):
    return _cli(ctx, "select", "FILE")


@case(
    "`snapshot render FILE` (whole process)",
    target_ms=1000.0,
    note=f"{CLI_CLIP}, 1280x720 PNG of the selected pose and view",
    max_repeats=5,
)
def _cli_render(ctx: BenchContext):
    return _cli(ctx, "render", "FILE", "-o", "OUT/render.png")


def _scale() -> int:
    return int(os.environ.get("SNAPSHOT_BENCH_SCALE", "0") or 0)


def _library_run(ctx: BenchContext, jobs: int, k: int) -> dict:
    """``snapshot batch`` on an ``SNAPSHOT_BENCH_SCALE``-scene generated library (made
    once) with ``jobs`` workers, as a new process: its wall time and the CPU time of it
    and its workers (cached per ``jobs`` and repeat ``k`` in the context: both cases
    read the same runs)."""
    key = f"library-run-{jobs}-{k}"
    if key not in ctx.cache:
        from snapcore.bench.library import make_library

        n = _scale()
        work = Path(os.environ.get("TMPDIR", "/tmp")) / "snapshot-bench-scale"
        lib = make_library(work / f"lib{n}", n, data=ctx.data)
        out = work / f"out{n}-{jobs}"
        if out.exists():
            shutil.rmtree(out)
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        subprocess.run(
            [*_snapshot(), "batch", str(lib), "-o", str(out), "--jobs", str(jobs), "-q"],
            check=True,
            stdout=subprocess.DEVNULL,
        )
        wall = time.perf_counter() - t0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
        ctx.cache[key] = {"scenes": n, "wall_s": wall, "cpu_s": cpu, "load": os.getloadavg()[0]}
        print(
            f"library --jobs {jobs}: {n} scenes, {wall:.1f} s wall, {cpu:.1f} CPU-s "
            f"(load average {os.getloadavg()[0]:.1f})",
            file=sys.stderr,
            flush=True,
        )
    return ctx.cache[key]


def _library_pair(ctx: BenchContext, case: str) -> tuple[dict, dict]:
    """The next repeat of ``case``: a ``--jobs 1`` run and the ``--jobs 2`` run right
    after it (the machine's speed drifts by ~5-10% over minutes, so a ratio is taken
    within one pair; each case's k-th repeat reads the k-th pair)."""
    k = ctx.cache[f"library-repeat-{case}"] = ctx.cache.get(f"library-repeat-{case}", -1) + 1
    return _library_run(ctx, 1, k), _library_run(ctx, 2, k)


@case(
    "library: CPU per scene (SNAPSHOT_BENCH_SCALE-scene batch, --jobs 1)",
    target_ms=150.0,
    note="CPU-ms per scene of `snapshot batch` and its workers (user + system); skipped "
    "unless SNAPSHOT_BENCH_SCALE is set (300: the issue's batch)",
    warmup=False,
)
def _library_cpu(ctx: BenchContext):
    if _scale() <= 0:
        return None

    def work():
        run, _ = _library_pair(ctx, "cpu")
        return Measured(1000.0 * run["cpu_s"] / run["scenes"])

    return work


@case(
    "library: --jobs 2 wall per 1000 ms of --jobs 1 (idle machine)",
    target_ms=1000.0 / 1.8,
    note="the same batch with two workers: 556 = a 1.8x speed-up; skipped unless "
    "SNAPSHOT_BENCH_SCALE is set",
    warmup=False,
)
def _library_speedup(ctx: BenchContext):
    if _scale() <= 0:
        return None

    def work():
        one, two = _library_pair(ctx, "speedup")
        return Measured(1000.0 * two["wall_s"] / one["wall_s"])

    return work
