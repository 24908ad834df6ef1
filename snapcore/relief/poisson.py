"""Poisson reconstruction of a height field from target slopes, exact and vectorised.

Three solvers of the least-squares problem ``min_h Σ_edges ((h_q - h_p)/d - g_pq)²`` on
a pixel grid (forward-difference slopes ``gx, gy`` on the staggered grid):

- :func:`poisson_solve`: the whole image, Neumann borders — one DCT, a division, one
  inverse DCT (exact, ``O(N log N)``);
- :func:`poisson_solve_masked`: unknowns on a mask, fixed values (0 or given) off it —
  a sparse LU solve (exact);
- :func:`poisson_solve_attached`: the masked problem with the background at 0, fast —
  the DCT solve plus a harmonic correction solved on a coarser grid.

Used by :mod:`snapcore.relief.height_field` (the bas-relief's reconstruction step).
"""

from __future__ import annotations

import numpy as np
from scipy import fft as sfft
from scipy import ndimage

from snapcore.errors import ReliefError

__all__ = ["poisson_solve", "poisson_solve_masked", "poisson_solve_attached", "pixel_pair"]


def pixel_pair(pixel) -> tuple[float, float]:
    """``(dx, dy)`` from one number or a pair, both > 0 (ValueError otherwise)."""
    p = np.broadcast_to(np.asarray(pixel, float), (2,))
    if not np.all(p > 0):
        raise ReliefError(f"pixel size must be > 0, got {pixel}")
    return float(p[0]), float(p[1])


def poisson_solve(gx, gy, *, pixel=(1.0, 1.0)):
    """Least-squares height field with the given forward-difference slopes (Neumann, DCT).

    Parameters
    ----------
    gx, gy : ndarray of shape (ny, nx)
        Target slopes on the staggered grid, as returned by :func:`clamped_gradients`
        (``gx[:, -1]`` and ``gy[-1, :]`` are ignored).
    pixel : (float, float)
        Pixel size ``(dx, dy)``; the result is in the unit of ``slope · pixel``.

    Returns
    -------
    ndarray of shape (ny, nx), float64
        The height field ``h`` minimising ``Σ (D_x h - gx)² + (D_y h - gy)²`` with zero mean.
        When ``(gx, gy)`` are the forward differences of some ``h0``, this is ``h0`` minus
        its mean, to rounding error.

    Notes
    -----
    The normal equations are the discrete Poisson equation ``L h = div g`` with the
    5-point Laplacian and Neumann (reflecting) boundaries. The type-II DCT diagonalises
    that Laplacian: eigenvalues ``(2cos(πk/ny) - 2)/dy² + (2cos(πl/nx) - 2)/dx²``. So one
    forward DCT, a division and one inverse DCT solve it exactly in ``O(N log N)``; the
    zero eigenvalue (the free constant) is set to give zero mean.
    """
    dx, dy = pixel_pair(pixel)
    gx = np.array(gx, dtype=float)
    gy = np.array(gy, dtype=float)
    if gx.shape != gy.shape or gx.ndim != 2:
        raise ReliefError(
            f"gx, gy: expected two arrays of one (ny, nx) shape, got {gx.shape} and {gy.shape}"
        )
    ny, nx = gx.shape
    gx[:, -1] = 0.0
    gy[-1, :] = 0.0
    # div = D_x^T-style backward differences of the staggered slopes (unit: 1/length)
    div = np.diff(gx, axis=1, prepend=0.0) / dx + np.diff(gy, axis=0, prepend=0.0) / dy
    lam = ((2.0 * np.cos(np.pi * np.arange(ny) / ny) - 2.0) / dy**2)[:, None] + (
        (2.0 * np.cos(np.pi * np.arange(nx) / nx) - 2.0) / dx**2
    )[None, :]
    lam[0, 0] = 1.0
    u = sfft.dctn(div, type=2, norm="ortho")
    u /= lam
    u[0, 0] = 0.0
    return sfft.idctn(u, type=2, norm="ortho")


