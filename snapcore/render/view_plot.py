"""Figures of view scores over the sphere, with the three methods' picks.

:func:`plot_views` draws one map per method (Projected Motion Area, motion area,
viewpoint entropy) of the score over all view directions, as a Mollweide (default) or
equirectangular heat map, and marks on every map the view each method picked:

- longitude = azimuth ``atan2(v_x, v_z)`` (0° = +Z, 90° = +X), latitude = elevation
  ``asin(v_y)``; a view is where the camera is, seen from the scene centre;
- ★ PMA (ours), ▲ motion area, ● viewpoint entropy; hollow markers at the antipodes of
  the PMA and motion-area picks (those scores cannot tell ``v`` from ``-v``);
- the characters' mean facing as a dashed meridian ("front").

The scores come from the exact evaluator on the sample sphere (PMA and motion area on
2,562 views, viewpoint entropy on its 162 face-id renders, every view rendered for the
map) and are interpolated between samples (inverse distance over the 3 nearest).
Matplotlib with the Agg backend, imported lazily; functions return the figure.
"""

from __future__ import annotations

import math

import numpy as np

from snapcore.errors import RenderError
from snapcore.render.bodies import DEFAULT_BODY, BodyKind
from snapcore.render.renderer import scene_index
from snapcore.render.viewpoint_entropy import select_view_entropy
from snapcore.select.view import motion_triangles, pma_scores, select_view, window_frames
from snapcore.select.view_methods import ViewMethod

__all__ = ["plot_views", "sphere_heatmap", "view_maps", "lon_lat", "PROJECTIONS", "MARKERS"]

#: Map projections: matplotlib's Mollweide, or plain longitude/latitude axes.
PROJECTIONS = ("mollweide", "equirect")
#: Marker, colour and label of each method's pick.
MARKERS = {
    "pma": ("*", "#d62728", f"PMA ({ViewMethod.OURS.label})"),
    "motion_area": ("^", "#1f77b4", ViewMethod.MOTION_AREA.label),
    "viewpoint_entropy": ("o", "#2ca02c", ViewMethod.VIEWPOINT_ENTROPY.label),
}
_TITLES = {
    "pma": "Projected Motion Area (sum of per-quad ratios)",
    "motion_area": "motion area, Kwon & Lee (m²)",
    "viewpoint_entropy": "viewpoint entropy, Vázquez et al. (bits)",
}
#: Pixels of the interpolated map (longitude × latitude).
MAP_SIZE = (360, 180)


def _check_projection(projection: str) -> None:
    """Refuse an unknown map projection before any work is done."""
    if projection not in PROJECTIONS:
        raise RenderError(f"projection must be one of {', '.join(PROJECTIONS)}, got {projection!r}")


def _pyplot():
    import matplotlib

    if matplotlib.get_backend().lower() not in ("agg", "pdf", "svg", "ps", "cairo"):
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def lon_lat(views) -> tuple[np.ndarray, np.ndarray]:
    """Longitude ``atan2(x, z)`` and latitude ``asin(y)`` (radians) of unit views (..., 3)."""
    v = np.asarray(views, float)
    return np.arctan2(v[..., 0], v[..., 2]), np.arcsin(np.clip(v[..., 1], -1.0, 1.0))


def _interpolate(views, scores, size=MAP_SIZE):
    """Scores on a lon/lat grid: inverse-angle weights over the 3 nearest samples."""
    from scipy.spatial import cKDTree

    ok = np.isfinite(scores)
    views, scores = np.asarray(views)[ok], np.asarray(scores)[ok]
    nx, ny = size
    lon = np.linspace(-math.pi, math.pi, nx + 1)
    lat = np.linspace(-math.pi / 2, math.pi / 2, ny + 1)
    lc, tc = 0.5 * (lon[1:] + lon[:-1]), 0.5 * (lat[1:] + lat[:-1])
    lg, tg = np.meshgrid(lc, tc)
    dirs = np.stack([np.cos(tg) * np.sin(lg), np.sin(tg), np.cos(tg) * np.cos(lg)], axis=-1)
    dist, idx = cKDTree(views).query(dirs.reshape(-1, 3), k=min(3, len(views)))
    dist, idx = dist.reshape(len(dist), -1), idx.reshape(len(idx), -1)
    w = 1.0 / np.maximum(dist, 1e-9) ** 2
    field = (w * scores[idx]).sum(axis=1) / w.sum(axis=1)
    return lon, lat, field.reshape(ny, nx)


