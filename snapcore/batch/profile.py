"""``snapshot batch --profile``: what a batch buys, measured side by side in one run.

Three ways to snapshot the same scenes, one after the other on the same machine:

1. the batch with ``jobs=1`` (one process, the renderer and Python loaded once);
2. the batch with ``jobs=N`` worker processes (N = 2 by default);
3. a loop of separate commands per scene, as a shell script would do it:
   ``snapshot select PATH --json`` then ``snapshot render PATH --frame F --view V``
   (a fresh interpreter, imports and GL context per call), on the first ``loop``
   scenes that the batch processed without error.

Each batch is forced (nothing reused) into its own folder under ``OUT/profile/``.
"""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from snapcore.batch.index import atomic_write
from snapcore.batch.run import run_batch

__all__ = ["profile_batch", "format_profile"]


def _cpu_s() -> float:
    """CPU seconds of this process and of its finished children (workers, commands)."""
    me, kids = (
        resource.getrusage(resource.RUSAGE_SELF),
        resource.getrusage(resource.RUSAGE_CHILDREN),
    )
    return me.ru_utime + me.ru_stime + kids.ru_utime + kids.ru_stime


def _snapshot_exe() -> str:
    exe = Path(sys.executable).with_name("snapshot")
    return str(exe) if exe.exists() else "snapshot"


def _loop(scenes, options, n: int) -> dict:
    """Seconds per scene for separate `select` + `render` processes on ``n`` scenes."""
    exe = _snapshot_exe()
    common = [] if options.fps is None else ["--fps", repr(options.fps)]
    common += [] if options.scale is None else ["--scale", repr(options.scale)]
    size = f"{options.size[0]}x{options.size[1]}"
    times = []
    cpu0 = _cpu_s()
    with tempfile.TemporaryDirectory() as tmp:
        for s in scenes[:n]:
            t0 = time.perf_counter()
            sel = [exe, "select", s.path, "--json", *common]
            if not options.snapshot.get("baselines", True):
                sel.append("--no-baselines")
            doc = json.loads(subprocess.run(sel, check=True, capture_output=True, text=True).stdout)
            view = ",".join(repr(float(x)) for x in doc["view"])
            subprocess.run(
                [
                    exe,
                    "render",
                    s.path,
                    *common,
                    "--frame",
                    str(doc["frame"]),
                    "--view",
                    view,
                    "--size",
                    size,
                    "-o",
                    str(Path(tmp) / "t.png"),
                ],
                check=True,
                capture_output=True,
            )
            times.append(time.perf_counter() - t0)
    n = len(times)
    return {
        "scenes": n,
        "elapsed_s": sum(times),
        "per_scene_s": sum(times) / n if n else None,
        "cpu_per_scene_s": (_cpu_s() - cpu0) / n if n else None,
    }


def _batch(scenes, out, options, jobs: int, quiet: bool) -> dict:
    if not quiet:
        print(f"profile: batch --jobs {jobs} ...", file=sys.stderr, flush=True)
    cpu0 = _cpu_s()
    r = run_batch(scenes, out, options, jobs=jobs, force=True)
    return {
        "jobs": jobs,
        "scenes": r.done,
        "ok": r.done - r.errors,
        "errors": r.errors,
        "elapsed_s": r.elapsed_s,
        "scenes_per_s": r.done / r.elapsed_s,
        "per_scene_s": r.elapsed_s / r.done,
        "cpu_per_scene_s": (_cpu_s() - cpu0) / r.done,
        "rows": r.rows,
    }


def profile_batch(
    scenes, out, options, *, loop: int = 3, jobs: int = 2, quiet: bool = False
) -> dict:
    """Time the batch at 1 and ``jobs`` processes and a loop of separate commands.

    Parameters
    ----------
    scenes : list of SceneSource
    out : path-like
        The measurement goes to ``out/profile/`` and ``out/profile.json``.
    options : BatchOptions
    loop : int
        Scenes timed with separate commands (0: skip the loop).
    jobs : int
        Worker processes of the parallel batch.
    quiet : bool

    Returns
    -------
    dict
        ``batch`` (one entry per job count: scenes, elapsed_s, scenes_per_s,
        per_scene_s, cpu_per_scene_s: CPU seconds of all processes involved, which a
        busy shared machine does not inflate), ``speedup`` (jobs vs 1), ``loop``
        (scenes, per_scene_s, cpu_per_scene_s),
        ``loop_vs_batch`` (loop's seconds per scene over the 1-process batch's, on the
        same scenes), ``cpus``.
    """
    base = Path(out) / "profile"
    one = _batch(scenes, base / "jobs1", options, 1, quiet)
    many = _batch(scenes, base / f"jobs{jobs}", options, jobs, quiet)
    result = {
        "cpus": os.cpu_count(),
        "scenes": len(scenes),
        "batch": [{k: v for k, v in b.items() if k != "rows"} for b in (one, many)],
        "speedup": one["elapsed_s"] / many["elapsed_s"],
    }
    if loop:
        if not quiet:
            print(
                f"profile: separate select + render calls on {loop} scenes ...",
                file=sys.stderr,
                flush=True,
            )
        ok = {r["path"]: r for r in one["rows"] if r["status"] == "ok"}
        picked = [s for s in scenes if s.key in ok][:loop]
        lp = _loop(picked, options, loop)
        same = sum(ok[s.key]["t_total_s"] for s in picked) / max(len(picked), 1)
        lp["batch_per_scene_s"] = same
        lp["paths"] = [s.key for s in picked]
        result["loop"] = lp
        result["loop_vs_batch"] = lp["per_scene_s"] / same if lp["per_scene_s"] else None
    atomic_write(Path(out) / "profile.json", json.dumps(result, indent=1) + "\n")
    return result


def format_profile(result: dict) -> list[str]:
    """The measurement as a Markdown table (what docs/library.md shows)."""
    lines = [
        f"{result['scenes']} scenes, {result['cpus']} CPUs",
        "",
        "| run | scenes | wall s | scenes/s | wall s per scene | CPU s per scene |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for b in result["batch"]:
        lines.append(
            f"| `batch --jobs {b['jobs']}` | {b['scenes']} | {b['elapsed_s']:.1f} | "
            f"{b['scenes_per_s']:.3f} | {b['per_scene_s']:.2f} | "
            f"{b['cpu_per_scene_s']:.2f} |"
        )
    lp = result.get("loop")
    if lp and lp["scenes"]:
        lines.append(
            f"| loop: `select` + `render` per scene | {lp['scenes']} | "
            f"{lp['elapsed_s']:.1f} | {lp['scenes'] / lp['elapsed_s']:.3f} | "
            f"{lp['per_scene_s']:.2f} | {lp['cpu_per_scene_s']:.2f} |"
        )
        lines += [
            "",
            f"--jobs {result['batch'][1]['jobs']} vs --jobs 1: "
            f"{result['speedup']:.2f}x the throughput",
            f"separate calls vs the batch on the same {lp['scenes']} scenes "
            f"({', '.join(lp['paths'])}): {lp['per_scene_s']:.2f} s vs "
            f"{lp['batch_per_scene_s']:.2f} s per scene = {result['loop_vs_batch']:.1f}x",
        ]
    else:
        lines += [
            "",
            f"--jobs {result['batch'][1]['jobs']} vs --jobs 1: "
            f"{result['speedup']:.2f}x the throughput",
        ]
    return lines