def poisson_solve_masked(gx, gy, mask, *, pixel=(1.0, 1.0), outside=None):
    """Least-squares height field on a mask with the plate (height 0) outside it.

    Parameters
    ----------
    gx, gy : ndarray of shape (ny, nx)
        Target forward-difference slopes as in :func:`poisson_solve`. Edges from a figure
        pixel to a background pixel count (their target is usually 0: the outline sits
        on the plate); edges between two background pixels are ignored.
    mask : ndarray of shape (ny, nx), bool
        The unknowns; every other pixel is fixed at 0 (or at ``outside``).
    pixel : (float, float)
        Pixel size ``(dx, dy)``.
    outside : ndarray of shape (ny, nx), optional
        Dirichlet values off the mask (default 0: the plate). With zero slopes this
        computes the discrete harmonic extension of ``outside`` into the mask.

    Returns
    -------
    ndarray of shape (ny, nx), float64
        The minimiser of ``Σ_edges ((h_q - h_p)/d - g_pq)²`` over heights with ``h = 0``
        off the mask (Dirichlet boundary on the outline, Neumann on the image border).

    Notes
    -----
    The normal equations are the 5-point Poisson equation restricted to the mask, a
    sparse symmetric positive-definite system (every figure region touches the plate),
    solved exactly by a sparse LU factorisation (SuperLU, minimum-degree ordering on
    ``A + Aᵀ``): about 0.5 s for 160k figure pixels. The right-hand side is the same
    divergence as :func:`poisson_solve`'s. A mask without background has no plate to
    attach to: then the result is :func:`poisson_solve`'s, shifted so its minimum is 0.
    """
    import scipy.sparse as sp
    from scipy.sparse.linalg import splu

    dx, dy = pixel_pair(pixel)
    m = np.asarray(mask, bool)
    gx = np.array(gx, dtype=float)
    gy = np.array(gy, dtype=float)
    if not (gx.shape == gy.shape == m.shape) or m.ndim != 2:
        raise ReliefError(
            f"gx, gy, mask: expected one (ny, nx) shape, got {gx.shape}, {gy.shape}, {m.shape}"
        )
    if m.all():
        h = poisson_solve(gx, gy, pixel=(dx, dy))
        return h - h.min()
    out = np.zeros(m.shape) if outside is None else np.where(m, 0.0, np.asarray(outside, float))
    if not m.any():
        return out
    gx[:, -1] = 0.0
    gy[-1, :] = 0.0
    div = np.diff(gx, axis=1, prepend=0.0) / dx + np.diff(gy, axis=0, prepend=0.0) / dy
    n = int(m.sum())
    idx = np.full(m.shape, -1, dtype=np.int64)
    idx[m] = np.arange(n)
    deg = np.zeros(m.shape)
    rows, cols, vals = [], [], []
    for a, b, ia, ib, w in (
        (m[:, :-1], m[:, 1:], idx[:, :-1], idx[:, 1:], 1.0 / dx**2),
        (m[:-1, :], m[1:, :], idx[:-1, :], idx[1:, :], 1.0 / dy**2),
    ):
        touch = (a | b) * w  # every edge with a figure end adds to its figure ends' degree
        if a.shape[1] != m.shape[1]:
            deg[:, :-1] += touch
            deg[:, 1:] += touch
        else:
            deg[:-1, :] += touch
            deg[1:, :] += touch
        if outside is not None:  # known neighbours move to the right-hand side
            lo = (
                (slice(None), slice(None, -1))
                if a.shape[1] != m.shape[1]
                else (slice(None, -1), slice(None))
            )
            hi = (
                (slice(None), slice(1, None))
                if a.shape[1] != m.shape[1]
                else (slice(1, None), slice(None))
            )
            div[lo] -= np.where(a & ~b, w * out[hi], 0.0)
            div[hi] -= np.where(~a & b, w * out[lo], 0.0)
        both = a & b
        rows += [ia[both], ib[both]]
        cols += [ib[both], ia[both]]
        vals += [np.full(both.sum() * 2, -w)]
    r = np.concatenate(rows + [np.arange(n)])
    c = np.concatenate(cols + [np.arange(n)])
    v = np.concatenate(vals + [deg[m]])
    a_mat = sp.csc_matrix((v, (r, c)), shape=(n, n))
    lu = splu(a_mat, permc_spec="MMD_AT_PLUS_A", options={"SymmetricMode": True})
    out[m] = lu.solve(-div[m])
    return out


def poisson_solve_attached(gx, gy, mask, *, pixel=(1.0, 1.0), grid: int = 256):
    """:func:`poisson_solve_masked` fast: exact DCT solve plus a coarse harmonic correction.

    Parameters
    ----------
    gx, gy, mask, pixel
        As :func:`poisson_solve_masked` (slopes across the outline are normally 0).
    grid : int
        Longest side of the grid on which the correction is solved. Images no larger
        than this (or ``grid <= 0``) are solved exactly by :func:`poisson_solve_masked`.

    Returns
    -------
    ndarray of shape (ny, nx)
        Heights with the background at 0 (approximately the masked least-squares
        solution; exactly it when solved at full resolution).

    Notes
    -----
    Let ``h_N`` be the whole-image Neumann solution (:func:`poisson_solve`, exact, DCT)
    and ``h_D`` the masked one (background fixed at 0). On the mask both satisfy the
    same normal equations, so ``c = h_N - h_D`` is discrete-harmonic on the mask with
    ``c = h_N`` on the background: ``h_D`` is ``h_N`` minus the harmonic extension of its
    background values. That extension is smooth, so it is solved on a grid ``f`` times
    coarser (``f = ceil(max(ny, nx) / grid)``; a coarse cell is figure when most of its
    pixels are; its background value is the mean of ``h_N`` over its background pixels),
    by sparse LU on ~1/f² of the unknowns, and upsampled bilinearly. Measured on the
    salsa pair at 1024²: 0.1 s instead of ~1 s for the full sparse solve, RMS difference
    under 1% of the relief depth (test ``test_attached_solver_matches_exact``).
    """
    m = np.asarray(mask, bool)
    ny, nx = m.shape
    if grid <= 0 or max(ny, nx) <= grid or m.all() or not m.any():
        return poisson_solve_masked(gx, gy, m, pixel=pixel)
    dx, dy = pixel_pair(pixel)
    h_n = poisson_solve(gx, gy, pixel=(dx, dy))
    f = int(np.ceil(max(ny, nx) / grid))
    py_, px_ = (-ny) % f, (-nx) % f
    hp = np.pad(h_n, ((0, py_), (0, px_)), mode="edge")
    mp = np.pad(m, ((0, py_), (0, px_)))
    cy, cx = hp.shape[0] // f, hp.shape[1] // f
    hb = hp.reshape(cy, f, cx, f)
    bg = ~mp.reshape(cy, f, cx, f)
    n_bg = bg.sum(axis=(1, 3))
    coarse_mask = n_bg * 2 < f * f
    bg_val = np.where(
        n_bg > 0, (hb * bg).sum(axis=(1, 3)) / np.maximum(n_bg, 1), hb.mean(axis=(1, 3))
    )
    zero = np.zeros((cy, cx))
    c = poisson_solve_masked(zero, zero, coarse_mask, pixel=(dx * f, dy * f), outside=bg_val)
    c_fine = ndimage.zoom(c, f, order=1, mode="nearest", grid_mode=True)[:ny, :nx]
    return np.where(m, h_n - c_fine, 0.0)
