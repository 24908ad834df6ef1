"""The benchmark behind ``snapshot bench``: repeatable timings of every hot path.

Each case is a function registered with :func:`case`; it receives a :class:`BenchContext`
(data paths, a cache of loaded scenes) and returns a zero-argument callable — the work
to time — so that set-up (reading files, building meshes) is not timed. Every case is
run ``repeats`` times after one warm-up; the table shows min and median wall time in
milliseconds and the target where the issue sets one. Timings use one thread of
BLAS (set before NumPy loads, in :func:`run`'s caller) so numbers are "on one core".
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

__all__ = ["case", "CASES", "BenchContext", "BenchResult", "run_cases"]


@dataclass
class BenchContext:
    """What a case may use: the data folder (or None) and a scene cache."""

    data: Path | None
    cache: dict = field(default_factory=dict)

    def path(self, rel: str) -> Path | None:
        if self.data is None:
            return None
        p = self.data / rel
        return p if p.exists() else None

    def salsa(self):
        """The 2,242-frame, two-person salsa scene at its true 60 fps (or None)."""
        if "salsa" not in self.cache:
            a, b = self.path("two_person/60_01_scaled.bvh"), self.path("two_person/61_01_scaled.bvh")
            if a is None or b is None:
                self.cache["salsa"] = None
            else:
                import warnings

                from .load import load_scene

                with warnings.catch_warnings():  # the salsa unit is fitted, which warns;
                    warnings.simplefilter("ignore")  # the table is not the place for it
                    self.cache["salsa"] = load_scene([a, b], fps=60)
        return self.cache["salsa"]


@dataclass
class BenchCase:
    name: str
    func: Callable[[BenchContext], Callable[[], object] | None]
    target_ms: float | None
    note: str
    max_repeats: int | None = None
    warmup: bool = True


@dataclass
class BenchResult:
    name: str
    min_ms: float | None
    median_ms: float | None
    repeats: int
    target_ms: float | None
    note: str

    @property
    def status(self) -> str:
        if self.min_ms is None:
            return "skipped"
        if self.target_ms is None:
            return ""
        return "ok" if self.median_ms <= self.target_ms else "SLOW"


CASES: list[BenchCase] = []


def case(name: str, *, target_ms: float | None = None, note: str = "",
         max_repeats: int | None = None, warmup: bool = True):
    """Register a benchmark case (decorator). The function returns the timed callable,
    or None to skip (e.g. data missing).

    ``max_repeats`` caps the timed runs of a long case (a 40 s video is timed once);
    ``warmup=False`` skips its untimed first run.
    """

    def deco(func):
        CASES.append(BenchCase(name, func, target_ms, note, max_repeats, warmup))
        return func

    return deco


def run_cases(ctx: BenchContext, *, repeats: int = 7, only: str | None = None,
              progress=None) -> list[BenchResult]:
    """Run every registered case (or those whose name contains ``only``)."""
    _register_all()
    results = []
    cases = [c for c in CASES if only is None or only in c.name]
    for c in cases:
        if progress:
            progress(c.name)
        work = c.func(ctx)
        if work is None:
            results.append(BenchResult(c.name, None, None, 0, c.target_ms, c.note or "no data"))
            continue
        if c.warmup:
            work()  # warm-up: imports, caches, first-touch of buffers
        n = repeats if c.max_repeats is None else min(repeats, c.max_repeats)
        times = []
        for _ in range(n):
            t0 = time.perf_counter()
            work()
            times.append((time.perf_counter() - t0) * 1000.0)
        results.append(BenchResult(c.name, min(times), statistics.median(times), n,
                                   c.target_ms, c.note))
    return results


def _register_all() -> None:
    """Import the modules that define cases (each registers itself once)."""
    from . import bench_cases  # noqa: F401
