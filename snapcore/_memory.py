"""Process-level memory allocator tuning for NumPy-heavy work.

NumPy allocates every temporary array with ``malloc``. glibc serves blocks above
``M_MMAP_THRESHOLD`` (128 KiB at start, raised dynamically) with fresh ``mmap`` pages
and returns freed memory at the top of the heap to the system once more than
``M_TRIM_THRESHOLD`` (128 KiB) is free. Both make the next array of the same size
start on untouched pages, and on virtual machines the page faults cost more than the
arithmetic: an elementwise operation on a 0.5 MB temporary ran at 3 ns per element
instead of 0.25 ns on the development VM, slowing pose selection 2-3 times.

:func:`tune_allocator` raises both thresholds once per process so freed arrays are
reused from the heap. The ``snapshot`` command calls it at start-up (every command
benefits, ``snapshot bench`` included); library users may call it themselves.
"""

from __future__ import annotations

import ctypes
import os
import sys

__all__ = ["MMAP_THRESHOLD", "TRIM_THRESHOLD", "tune_allocator"]

#: Blocks up to this size (bytes) come from the heap, not from fresh ``mmap`` pages.
#: glibc's own ceiling for its dynamic threshold (32 MiB on 64-bit systems): larger
#: arrays (video frames, big meshes) are rare and still mapped and unmapped directly.
MMAP_THRESHOLD = 32 * 1024 * 1024
#: Free memory (bytes) the heap may keep at its top before it is given back.
TRIM_THRESHOLD = 256 * 1024 * 1024

# mallopt parameter numbers from glibc's <malloc.h>.
_M_TRIM_THRESHOLD = -1
_M_MMAP_THRESHOLD = -3
# Environment variables with which a user already chose glibc's settings.
_USER_SETTINGS = ("MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_", "MALLOC_TOP_PAD_")

_done: bool | None = None


def tune_allocator() -> bool:
    """Keep freed memory for reuse instead of returning it to the system (glibc only).

    Sets ``M_MMAP_THRESHOLD`` to :data:`MMAP_THRESHOLD` and ``M_TRIM_THRESHOLD`` to
    :data:`TRIM_THRESHOLD` with ``mallopt``. Results of computations do not change;
    only page faults are avoided, at the price of the process keeping up to
    :data:`TRIM_THRESHOLD` bytes of freed memory.

    Returns
    -------
    bool
        True when the settings are in effect. False on other C libraries (macOS,
        Windows, musl) and when the user set any ``MALLOC_*_`` environment variable
        (their choice wins). Calling it again does nothing and returns the first answer.
    """
    global _done
    if _done is not None:
        return _done
    _done = False
    if not sys.platform.startswith("linux") or any(v in os.environ for v in _USER_SETTINGS):
        return False
    try:
        mallopt = ctypes.CDLL(None).mallopt  # the process's own C library
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    mallopt.restype = ctypes.c_int
    # The trim threshold first: setting either one switches off glibc's dynamic
    # adjustment, and a fixed 128 KiB mmap threshold would be the worst case.
    ok = mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD) == 1
    ok = mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD) == 1 and ok
    _done = ok
    return ok