def sphere_heatmap(
    views,
    scores,
    *,
    ax=None,
    projection: str = "mollweide",
    picks=None,
    facing=None,
    title: str | None = None,
    cmap: str = "magma",
    symmetric: tuple[str, ...] = (),
):
    """One heat map of scores over view directions.

    Parameters
    ----------
    views : ndarray of shape (V, 3)
        Unit views (scene centre → camera).
    scores : ndarray of shape (V,)
        Score per view (NaN = not computed; left out of the interpolation).
    ax : Axes, optional
        Must have the Mollweide projection when ``projection="mollweide"``.
    projection : {"mollweide", "equirect"}
    picks : dict, optional
        Method name (a key of :data:`MARKERS`) → unit view to mark.
    facing : array_like of shape (3,), optional
        Mean facing: drawn as a dashed meridian labelled "front".
    title : str, optional
    cmap : str
    symmetric : tuple of str
        Picks whose score is even in ``v``: also marked (hollow) at ``-v``.

    Returns
    -------
    Figure
    """
    _check_projection(projection)
    plt = _pyplot()
    if ax is None:
        fig = plt.figure(figsize=(8, 4.4))
        ax = fig.add_subplot(111, projection="mollweide" if projection == "mollweide" else None)
    fig = ax.figure
    lon, lat, field = _interpolate(views, scores)
    scale = 1.0 if projection == "mollweide" else 180.0 / math.pi
    mesh = ax.pcolormesh(
        lon * scale, lat * scale, field, cmap=cmap, shading="flat", rasterized=True
    )
    fig.colorbar(mesh, ax=ax, shrink=0.75, pad=0.02)
    if facing is not None and np.linalg.norm(np.asarray(facing)[[0, 2]]) > 1e-9:
        f_lon, _ = lon_lat(np.asarray(facing) / np.linalg.norm(facing))
        ax.plot(
            [f_lon * scale] * 2,
            [-math.pi / 2 * scale, math.pi / 2 * scale],
            ls="--",
            color="white",
            lw=0.9,
            alpha=0.8,
        )
        ax.text(f_lon * scale, 0.62 * math.pi / 2 * scale, " front", color="white", fontsize=8)
    # hollow antipodes first, then the picks
    order = [
        m for m in ("viewpoint_entropy", "motion_area", "pma") if (picks or {}).get(m) is not None
    ]
    for name in order:
        if name in symmetric:
            marker, colour, _ = MARKERS[name]
            x, y = lon_lat(-np.asarray(picks[name], float))
            ax.plot(
                x * scale,
                y * scale,
                marker=marker,
                ms=15 if marker == "*" else 10,
                mfc="none",
                mec=colour,
                mew=1.5,
                ls="none",
                zorder=4,
            )
    # the big star underneath, the smaller markers on it: picks at the same place all show
    for z, name in enumerate(sorted(order, key=lambda m: MARKERS[m][0] != "*")):
        marker, colour, label = MARKERS[name]
        x, y = lon_lat(np.asarray(picks[name], float))
        ax.plot(
            x * scale,
            y * scale,
            marker=marker,
            ms=15 if marker == "*" else 8,
            color=colour,
            mec="white",
            mew=1.0,
            ls="none",
            label=label,
            zorder=5 + z,
        )
    if projection == "equirect":
        ax.set_xlim(-180, 180)
        ax.set_ylim(-90, 90)
        ax.set_xticks(range(-180, 181, 45))
        ax.set_yticks(range(-90, 91, 30))
        ax.set_xlabel("azimuth from +Z towards +X (°)")
        ax.set_ylabel("elevation (°)")
        ax.set_aspect("equal")
    ax.grid(True, color="white", alpha=0.25, lw=0.5)
    ax.tick_params(labelsize=7)
    if title:
        ax.set_title(title, fontsize=10, pad=14)  # clear of the map's top latitude label
    return fig


