"""The library-scale benchmark of ``snapshot batch``: thousands of clips in one run.

A generated library (:func:`make_library`): clips from the synthetic motion generator
(:mod:`snapcore.motion.synth`, six motions) with varied seeds, lengths (1-6 s), frame
rates (30/60 fps), facing and three rigs (the generator's skeleton in metres, the same
in centimetres, and with prefixed joint names as exporters write them), plus the real
clips of the data folder (CMU, Bandai-Namco and glTF characters) when it is there, at
the start and again at the end of the run. The
batch (:func:`run_library`) then runs it with ``--jobs N`` while a sampler records
every worker's resident memory, and the report gives scenes per minute, peak RSS per
worker, RSS growth after the first 100 scenes, and the cost split per stage (load,
select, render) from the index's timings.

Run it with ``snapshot bench --only library`` and ``SNAPSHOT_BENCH_LIBRARY=2500``
(clips; the case is skipped without it, being 20+ minutes on two cores), or call
:func:`run_library` directly for a slice.
"""

from __future__ import annotations

import json
import os
import shutil
import sys
import threading
from pathlib import Path

import numpy as np

from snapcore.bench.registry import BenchContext, case

__all__ = ["make_library", "run_library", "format_library", "RIGS"]

#: Rig variants of the generated clips.
RIGS = ("metres", "centimetres", "prefixed")
_MOTIONS = ("walk", "jump", "kick", "punch", "jumping_jacks", "idle")
_LENGTHS_S = (1.0, 2.0, 3.0, 4.0, 6.0)
#: Real clips copied in (relative to the data folder), when present.
REAL = (
    "walk_run/02_01.bvh",
    "walk_run/dataset-2_run_normal_001.bvh",
    "boxing_jump/Boxing_Toes.bvh",
    "basketball/06_15_jumpshot_excerpt.bvh",
    "dance/05_06.bvh",
    "soccer/10_01.bvh",
    "gltf/CesiumMan.glb",
    "gltf/BrainStem.glb",
)


def _rig(doc, rig: str):
    """``doc`` (the generator's skeleton, metres) as rig ``rig``."""
    from dataclasses import replace

    if rig == "centimetres":
        motion = doc.motion.copy()
        col = 0
        for chans in doc.channels:
            for c in chans:
                if c.endswith("position"):
                    motion[:, col] *= 100.0
                col += 1
        return replace(doc, offsets=doc.offsets * 100.0, motion=motion)
    if rig == "prefixed":
        return replace(doc, names=tuple(f"mixamorig:{n}" for n in doc.names))
    return doc


