"""The registry of benchmark cases: what a case receives and how it is registered.

Each case is a function registered with :func:`case`; it receives a :class:`BenchContext`
(data paths, a cache of loaded scenes) and returns a zero-argument callable, the work to
time, so that set-up (reading files, building meshes) is not timed.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from snapcore.motion.load import load_scene

__all__ = ["case", "CASES", "BenchCase", "BenchContext", "Measured"]


@dataclass(frozen=True)
class Measured:
    """What a case's work returns when its figure is not its own wall time (a CPU time
    per scene, a ratio): the runner reports ``ms`` instead of the time it measured."""

    ms: float


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
            a, b = (
                self.path("two_person/60_01_scaled.bvh"),
                self.path("two_person/61_01_scaled.bvh"),
            )
            if a is None or b is None:
                self.cache["salsa"] = None
            else:
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


CASES: list[BenchCase] = []


def case(
    name: str,
    *,
    target_ms: float | None = None,
    note: str = "",
    max_repeats: int | None = None,
    warmup: bool = True,
):
    """Register a benchmark case (decorator). The function returns the timed callable,
    or None to skip (e.g. data missing).

    ``max_repeats`` caps the timed runs of a long case (a 40 s video is timed once);
    ``warmup=False`` skips its untimed first run.
    """

    def deco(func):
        CASES.append(BenchCase(name, func, target_ms, note, max_repeats, warmup))
        return func

    return deco