def view_maps(
    scene,
    *,
    frame: int,
    window_s: float | None = None,
    n_views: int = 2562,
    entropy: bool = True,
    body: BodyKind = DEFAULT_BODY,
) -> dict:
    """Exact scores over the sphere of every method, and their picks.

    Parameters
    ----------
    scene : Scene
    frame : int
        Source frame (the file's own number, ``Snapshot.source_frame``): the posed body
        for viewpoint entropy, the window's centre.
    window_s : float, optional
        Score PMA and motion area over ``frame ± window_s`` (default: the whole sequence).
    n_views : int
        Samples for PMA and motion area.
    entropy : bool
        Include viewpoint entropy (renders the posed body; needs OpenGL).
    body : {"human", "mannequin"}
        What the characters wear for viewpoint entropy
        (:data:`snapcore.render.bodies.BodyKind`).

    Returns
    -------
    dict
        Method → ``{"views", "scores", "pick", "score", "facing"}``.
    """
    index = scene_index(scene, frame)
    frames = window_frames(scene, index if window_s is not None else None, window_s)
    tri = motion_triangles(scene, frames=frames)
    out = {}
    for method in ("pma", "motion_area"):
        sel = select_view(
            scene, index=index, window_s=window_s, method=method, n_views=n_views, triangles=tri
        )
        out[method] = {
            "views": sel.views,
            "scores": pma_scores(sel.views, tri, weighting=method),
            "pick": sel.view,
            "score": sel.score,
            "facing": sel.facing,
        }
    if entropy:
        ve = select_view_entropy(scene, index, score_all=True, body=body)
        out["viewpoint_entropy"] = {
            "views": ve.views,
            "scores": ve.scores,
            "pick": ve.view,
            "score": ve.score,
            "facing": out["pma"]["facing"],
        }
    return out


def plot_views(
    scene,
    *,
    frame: int,
    window_s: float | None = None,
    n_views: int = 2562,
    projection: str = "mollweide",
    entropy: bool = True,
    maps: dict | None = None,
    body: BodyKind = DEFAULT_BODY,
):
    """Heat maps of PMA, motion area and viewpoint entropy with all picks marked.

    Parameters
    ----------
    scene : Scene
    frame : int
        Source frame of the pose (``Snapshot.source_frame``; viewpoint entropy, window
        centre).
    window_s : float, optional
        PMA and motion area over ``frame ± window_s`` seconds (default: whole sequence).
    n_views : int
    projection : {"mollweide", "equirect"}
    entropy : bool
        Include the viewpoint-entropy map (renders the body).
    maps : dict, optional
        Precomputed :func:`view_maps` output.
    body : {"human", "mannequin"}
        What the characters wear for viewpoint entropy (ignored with ``maps``)
        (:data:`snapcore.render.bodies.BodyKind`).

    Returns
    -------
    Figure
    """
    _check_projection(projection)
    plt = _pyplot()
    if maps is None:
        maps = view_maps(
            scene, frame=frame, window_s=window_s, n_views=n_views, entropy=entropy, body=body
        )
    names = [m for m in ("pma", "motion_area", "viewpoint_entropy") if m in maps]
    fig = plt.figure(figsize=(8.5, 3.9 * len(names)))
    picks = {m: maps[m]["pick"] for m in names}
    for i, m in enumerate(names):
        ax = fig.add_subplot(
            len(names), 1, i + 1, projection="mollweide" if projection == "mollweide" else None
        )
        sphere_heatmap(
            maps[m]["views"],
            maps[m]["scores"],
            ax=ax,
            projection=projection,
            picks=picks,
            facing=maps[m]["facing"],
            title=_TITLES[m],
            symmetric=("pma", "motion_area"),
        )
    when = f"frame {int(frame)}"
    span = "whole sequence" if window_s is None else f"frame ± {window_s:g} s"
    fig.suptitle(
        f"{scene.name}: view scores over the sphere (PMA and motion area: {span}; "
        f"entropy: body at {when})",
        fontsize=10,
    )
    handles, labels = fig.axes[0].get_legend_handles_labels()
    handles.append(
        plt.Line2D([], [], marker="*", ms=11, mfc="none", mec=MARKERS["pma"][1], mew=1.5, ls="none")
    )
    labels.append("hollow: the antipode (same PMA / motion area)")
    fig.tight_layout(rect=(0, 0.035, 1, 1))
    fig.legend(handles, labels, loc="lower center", ncol=len(labels), fontsize=8, frameon=False)
    return fig
