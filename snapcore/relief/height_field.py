"""Bas-reliefs: a height field seen along a view, compressed in the gradient domain, printable.

The paper's application (§4.3, Fig. 11–12; METHOD.md §4). Pipeline:

1. height field: an orthographic depth render of the posed body mesh along the view
   (:func:`snapcore.relief.scene.height_field_from_scene`), height = distance towards
   the camera (:func:`height_from_depth`), plus the foreground mask;
2. gradient-domain compression after Weyrich et al. 2007 (:func:`compress_height_field`):
   clamp silhouette and occlusion jumps, attenuate gradient magnitudes non-linearly,
   keep (boost) small-scale detail split off by a cross-bilateral filter with spatial,
   height and view-angle kernels (the paper's "visual perception" kernel);
3. Poisson reconstruction (:mod:`snapcore.relief.poisson`: an exact DCT solver for the whole
   image, and the figure solved with the plate fixed at 0);
4. scaling to the print box on a base plate and a watertight mesh / STL
   (:class:`Relief`, :mod:`snapcore.relief.mesh`).

From a scene: :func:`snapcore.relief.scene.relief_from_scene`, and the paper's Fig. 11
(one pose carved from several views) :func:`snapcore.relief.scene.relief_comparison_figure`.

The plain linear compression (:func:`linear_height_field`) is kept for comparison, and
:func:`detail_energy` measures how much small-scale relief each method keeps.
All kernels are vectorised over the image; the cross-bilateral filter loops over kernel
offsets only.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal, overload

import numpy as np
from numpy.typing import ArrayLike
from scipy import ndimage

from snapcore.errors import ReliefError
from snapcore.relief.mesh import relief_mesh, shade_relief, write_png, write_relief_stl
from snapcore.relief.poisson import poisson_solve, poisson_solve_attached, poisson_solve_masked

__all__ = [
    "ReliefError",
    "ReliefParams",
    "Relief",
    "height_from_depth",
    "clamped_gradients",
    "attenuate_gradients",
    "cross_bilateral",
    "poisson_solve",
    "compress_height_field",
    "linear_height_field",
    "relief_from_height_field",
    "detail_energy",
    "detail_region",
    "DETAIL_SIGMA_PX",
    "DETAIL_ERODE_PX",
    "CBF_TAPS_PER_SIGMA",
    "poisson_solve_masked",
    "poisson_solve_attached",
]


#: Scale of "small-scale detail" for :func:`detail_energy`: Gaussian sigma in pixels.
DETAIL_SIGMA_PX = 3.0
#: Pixels dropped next to the silhouette by :func:`detail_energy`, so the outline step of
#: the linear relief (one big jump) is not counted as "detail".
DETAIL_ERODE_PX = 6
#: A pixel size: ``(dx, dy)``, or one number for square pixels.
Pixel = float | tuple[float, float]
#: Kernel samples per spatial sigma in :func:`cross_bilateral` (tap spacing sigma/4).
CBF_TAPS_PER_SIGMA = 4.0


@dataclass(frozen=True)
class ReliefParams:
    """Every setting of a relief, with the defaults used by ``snapshot relief``.

    Print box
    ---------
    size_mm : (float, float)
        Footprint ``(W, D)`` in millimetres along image x (width) and image y (height).
        Paper: 100 × 100 mm.
    depth_mm : float
        Relief depth in millimetres: the highest point stands this far above the plate.
        Paper: 4 mm.
    base_mm : float
        Thickness of the base plate under the relief (mm). The solid is
        ``base_mm + depth_mm`` thick.
    resolution : int
        Height-field pixels along the longer side of the footprint (the other side in
        proportion). 512 gives ~0.2 mm cells on 100 mm, about the printer's precision
        and a ~25 MB binary STL; the STL grows with resolution squared (1024: ~100 MB).
    margin : float
        Flat border around the figure as a share of the footprint's shorter side.

    Compression (Weyrich et al. 2007)
    ---------------------------------
    method : {"compressed", "linear"}
        Gradient-domain compression (default) or plain linear scaling of the depth.
    silhouette_slope : float
        Depth slopes (dimensionless: metres of depth per metre across the image) above
        this are depth discontinuities — occlusion edges, grazing silhouettes — and are
        removed (``jump="zero"``, Weyrich) or clamped to it (``jump="clamp"``). Slope 5 is
        a surface at 79° to the image plane. Background–figure steps are always removed.
    jump : {"zero", "clamp"}
        What to do with a discontinuity (see ``silhouette_slope``).
    alpha : float
        Attenuation strength: a gradient of magnitude ``g`` becomes
        ``log(1 + alpha·g) / alpha`` (Weyrich eq. 2); 0 disables it.
    detail_sigma : float
        Spatial sigma of the cross-bilateral filter as a share of the longer image
        side (0.02 = 10 px at 512): features smaller than about this (folds, fingers,
        the face) are "detail"; larger ones (limbs, torso) are "shape".
    sigma_height : float
        Height kernel sigma as a share of the figure's depth range: neighbours at other
        depths (an arm in front of the torso) do not blur into each other.
    sigma_angle : float
        View-angle kernel sigma in radians on the angle between the surface normal and
        the view direction (the paper's visual-perception kernel).
    detail_gain : float
        Factor on the detail layer: compressed gradients become
        ``base + detail_gain · (g - base)``, ``base`` the filtered field. 1 = no boost.
    bilateral : {"separable", "full"}
        Separable approximation (x pass then y pass, 2·(2r+1) offsets; Pham & van Vliet
        2005) or the full 2-D kernel ((2r+1)² offsets).
    plate : {"attached", "free"}
        Poisson boundary. "attached": the background is the plate, fixed at height 0,
        and the figure is solved on its mask (:func:`poisson_solve_masked`, exact sparse
        LU), so the whole outline meets the plate. "free": Weyrich's whole-image solve
        with Neumann borders (:func:`poisson_solve`, exact DCT), after which the
        background is levelled to 0 — faster, but a pose whose outline lies at different
        depths (a foot forward, an arm back) leaves steps of up to most of the relief
        depth at the outline, because the least-squares error is shared with the
        background.
    plate_grid : int
        ``plate="attached"``: longest side of the grid on which the outline correction
        is solved (:func:`poisson_solve_attached`); 0 = exact sparse solve at full
        resolution (~10x slower at 1024²).
    """

    size_mm: tuple[float, float] = (100.0, 100.0)
    depth_mm: float = 4.0
    base_mm: float = 2.0
    resolution: int = 512
    margin: float = 0.05
    method: str = "compressed"
    silhouette_slope: float = 5.0
    jump: str = "zero"
    alpha: float = 4.0
    detail_sigma: float = 0.02
    sigma_height: float = 0.05
    sigma_angle: float = 0.35
    detail_gain: float = 2.5
    bilateral: str = "separable"
    plate: str = "attached"
    plate_grid: int = 256

    def __post_init__(self) -> None:
        size = tuple(float(s) for s in np.broadcast_to(np.asarray(self.size_mm, float), (2,)))
        object.__setattr__(self, "size_mm", size)
        checks = [
            ("size_mm", all(np.isfinite(size)) and min(size) > 0, "both sides > 0"),
            ("depth_mm", np.isfinite(self.depth_mm) and self.depth_mm > 0, "> 0"),
            ("base_mm", np.isfinite(self.base_mm) and self.base_mm > 0, "> 0"),
            (
                "resolution",
                int(self.resolution) == self.resolution and 8 <= self.resolution <= 8192,
                "an integer in 8..8192",
            ),
            ("margin", 0 <= self.margin < 0.5, "in [0, 0.5)"),
            ("method", self.method in ("compressed", "linear"), "'compressed' or 'linear'"),
            ("silhouette_slope", self.silhouette_slope > 0, "> 0"),
            ("jump", self.jump in ("zero", "clamp"), "'zero' or 'clamp'"),
            ("alpha", self.alpha >= 0, ">= 0"),
            ("detail_sigma", self.detail_sigma > 0, "> 0"),
            ("sigma_height", self.sigma_height > 0, "> 0"),
            ("sigma_angle", self.sigma_angle > 0, "> 0"),
            ("detail_gain", self.detail_gain >= 0, ">= 0"),
            ("bilateral", self.bilateral in ("separable", "full"), "'separable' or 'full'"),
            ("plate", self.plate in ("attached", "free"), "'attached' or 'free'"),
            (
                "plate_grid",
                int(self.plate_grid) == self.plate_grid and self.plate_grid >= 0,
                "an integer >= 0",
            ),
        ]
        for name, ok, what in checks:
            if not ok:
                raise ReliefError(
                    f"relief parameter {name}: must be {what}, got {getattr(self, name)!r}"
                )

    def shape(self) -> tuple[int, int]:
        """Height-field shape ``(ny, nx)`` for this footprint and resolution."""
        w, d = self.size_mm
        n = int(self.resolution)
        if w >= d:
            return max(2, int(round(n * d / w))), n
        return n, max(2, int(round(n * w / d)))


# --------------------------------------------------------------------- height field


def height_from_depth(depth: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Height field and foreground mask from a depth map.

    Parameters
    ----------
    depth : ndarray of shape (ny, nx)
        Distance from the camera plane along the view (any length unit); background
        pixels are NaN or infinite.

    Returns
    -------
    height : ndarray of shape (ny, nx)
        ``max(depth[mask]) - depth`` inside the mask (>= 0, towards the camera),
        0 on the background.
    mask : ndarray of shape (ny, nx), bool
        Foreground (finite depth).
    """
    d = np.asarray(depth, dtype=float)
    if d.ndim != 2:
        raise ReliefError(f"depth map: expected a 2-D array, got shape {d.shape}")
    mask = np.isfinite(d)
    if not mask.any():
        raise ReliefError("depth map has no foreground pixels: the figure is outside the view")
    height = np.where(mask, np.nanmax(np.where(mask, d, -np.inf)) - np.where(mask, d, 0.0), 0.0)
    return height, mask


def _forward_slopes(
    height: np.ndarray, mask: np.ndarray, pixel: tuple[float, float]
) -> tuple[np.ndarray, np.ndarray]:
    """Forward-difference slopes on the staggered grid, zero across the mask boundary."""
    px, py = pixel
    gx = np.zeros_like(height)
    gy = np.zeros_like(height)
    gx[:, :-1] = np.diff(height, axis=1) / px
    gy[:-1, :] = np.diff(height, axis=0) / py
    # an edge counts only if both of its pixels are figure: the outline sits on the plate
    gx[:, :-1] *= mask[:, :-1] & mask[:, 1:]
    gy[:-1, :] *= mask[:-1, :] & mask[1:, :]
    gx[:, -1] = 0.0
    gy[-1, :] = 0.0
    return gx, gy


def clamped_gradients(
    height: np.ndarray,
    mask: np.ndarray,
    *,
    pixel: Pixel = (1.0, 1.0),
    max_slope: float = 5.0,
    jump: str = "zero",
) -> tuple[np.ndarray, np.ndarray]:
    """Slopes of a height field with silhouette and occlusion jumps removed.

    Parameters
    ----------
    height : ndarray of shape (ny, nx)
        Heights (same length unit as ``pixel``).
    mask : ndarray of shape (ny, nx), bool
        Foreground.
    pixel : (float, float)
        Pixel size ``(dx, dy)``.
    max_slope : float
        Slopes of larger magnitude are discontinuities.
    jump : {"zero", "clamp"}
        Set discontinuities to 0 (Weyrich et al. 2007) or clamp them to ``±max_slope``.

    Returns
    -------
    gx, gy : ndarray of shape (ny, nx)
        ``gx[i, j] = (h[i, j+1] - h[i, j]) / dx`` and ``gy[i, j] = (h[i+1, j] - h[i, j]) / dy``
        (dimensionless), 0 on the last column / row, across the mask boundary and on the
        background.
    plate_grid : int
        ``plate="attached"``: longest side of the grid on which the outline correction
        is solved (:func:`poisson_solve_attached`); 0 = exact sparse solve at full
        resolution (~10x slower at 1024²).
    """
    gx, gy = _forward_slopes(np.asarray(height, float), np.asarray(mask, bool), _pixel_of(pixel))
    for g in (gx, gy):
        big = np.abs(g) > max_slope
        g[big] = 0.0 if jump == "zero" else np.sign(g[big]) * max_slope
    return gx, gy


def attenuate_gradients(
    gx: np.ndarray, gy: np.ndarray, *, alpha: float
) -> tuple[np.ndarray, np.ndarray]:
    """Non-linear attenuation of gradient magnitude (Weyrich et al. 2007, eq. 2).

    ``g ← g · C(|g|) / |g|`` with ``C(x) = log(1 + alpha·x) / alpha``: small slopes pass
    almost unchanged (``C'(0) = 1``), large ones are compressed logarithmically.
    ``alpha = 0`` returns the input.
    """
    if alpha == 0:
        return gx.copy(), gy.copy()
    m = np.hypot(gx, gy)
    am = alpha * m
    f = np.ones_like(m)
    nz = am > 1e-12
    f[nz] = np.log1p(am[nz]) / am[nz]
    return gx * f, gy * f


def view_angle(height: np.ndarray, mask: np.ndarray, *, pixel: Pixel = (1.0, 1.0)) -> np.ndarray:
    """Angle (radians) between the surface normal and the view direction, per pixel.

    The view looks down the height axis, so for the unit normal ``(-hx, -hy, 1)/|…|`` the
    angle is ``arctan(|∇h|)``: 0 facing the camera, → π/2 at grazing silhouettes.
    Central differences inside the mask; 0 on the background.
    """
    h = np.asarray(height, float)
    gx, gy = _forward_slopes(h, np.asarray(mask, bool), _pixel_of(pixel))
    # average the two staggered neighbours of each pixel (a central difference where both exist)
    cx = 0.5 * (gx + np.pad(gx, ((0, 0), (1, 0)))[:, :-1])
    cy = 0.5 * (gy + np.pad(gy, ((1, 0), (0, 0)))[:-1, :])
    return np.where(mask, np.arctan(np.hypot(cx, cy)), 0.0)


def cross_bilateral(
    values: np.ndarray,
    mask: np.ndarray,
    guides: Sequence[np.ndarray] | np.ndarray,
    *,
    sigma_spatial: float,
    sigmas: Sequence[float] | np.ndarray,
    mode: str = "separable",
) -> np.ndarray:
    """Masked cross-bilateral filter of one or more images guided by other images.

    Parameters
    ----------
    values : ndarray of shape (C, ny, nx)
        Images to filter (e.g. the two gradient components), all with the same weights.
    mask : ndarray of shape (ny, nx), bool
        Only foreground pixels contribute and receive a value (0 elsewhere).
    guides : sequence of ndarray of shape (ny, nx)
        Guide images (here: normalised height and view angle).
    sigma_spatial : float
        Spatial Gaussian sigma in pixels. The kernel reaches ``2·sigma`` and is sampled
        every ``ceil(sigma / CBF_TAPS_PER_SIGMA)`` pixels (every pixel up to sigma = 4):
        the weights are smooth on that scale, and a 20-px sigma costs 17 taps a pass
        instead of 81.
    sigmas : sequence of float
        Gaussian sigma of each guide's range kernel.
    mode : {"separable", "full"}
        Separable (x then y) or full 2-D kernel.

    Returns
    -------
    ndarray of shape (C, ny, nx)

    Notes
    -----
    ``out(p) = Σ_q w(p,q) v(q) / Σ_q w(p,q)`` with
    ``w = m(q) · exp(-|p-q|²/2σ_s²) · Π_k exp(-(g_k(p) - g_k(q))²/2σ_k²)`` (Tomasi &
    Manduchi 1998; cross/joint form: Petschnigg et al. 2004, Eisemann & Durand 2004).
    The loop runs over kernel offsets; each step is vectorised over the image.
    """
    v = np.asarray(values, dtype=np.float32)
    m = np.asarray(mask, bool)
    step = max(1, int(np.ceil(sigma_spatial / CBF_TAPS_PER_SIGMA)))
    r = step * max(1, int(np.ceil(2.0 * sigma_spatial / step)))
    taps = range(-r, r + 1, step)
    gs = [np.asarray(g, np.float32) for g in guides]
    inv = [np.float32(0.5 / s**2) for s in sigmas]
    if mode == "full":
        offsets = [(dy, dx) for dy in taps for dx in taps if dy * dy + dx * dx <= r * r]
        return _cbf_offsets(v, m, gs, inv, offsets, sigma_spatial, r)
    out = _cbf_offsets(v, m, gs, inv, [(0, d) for d in taps], sigma_spatial, r)
    return _cbf_offsets(out, m, gs, inv, [(d, 0) for d in taps], sigma_spatial, r)


def _cbf_offsets(
    v: np.ndarray,
    m: np.ndarray,
    guides: Sequence[np.ndarray],
    inv: Sequence[np.floating | float] | np.ndarray,
    offsets: Sequence[tuple[int, int]],
    sigma_spatial: float,
    r: int,
) -> np.ndarray:
    c, ny, nx = v.shape
    pad = ((r, r), (r, r))
    vp = np.pad(v, ((0, 0),) + pad)
    mp = np.pad(m.astype(np.float32), pad)
    gp = [np.pad(g, pad) for g in guides]
    num = np.zeros_like(v)
    den = np.zeros((ny, nx), np.float32)
    arg = np.empty((ny, nx), np.float32)
    tmp = np.empty((ny, nx), np.float32)
    for dy, dx in offsets:
        sl = (slice(r + dy, r + dy + ny), slice(r + dx, r + dx + nx))
        arg.fill(np.float32((dy * dy + dx * dx) / (2.0 * sigma_spatial**2)))
        for g, gq, k in zip(guides, gp, inv):
            np.subtract(gq[sl], g, out=tmp)
            np.multiply(tmp, tmp, out=tmp)
            tmp *= k
            arg += tmp
        np.negative(arg, out=arg)
        np.exp(arg, out=arg)
        arg *= mp[sl]
        den += arg
        for ch in range(c):
            num[ch] += arg * vp[ch][sl]
    np.divide(num, den, out=num, where=den > 0)
    num *= m
    return num


# --------------------------------------------------------------------- compression


def _pixel_of(pixel: Pixel) -> tuple[float, float]:
    p = np.broadcast_to(np.asarray(pixel, float), (2,))
    if not np.all(p > 0):
        raise ReliefError(f"pixel size must be > 0, got {pixel}")
    return float(p[0]), float(p[1])


def _normalise_relief(h: np.ndarray, mask: np.ndarray, *, what: str) -> np.ndarray:
    """Put the plate at 0, keep the figure >= 0, scale the highest point to 1."""
    top = h[mask].max() if mask.any() else 0.0
    if not top > 0:
        warnings.warn(
            f"{what}: the figure has no height (flat height field); the relief is an empty plate",
            stacklevel=3,
        )
        return np.zeros_like(h)
    return np.where(mask, np.clip(h / top, 0.0, 1.0), 0.0)


def linear_height_field(height: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Plain linear compression: the figure's depth range scaled to [0, 1].

    The farthest figure point lands on the plate (0), the nearest at 1, the background
    at 0; the outline is a step. Returns ndarray of shape (ny, nx).
    """
    h = np.asarray(height, float)
    m = np.asarray(mask, bool)
    if not m.any():
        raise ReliefError("height field has no foreground pixels")
    lo = h[m].min()
    return _normalise_relief(np.where(m, h - lo, 0.0), m, what="linear relief")


@overload
def compress_height_field(
    height: np.ndarray,
    mask: np.ndarray,
    *,
    pixel: Pixel = ...,
    params: ReliefParams | None = ...,
    return_layers: Literal[False] = ...,
) -> np.ndarray: ...
@overload
def compress_height_field(
    height: np.ndarray,
    mask: np.ndarray,
    *,
    pixel: Pixel = ...,
    params: ReliefParams | None = ...,
    return_layers: Literal[True],
) -> tuple[np.ndarray, dict[str, Any]]: ...
def compress_height_field(
    height: np.ndarray,
    mask: np.ndarray,
    *,
    pixel: Pixel = (1.0, 1.0),
    params: ReliefParams | None = None,
    return_layers: bool = False,
) -> np.ndarray | tuple[np.ndarray, dict[str, Any]]:
    """Gradient-domain bas-relief compression of a height field (Weyrich et al. 2007).

    Parameters
    ----------
    height : ndarray of shape (ny, nx)
        Heights towards the viewer (e.g. from :func:`height_from_depth`), any unit.
    mask : ndarray of shape (ny, nx), bool
        Foreground.
    pixel : float or (float, float)
        Pixel size ``(dx, dy)`` in the unit of ``height``.
    params : ReliefParams, optional
        ``silhouette_slope, jump, alpha, detail_sigma, sigma_height, sigma_angle,
        detail_gain, bilateral`` are used.
    return_layers : bool
        Also return a dict of intermediate fields (for figures and tests).

    Returns
    -------
    ndarray of shape (ny, nx)
        Relief in [0, 1]: background 0, highest figure point 1.

    Notes
    -----
    1. Slopes ``g = ∇h`` (forward differences); steps between figure and background and
       slopes above ``silhouette_slope`` are removed (Weyrich §4.1), so the outline sits
       on the plate and an arm in front of the torso does not spend the depth budget on
       the gap between them.
    2. ``g ← g · C(|g|)/|g|``, ``C(x) = log(1 + αx)/α`` (Weyrich §4.2).
    3. Detail: ``b = CBF(g)``, a cross-bilateral filter (spatial sigma ``detail_sigma``,
       range kernels on the normalised height and on the angle between normal and view
       direction — the paper's §4.3 third kernel); ``g ← b + detail_gain·(g - b)``. This is
       Weyrich's unsharp masking of the gradient field (§4.3 there) with the Gaussian
       replaced by the cross-bilateral filter the Action Snapshot paper describes, so the
       detail layer does not pick up halos across depth edges.
    4. Poisson reconstruction: with ``plate="attached"`` (default) on the mask with the
       background fixed at 0 (:func:`poisson_solve_attached`: the exact DCT solve plus a
       coarse harmonic correction; :func:`poisson_solve_masked`, exact, when
       ``plate_grid=0``); with ``plate="free"`` on the whole image (:func:`poisson_solve`,
       DCT, Neumann), then the background's median is moved to 0. Figure heights below
       the plate (small, from the non-integrable part of ``g``) are clipped; the result
       is scaled so the highest point is 1.
    """
    p = params or ReliefParams()
    h = np.asarray(height, float)
    m = np.asarray(mask, bool)
    if h.shape != m.shape or h.ndim != 2:
        raise ReliefError(
            f"height and mask: expected one (ny, nx) shape, got {h.shape} and {m.shape}"
        )
    if not m.any():
        raise ReliefError("height field has no foreground pixels")
    pixel = _pixel_of(pixel)
    gx, gy = clamped_gradients(h, m, pixel=pixel, max_slope=p.silhouette_slope, jump=p.jump)
    # edges that carry a slope: both pixels figure, and not a removed jump
    rx, ry = _forward_slopes(h, m, pixel)
    keep_x = np.zeros_like(m)
    keep_y = np.zeros_like(m)
    keep_x[:, :-1] = m[:, :-1] & m[:, 1:]
    keep_y[:-1, :] = m[:-1, :] & m[1:, :]
    if p.jump == "zero":
        keep_x &= np.abs(rx) <= p.silhouette_slope
        keep_y &= np.abs(ry) <= p.silhouette_slope
    ax, ay = attenuate_gradients(gx, gy, alpha=p.alpha)
    rng = np.ptp(h[m])
    layers = {"gx": gx, "gy": gy, "attenuated": (ax, ay)}
    if p.detail_gain != 1.0:
        guides = [h / rng if rng > 0 else np.zeros_like(h), view_angle(h, m, pixel=pixel)]
        sig = max(0.5, p.detail_sigma * max(h.shape))
        base = cross_bilateral(
            np.stack([ax, ay]),
            m,
            guides,
            sigma_spatial=sig,
            sigmas=(p.sigma_height, p.sigma_angle),
            mode=p.bilateral,
        )
        fx = base[0] + p.detail_gain * (ax - base[0])
        fy = base[1] + p.detail_gain * (ay - base[1])
        layers.update(base=base, angle=guides[1])
    else:
        fx, fy = ax, ay
    # removed edges stay removed: the detail boost must not turn "no jump here" (0) into
    # (1 - gain)·base at an outline or an occlusion edge
    fx = fx * keep_x
    fy = fy * keep_y
    if p.plate == "attached":
        rec = poisson_solve_attached(fx, fy, m, pixel=pixel, grid=p.plate_grid)
    else:
        rec = poisson_solve(fx, fy, pixel=pixel)
        rec -= np.median(rec[~m]) if (~m).any() else rec[m].min()
    out = _normalise_relief(rec, m, what="compressed relief")
    if return_layers:
        layers.update(final=(fx, fy), poisson=rec)
        return out, layers
    return out


# --------------------------------------------------------------------- print


@dataclass(frozen=True)
class Relief:
    """A relief ready to print: heights above the plate on a regular grid (millimetres).

    Attributes
    ----------
    height_mm : ndarray of shape (ny, nx)
        Height above the plate, in [0, depth_mm]; 0 on the background. Row 0 is the top
        of the image.
    mask : ndarray of shape (ny, nx), bool
        The figure's silhouette.
    params : ReliefParams
        Print box and compression settings used.
    meta : dict
        Where it came from (frame, view, pixel size in metres...), JSON-ready.
    """

    height_mm: np.ndarray
    mask: np.ndarray
    params: ReliefParams
    meta: dict = field(default_factory=dict)

    @property
    def pixel_mm(self) -> tuple[float, float]:
        """Grid spacing ``(dx, dy)`` in millimetres."""
        ny, nx = self.height_mm.shape
        w, d = self.params.size_mm
        return w / (nx - 1), d / (ny - 1)

    @property
    def n_triangles(self) -> int:
        """Triangles of the solid: ``2(ny-1)(nx-1)`` on top, ``3P`` walls and bottom."""
        ny, nx = self.height_mm.shape
        return 2 * (ny - 1) * (nx - 1) + 3 * (2 * (nx - 1) + 2 * (ny - 1))

    def mesh(self) -> tuple[np.ndarray, np.ndarray]:
        """``(vertices, faces)`` of the watertight solid (see :func:`relief_mesh`)."""
        return relief_mesh(self.height_mm, size_mm=self.params.size_mm, base_mm=self.params.base_mm)

    def shaded(self, **light: Any) -> np.ndarray:
        """Lambert-shaded preview image (ny, nx) in [0, 1] (see :func:`shade_relief`)."""
        return shade_relief(self.height_mm, pixel_mm=self.pixel_mm, **light)

    def write_stl(self, path: str | Path) -> Path:
        """Write the solid as binary STL (millimetres; see :func:`write_relief_stl`)."""
        p = self.params
        return write_relief_stl(path, self.height_mm, size_mm=p.size_mm, base_mm=p.base_mm)

    def write_preview(self, path: str | Path, **light: Any) -> Path:
        """Write the shaded preview as PNG."""
        return write_png(path, self.shaded(**light))


def relief_from_height_field(
    height: np.ndarray,
    mask: np.ndarray,
    *,
    pixel: Pixel = (1.0, 1.0),
    params: ReliefParams | None = None,
    meta: dict | None = None,
) -> Relief:
    """Compress a height field (or scale it linearly) into a :class:`Relief`.

    ``params.method`` picks :func:`compress_height_field` or :func:`linear_height_field`;
    the result is scaled to ``params.depth_mm``. The height field is used at its own
    resolution; its aspect ratio should match ``params.size_mm`` (pixels stretch if not).
    """
    p = params or ReliefParams()
    if p.method == "linear":
        unit = linear_height_field(height, mask)
    else:
        unit = compress_height_field(height, mask, pixel=pixel, params=p)
    return Relief(unit * p.depth_mm, np.asarray(mask, bool).copy(), p, dict(meta or {}))


def detail_region(
    mask: np.ndarray,
    *,
    height: np.ndarray | None = None,
    pixel: Pixel = (1.0, 1.0),
    max_slope: float = 5.0,
    erode_px: int = DETAIL_ERODE_PX,
) -> np.ndarray:
    """Where :func:`detail_energy` looks: the silhouette minus bands around its edges.

    Pixels within ``erode_px`` of the outline are dropped and, when the original
    ``height`` field is given, also those within ``erode_px`` of a depth discontinuity
    (a slope above ``max_slope``, e.g. an arm in front of the torso): a step is not
    detail, and a linear relief keeps every step at full height.
    Returns ndarray of shape (ny, nx), bool.
    """
    m = np.asarray(mask, bool)
    if height is None:
        bad = ~m
    else:
        rx, ry = _forward_slopes(np.asarray(height, float), m, _pixel_of(pixel))
        jump = np.zeros_like(m)
        jx, jy = np.abs(rx) > max_slope, np.abs(ry) > max_slope
        jump |= jx
        jump[:, 1:] |= jx[:, :-1]
        jump |= jy
        jump[1:, :] |= jy[:-1, :]
        bad = ~m | jump
    if erode_px > 0:
        bad = ndimage.binary_dilation(bad, iterations=erode_px)
    return m & ~bad


def detail_energy(
    relief: np.ndarray,
    mask: np.ndarray,
    *,
    sigma_px: float = DETAIL_SIGMA_PX,
    erode_px: int = DETAIL_ERODE_PX,
    depth: float | None = None,
    region: np.ndarray | None = None,
) -> float:
    """Small-scale gradient energy of a relief inside its silhouette, per unit depth.

    Parameters
    ----------
    relief : ndarray of shape (ny, nx)
        Relief heights (any unit).
    mask : ndarray of shape (ny, nx), bool
        Silhouette.
    sigma_px : float
        Scale separating "detail" from "shape": Gaussian sigma in pixels.
    erode_px : int
        Pixels next to the outline left out (the outline itself is not detail).
    depth : float, optional
        Normalising depth; default the relief's peak height ``max(relief[mask])``.
    region : ndarray of shape (ny, nx), bool, optional
        Pixels to average over instead of the eroded mask, e.g. :func:`detail_region`
        with the original height field, which also leaves out occlusion steps.

    Returns
    -------
    float
        ``sqrt(mean_{region} |∇(r - G_σ * r)|²) / depth``: the RMS slope (per pixel)
        of the high-pass relief, as a share of the total relief depth. Two reliefs of
        the same depth compare directly: the larger keeps more small-scale detail.
    """
    r = np.asarray(relief, float)
    m = np.asarray(mask, bool)
    inner = detail_region(m, erode_px=erode_px) if region is None else np.asarray(region, bool)
    if not inner.any():
        raise ReliefError("detail_energy: the region is empty; use a smaller erode_px")
    hp = r - ndimage.gaussian_filter(r, sigma_px, mode="nearest")
    gy, gx = np.gradient(hp)
    d = float(r[m].max()) if depth is None else float(depth)
    if not d > 0:
        raise ReliefError("detail_energy: the relief has no depth")
    return float(np.sqrt(np.mean((gx * gx + gy * gy)[inner])) / d)
