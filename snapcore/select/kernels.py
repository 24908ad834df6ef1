"""The view search's compiled passes, and the one place that chooses them over NumPy.

:mod:`snapcore.select._pma_kernel` (Cython, built by ``make install`` through
``setup.py``) fuses the whole-array passes of :func:`snapcore.select.view.select_view`
over its ~500k swept triangles: the triangles' vectors, norms and quad areas in one pass
instead of ~25 NumPy passes, the octahedral bin index and per-bin sums in one instead of
~20, the vectors of the bins near a view in two instead of four (docs/speed.md § "Fourth
pass: a compiled kernel"). Each kernel repeats its NumPy reference's operations in the
same order, so the results are the same doubles.

The NumPy code stays the reference and the fallback: :func:`compiled` is False when the
extension was not built (a machine without a C compiler: the build is optional) or is
hidden, and the callers then run NumPy. Importing the extension imports nothing else.
"""

from __future__ import annotations

import functools
from types import ModuleType

import numpy as np

__all__ = ["compiled", "swept_block", "bin_vectors", "near_columns"]


@functools.cache
def _module() -> ModuleType | None:
    """The compiled module, or None when it cannot be imported (cached: one import)."""
    try:  # the import statement that honours a hidden module (None in sys.modules)
        import snapcore.select._pma_kernel as _pma_kernel
    except ImportError:
        return None
    return _pma_kernel


def compiled() -> bool:
    """Whether the compiled kernels are available (else the callers run NumPy)."""
    return _module() is not None


def _kernel():
    mod = _module()
    if mod is None:  # pragma: no cover - callers ask compiled() first
        raise RuntimeError("the compiled view kernels are not available")
    return mod


def swept_block(
    x: np.ndarray,
    links: np.ndarray,
    floor: float,
    b_pma: np.ndarray,
    n_pma: np.ndarray,
    quads: np.ndarray,
    offset: int,
) -> bool:
    """One character's PMA vectors, norms and quad areas (``view._swept_block``).

    Parameters
    ----------
    x : ndarray of shape (F, J, 3)
        Joint positions, m.
    links : ndarray of int, shape (L, 2)
        (parent, child) joint pairs.
    floor : float
        Noise floor on a quad's swept area, m².
    b_pma : ndarray of shape (3, K)
        All characters' PMA vectors (C-contiguous, written).
    n_pma : ndarray of shape (K,)
        Their norms (written).
    quads : ndarray of shape (K/2,)
        Quad areas, m² (written).
    offset : int
        This character's first triangle (even).

    Returns
    -------
    bool
        False (nothing written) when a link names a joint outside ``0..J-1``: the NumPy
        path then gives its own answer (negative indices count from the end there).
    """
    x = np.ascontiguousarray(x, dtype=np.float64)
    lk = np.ascontiguousarray(links, dtype=np.intp)
    if lk.size and not (lk.min() >= 0 and lk.max() < x.shape[1]):
        return False
    _kernel().swept_block(x, lk, float(floor), b_pma, n_pma, quads, int(offset))
    return True


def bin_vectors(b: np.ndarray, res: int, chunk: int, index: np.ndarray, gen: np.ndarray) -> None:
    """Bin index (written to ``index``, (K,) int32) and per-bin sums (added to ``gen``,
    (res², 3)) of the folded vectors ``b`` (3, K), summed per ``chunk`` as
    ``sphere._bin_generators`` does. Raises ValueError on a non-finite vector."""
    _kernel().bin_vectors(
        np.ascontiguousarray(b, dtype=np.float64), int(res), int(chunk), index, gen
    )


def near_columns(
    index: np.ndarray, near_bin: np.ndarray, b: np.ndarray, bn: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The vectors of the flagged bins, in order: a count and one gathering pass.

    Parameters
    ----------
    index : ndarray of int32, shape (K,)
        Each vector's bin (as :func:`bin_vectors` writes it).
    near_bin : ndarray of bool, shape (B,)
        The bins whose members are wanted.
    b : ndarray of shape (3, K)
    bn : ndarray of shape (K,)

    Returns
    -------
    bc : ndarray of shape (3, n)
    bcn : ndarray of shape (n,)
        ``np.take(b, sel, axis=1)`` and ``np.take(bn, sel)`` with
        ``sel = np.flatnonzero(np.take(near_bin, index))``.
    """
    mod = _kernel()
    idx = np.ascontiguousarray(index, dtype=np.int32)
    flags = np.ascontiguousarray(near_bin, dtype=bool).view(np.uint8)
    n = mod.count_near(idx, flags)
    bc, bcn = np.empty((3, n)), np.empty(n)
    mod.gather_near(
        idx,
        flags,
        np.ascontiguousarray(b, np.float64),
        np.ascontiguousarray(bn, np.float64),
        bc,
        bcn,
    )
    return bc, bcn
