"""The benchmark behind ``snapshot bench``: repeatable timings of every hot path.

The cases live in :mod:`snapcore.bench.cases`, registered in
:mod:`snapcore.bench.registry`. Every case is
run ``repeats`` times after one warm-up; the table shows min and median wall time in
milliseconds (or the figure a case reports as :class:`~snapcore.bench.registry.Measured`:
CPU per scene, a ratio) and the target where the issue sets one. Timings use one thread of
BLAS (set before NumPy loads, in :func:`run`'s caller) so numbers are "on one core".
"""

from __future__ import annotations

import re
import statistics
import time
from dataclasses import dataclass

from snapcore.bench import cases, cases_bodies, cases_speed, library  # noqa: F401  (registers)
from snapcore.bench.registry import CASES, BenchContext, Measured

__all__ = ["BenchResult", "run_cases", "select_cases", "PLUGIN_GROUP"]

#: Entry-point group of the modules of higher layers that register cases (the analysis's:
#: ``analysis.bench``); loaded by name, since this layer may not import them.
PLUGIN_GROUP = "action_snapshot.bench"


def _load_plugins() -> None:
    from importlib.metadata import entry_points

    for ep in entry_points(group=PLUGIN_GROUP):
        ep.load()


_load_plugins()


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
        if self.min_ms is None or self.median_ms is None:  # both None when skipped
            return "skipped"
        if self.target_ms is None:
            return ""
        return "ok" if self.median_ms <= self.target_ms else "SLOW"


def select_cases(only: str | None) -> list:
    """The cases ``--only`` names: the case whose name is exactly ``only`` (leading
    spaces aside), else those whose name holds it, numbers whole (``"dancers, 100"``
    is not part of ``"dancers, 1000 frames"``); all cases for None."""
    if only is None:
        return list(CASES)
    exact = [c for c in CASES if c.name.strip() == only.strip()]
    if exact:
        return exact
    # a number in the text is a whole number ("100" is not the start of "1000"); words
    # may be prefixes ("Boxing" names "Boxing_Toes")
    text = only.strip()
    words = re.compile(
        r"(?<![0-9])" * text[:1].isdigit() + re.escape(text) + r"(?![0-9])" * text[-1:].isdigit()
    )
    return [c for c in CASES if words.search(c.name)]


def run_cases(
    ctx: BenchContext, *, repeats: int = 7, only: str | None = None, progress=None
) -> list[BenchResult]:
    """Run every registered case, or those :func:`select_cases` picks by ``only``."""
    results = []
    chosen = select_cases(only)
    for c in chosen:
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
            got = work()
            wall = (time.perf_counter() - t0) * 1000.0
            times.append(got.ms if isinstance(got, Measured) else wall)
        results.append(
            BenchResult(c.name, min(times), statistics.median(times), n, c.target_ms, c.note)
        )
    return results