def make_library(root, n: int, *, data: Path | None = None) -> Path:
    """Write ``n`` clips under ``root`` (reused when already complete).

    Parameters
    ----------
    root : path-like
    n : int
        Clips in all (the real ones included).
    data : Path, optional
        The real data folder: :data:`REAL` clips are copied from it into ``real/``.

    Returns
    -------
    Path
        ``root``; its clips lie in ``<rig>/<motion>/`` folders.
    """
    from snapcore.motion import synth
    from snapcore.motion.bvh import write_bvh

    root = Path(root)
    done = root / ".complete"
    stamp = f"{n} clips, layout 2"  # a new layout makes a new library
    if done.exists() and done.read_text().strip() == stamp:
        return root
    if root.exists():
        shutil.rmtree(root)
    real = [data / r for r in REAL if data is not None and (data / r).exists()][: n // 2]
    # twice: at the start of the run (folder a_real, sorted first) and at its end
    # (z_real), so the largest clips set the memory high-water mark within the first
    # 100 scenes, and a growth measured after them is a leak, not a bigger clip
    for folder in ("a_real", "z_real"):
        for p in real:
            target = root / folder / p.parent.name / p.name
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy(p, target)
    rng = np.random.default_rng(2500)
    for i in range(n - 2 * len(real)):
        motion = _MOTIONS[i % len(_MOTIONS)]
        rig = RIGS[(i // len(_MOTIONS)) % len(RIGS)]
        seconds = float(_LENGTHS_S[rng.integers(len(_LENGTHS_S))])
        fps = 60.0 if rng.random() < 0.2 else 30.0
        doc = synth.humanoid_document(
            motion, seconds=seconds, fps=fps, seed=i, facing_deg=float(rng.uniform(0, 360))
        )
        folder = root / rig / motion
        folder.mkdir(parents=True, exist_ok=True)
        write_bvh(_rig(doc, rig), folder / f"{motion}_{i:05d}.bvh")
    done.write_text(stamp + "\n")
    return root


class _RssSampler:
    """Resident memory of this process's worker children, sampled every ``every_s``
    and at every finished scene: ``samples`` is a list of (scenes done, pid, MB)."""

    def __init__(self, every_s: float = 1.0):
        import psutil

        self.me = psutil.Process()
        self.every_s = every_s
        self.done = 0
        self.samples: list[tuple[int, int, float]] = []
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._loop, daemon=True)

    def sample(self):
        for p in self.me.children():
            try:
                if "resource_tracker" in " ".join(p.cmdline()):
                    continue
                self.samples.append((self.done, p.pid, p.memory_info().rss / 2**20))
            except Exception:  # noqa: BLE001 - a worker that just ended
                continue

    def _loop(self):
        while not self.stop.wait(self.every_s):
            self.sample()

    def __enter__(self):
        self.thread.start()
        return self

    def __exit__(self, *exc):
        self.stop.set()
        self.thread.join()


def run_library(
    n: int = 2500,
    *,
    jobs: int = 2,
    work: Path | None = None,
    data: Path | None = None,
    quiet: bool = False,
) -> dict:
    """Generate (or reuse) an ``n``-clip library and run ``snapshot batch`` on it.

    Parameters
    ----------
    n : int
    jobs : int
        Worker processes (at least 2: the RSS is measured on workers).
    work : Path, optional
        Folder for the library and the output (default a folder in the temp dir).
    data : Path, optional
        The real data folder.

    Returns
    -------
    dict
        ``scenes``, ``ok``, ``errors``, ``elapsed_s``, ``scenes_per_min``,
        ``workers`` (pid → ``first_mb``, ``at_100_mb``, ``peak_mb``, ``last_mb``,
        ``peak_to_100_mb``: highest RSS up to scene 100),
        ``growth_after_100_mb`` (the highest RSS of any worker after scene 100 minus
        the highest of any worker up to scene 100), ``stages_s`` (summed load/select/render seconds and
        shares), ``curve`` (scenes done, pid, MB), ``load`` (1-minute load average at
        start and end: the machine is shared).
    """
    from snapcore.batch import BatchOptions, discover, run_batch

    work = (
        Path(work)
        if work is not None
        else Path(os.environ.get("TMPDIR", "/tmp")) / "snapshot-bench-library"
    )
    lib = make_library(work / f"lib{n}", n, data=data)
    out = work / f"out{n}"
    if out.exists():
        shutil.rmtree(out)
    scenes = discover([lib]).scenes
    options = BatchOptions(snapshot={"baselines": False})  # the batch's default
    load0 = os.getloadavg()[0]
    with _RssSampler() as rss:

        def progress(total):
            def tick(row):
                rss.done += 1
                rss.sample()
                if not quiet and rss.done % 50 == 0:
                    print(f"library: {rss.done}/{total} scenes", file=sys.stderr, flush=True)

            return tick

        report = run_batch(scenes, out, options, jobs=max(jobs, 2), progress=progress)
    workers = {}
    for pid in sorted({p for _, p, _ in rss.samples}):
        curve = [(d, mb) for d, p, mb in rss.samples if p == pid]
        at_100 = [mb for d, mb in curve if d <= 100]
        after = [mb for d, mb in curve if d > 100]
        workers[pid] = {
            "first_mb": curve[0][1],
            "at_100_mb": at_100[-1] if at_100 else None,
            "peak_to_100_mb": max(at_100) if at_100 else None,
            "peak_mb": max(mb for _, mb in curve),
            "last_mb": curve[-1][1],
            # the high-water mark after scene 100 over the one before it
            "growth_after_100_mb": (max(after) - max(at_100)) if at_100 and after else None,
        }
    ok = [r for r in report.rows if r["status"] == "ok"]
    stages = {s: sum(r[f"t_{s}_s"] or 0.0 for r in ok) for s in ("load", "select", "render")}
    total = sum(stages.values()) or 1.0
    # the workers are alike and which one gets the largest clip is chance, so the leak
    # measure is over all of them: the highest RSS of any worker after scene 100 over
    # the highest of any worker up to scene 100 (a worker's own growth can be a large
    # clip that the other worker happened to get early)
    before = [mb for d, _, mb in rss.samples if d <= 100]
    after = [mb for d, _, mb in rss.samples if d > 100]
    growth = [max(after) - max(before)] if before and after else []
    result = {
        "scenes": report.done,
        "ok": len(ok),
        "errors": report.errors,
        "jobs": max(jobs, 2),
        "elapsed_s": report.elapsed_s,
        "scenes_per_min": 60.0 * report.done / report.elapsed_s,
        "workers": workers,
        "growth_after_100_mb": max(growth) if growth else None,
        "stages_s": {s: {"s": v, "share": v / total} for s, v in stages.items()},
        "curve": rss.samples,
        "load": [load0, os.getloadavg()[0]],
        "cpus": os.cpu_count(),
    }
    (work / f"library{n}.json").write_text(json.dumps(result, indent=1) + "\n")
    return result


def format_library(result: dict) -> list[str]:
    """The report as text lines (what docs/library.md's scale section shows)."""
    lines = [
        f"{result['scenes']} scenes ({result['ok']} ok, {result['errors']} errors), "
        f"--jobs {result['jobs']} on {result['cpus']} CPUs (load average "
        f"{result['load'][0]:.1f} at start, {result['load'][1]:.1f} at end): "
        f"{result['elapsed_s'] / 60:.1f} min, {result['scenes_per_min']:.1f} scenes/min"
    ]
    for pid, w in result["workers"].items():
        at = (
            ""
            if w["at_100_mb"] is None
            else (f", peak up to scene 100 {w['peak_to_100_mb']:.0f} MB")
        )
        lines.append(
            f"worker {pid}: RSS first {w['first_mb']:.0f} MB{at}, peak "
            f"{w['peak_mb']:.0f} MB, last {w['last_mb']:.0f} MB"
        )
    if result["growth_after_100_mb"] is not None:
        lines.append(
            f"growth of the workers' peak RSS after the first 100 scenes: "
            f"{result['growth_after_100_mb']:.0f} MB"
        )
    lines.append(
        "cost per stage (worker seconds): "
        + ", ".join(
            f"{s} {v['s']:.0f} s ({100 * v['share']:.0f}%)" for s, v in result["stages_s"].items()
        )
    )
    return lines


@case(
    "batch library: generated clips, --jobs 2 (SNAPSHOT_BENCH_LIBRARY=N clips)",
    max_repeats=1,
    warmup=False,
    note="skipped unless SNAPSHOT_BENCH_LIBRARY is set (2500: the CMU-sized library); "
    "prints scenes/min, RSS per worker and the cost per stage",
)
def _library(ctx: BenchContext):
    n = int(os.environ.get("SNAPSHOT_BENCH_LIBRARY", "0") or 0)
    if n <= 0:
        return None

    def work():
        result = run_library(n, jobs=2, data=ctx.data)
        for line in format_library(result):
            print(line, file=sys.stderr, flush=True)
        return result

    return work
