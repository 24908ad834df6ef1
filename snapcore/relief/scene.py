"""From a scene to a relief: the posed body seen along a view, carved, and the Fig. 11 figure.

The edge of :mod:`snapcore.relief.height_field` that touches motion data: :func:`height_field_from_scene`
renders the merged body mesh of every character at one frame as an orthographic depth
map framed to the print footprint (:func:`snapcore.render.buffers.render_depth`),
:func:`relief_from_scene` turns it into a :class:`~snapcore.relief.height_field.Relief`, and
:func:`relief_comparison_figure` shows one pose carved from several views side by side,
like the paper's Fig. 11 (one relief per method's view).
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from snapcore.relief.height_field import (
    Relief,
    ReliefError,
    ReliefParams,
    height_from_depth,
    relief_from_height_field,
)
from snapcore.render.bodies import DEFAULT_BODY, BodyKind, scene_body
from snapcore.render.buffers import DepthMap, render_depth
from snapcore.render.camera import view_basis
from snapcore.render.mannequin import TESSELLATION_FINE, PosedMesh, SceneBody

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from snapcore.motion.scene import Scene

__all__ = [
    "frame_extent",
    "relief_body",
    "height_field_from_scene",
    "relief_from_scene",
    "relief_comparison_figure",
]


def _index(scene: Scene, frame: int) -> int:
    """The internal index of source frame ``frame``, or a :class:`ReliefError`."""
    f = int(frame)
    first = int(scene.frame_offset)
    if not 0 <= f - first < scene.n_frames:
        raise ReliefError(
            f"frame {f} is not in the scene, which keeps source frames "
            f"{first}..{first + scene.n_frames - 1}"
        )
    return f - first


def frame_extent(
    vertices: np.ndarray,
    view: ArrayLike,
    *,
    size_mm: tuple[float, float] = (100.0, 100.0),
    margin: float = 0.05,
    up: ArrayLike | None = None,
) -> tuple[float, float]:
    """Half width and half height (metres) of an image with the footprint's aspect that holds the mesh.

    Parameters
    ----------
    vertices : ndarray of shape (N, 3)
        Posed mesh, metres.
    view : array of shape (3,)
        From the scene towards the viewer.
    size_mm : (float, float)
        Footprint ``(W, D)``; the image gets aspect ``W : D``.
    margin : float
        Flat border on every side as a share of the footprint's shorter side.
    up : array of shape (3,), optional
        Up hint (see :func:`snapcore.render.camera.view_basis`).

    Returns
    -------
    (float, float)
        ``(half_width, half_height)`` in metres: the mesh's projected bounding box fits
        inside the footprint less the margin, scaled uniformly (no stretching).
    """
    right, upv, _ = view_basis(view, up)
    v = np.asarray(vertices, float)
    bw = float(np.ptp(v @ right))
    bh = float(np.ptp(v @ upv))
    w, d = (float(s) for s in size_mm)
    border = 2.0 * margin * min(w, d)
    metres_per_mm = max(bw / (w - border), bh / (d - border), 1e-9)
    return metres_per_mm * w / 2.0, metres_per_mm * d / 2.0


def relief_body(scene: Scene, frame: int, *, body: BodyKind = DEFAULT_BODY) -> PosedMesh:
    """The body mesh a relief carves: every character at source frame ``frame``, finely
    tessellated (:data:`snapcore.render.mannequin.TESSELLATION_FINE`: a relief is read as geometry,
    and the facets of the rendering body would stand out as ridges in raking light), in the
    body kind ``body`` (:data:`snapcore.render.bodies.BodyKind`; by default the human
    mesh, smooth as it is).

    Returns
    -------
    snapcore.render.mannequin.PosedMesh
    """
    from snapcore.render.mannequin import CharacterBody

    mesh = scene_body(scene, TESSELLATION_FINE, kind=body)
    index = _index(scene, frame)
    if all(isinstance(b, CharacterBody) for b in mesh.characters):
        return mesh.pose(index)
    return _smoothed(mesh, index)


def _smoothed(body: SceneBody, index: int) -> PosedMesh:
    """The posed bodies with the human meshes Loop-subdivided once (4x the faces): their
    flat facets would otherwise show as ridges in the relief's raking light, as the
    mannequin's would without :data:`~snapcore.render.mannequin.TESSELLATION_FINE`. glTF
    meshes are carved as they are (a low-poly fox is faceted by design, and its
    unwelded triangles would come apart under subdivision)."""
    import trimesh

    from snapcore.motion.skinning import vertex_normals
    from snapcore.render.human import HumanBody
    from snapcore.render.mannequin import PosedMesh

    verts, faces, cols, who = [], [], [], []
    n0 = 0
    for i, b in enumerate(body.characters):
        v = np.asarray(b.vertices(index), float)
        f, c = b.faces, b.face_colors
        if isinstance(b, HumanBody):  # a closed, smooth mesh; glTF ones may be unwelded
            v, f = trimesh.remesh.subdivide_loop(v, f, iterations=1)
            c = np.repeat(b.face_colors[:1], len(f), axis=0)
        verts.append(v)
        faces.append(np.asarray(f) + n0)
        cols.append(c)
        who.append(np.full(len(f), i))
        n0 += len(v)
    v, f = np.vstack(verts), np.vstack(faces)
    return PosedMesh(v, f, np.vstack(cols), vertex_normals(v, f), np.concatenate(who))


def height_field_from_scene(
    scene: Scene,
    frame: int,
    view: ArrayLike,
    *,
    params: ReliefParams | None = None,
    up: ArrayLike | None = None,
    body: BodyKind = DEFAULT_BODY,
) -> DepthMap:
    """Orthographic depth render of all characters' body meshes at one frame.

    Parameters
    ----------
    scene : Scene
    frame : int
        Source frame (the file's own number, ``Snapshot.source_frame``).
    view : array of shape (3,)
        Unit vector from the scene centre towards the viewer (the snapshot's view).
    params : ReliefParams, optional
        ``size_mm`` (aspect), ``resolution`` and ``margin`` are used.
    up : array of shape (3,), optional
        Up hint for the image (default world +Y; see :func:`snapcore.render.camera.view_basis`).
    body : {"human", "mannequin"}
        What the characters wear (:data:`snapcore.render.bodies.BodyKind`).

    Returns
    -------
    snapcore.render.buffers.DepthMap
        ``depth`` in metres (NaN = background), ``pixel_size`` in metres, with the shape
        ``params.shape()``.
    """
    p = params or ReliefParams()
    mesh = relief_body(scene, frame, body=body)
    extent = frame_extent(mesh.vertices, view, size_mm=p.size_mm, margin=p.margin, up=up)
    ny, nx = p.shape()
    return render_depth(mesh.vertices, mesh.faces, view, resolution=(nx, ny), extent=extent, up=up)


def relief_from_scene(
    scene: Scene,
    frame: int,
    view: ArrayLike,
    *,
    params: ReliefParams | None = None,
    up: ArrayLike | None = None,
    body: BodyKind = DEFAULT_BODY,
) -> Relief:
    """The bas-relief of the scene's pose at ``frame`` seen along ``view``.

    Parameters
    ----------
    scene : Scene
        One or more characters (all are carved together).
    frame : int
        Source frame (the file's own number, ``Snapshot.source_frame``).
    view : array of shape (3,)
        From the scene centre towards the viewer.
    params : ReliefParams, optional
        Print box and compression settings (default :class:`ReliefParams`).
    up : array of shape (3,), optional
        Up hint for the image.
    body : {"human", "mannequin"}
        What the characters wear (:data:`snapcore.render.bodies.BodyKind`).

    Returns
    -------
    Relief
        ``meta`` holds ``frame`` (source numbering), ``view``, ``pixel_size_m``,
        ``scene`` and ``method``.

    Examples
    --------
    A 128-pixel relief of the synthetic walk's middle frame seen from the side, on the
    default 100 × 100 mm plate:

    >>> from snapcore import ReliefParams, relief_from_scene
    >>> from snapcore.motion.synth import synth_scene
    >>> relief = relief_from_scene(synth_scene("walk"), 45, [1.0, 0.0, 0.0],
    ...                            params=ReliefParams(resolution=128))
    >>> relief.height_mm.shape
    (128, 128)
    >>> bool(relief.mask.any()), float(relief.height_mm[~relief.mask].max())  # flat around
    (True, 0.0)
    >>> bool(relief.height_mm.max() <= relief.params.depth_mm)
    True
    """
    p = params or ReliefParams()
    dm = height_field_from_scene(scene, frame, view, params=p, up=up, body=body)
    height, mask = height_from_depth(dm.depth)
    v = np.asarray(view, float)
    meta = {
        "scene": getattr(scene, "name", None),
        "frame": int(frame),
        "view": (v / np.linalg.norm(v)).tolist(),
        "pixel_size_m": float(dm.pixel_size),
        "method": p.method,
        "size_mm": list(p.size_mm),
        "depth_mm": p.depth_mm,
        "base_mm": p.base_mm,
    }
    return relief_from_height_field(height, mask, pixel=dm.pixel_size, params=p, meta=meta)


def relief_comparison_figure(
    scene: Scene,
    frame: int,
    views: dict,
    *,
    params: ReliefParams | None = None,
    with_linear: bool = False,
    up: ArrayLike | None = None,
    title: str | None = None,
    panel_inches: float = 3.2,
    body: BodyKind = DEFAULT_BODY,
) -> Figure:
    """One pose carved from several views side by side (the paper's Fig. 11).

    Parameters
    ----------
    scene : Scene
    frame : int
        Source frame (the file's own number, as the title shows it).
    views : dict of str -> array of shape (3,)
        Panel name (e.g. the method: "ours (PMA)", "viewpoint entropy", "motion area")
        → view direction from the scene centre towards the viewer. Order is kept.
    params : ReliefParams, optional
        Relief settings (default :class:`ReliefParams` at 384 px for speed of figures).
    with_linear : bool
        Add a second row with the plain linear-compression relief of each view.
    up : array of shape (3,), optional
        Up hint for every panel.
    title : str, optional
        Figure title (default: scene name and source frame).
    panel_inches : float
        Width of one panel in inches.
    body : {"human", "mannequin"}
        What the characters wear (:data:`snapcore.render.bodies.BodyKind`).

    Returns
    -------
    matplotlib.figure.Figure
        Shaded previews (raking light, as :func:`snapcore.relief.mesh.shade_relief`),
        one column per view; each panel is titled with its name and view vector.
        The reliefs are in ``fig.reliefs`` (dict name → :class:`Relief`, and
        ``name + " (linear)"`` for the second row).
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    if not views:
        raise ReliefError("relief_comparison_figure: no views given")
    p = params or ReliefParams(resolution=384)
    rows = [p] + ([replace(p, method="linear")] if with_linear else [])
    w, d = p.size_mm
    title_inches = 0.55 if with_linear else 0.4  # room for 2-3 title lines above each panel
    fig, axes = plt.subplots(
        len(rows),
        len(views),
        squeeze=False,
        figsize=(
            panel_inches * len(views),
            len(rows) * (panel_inches * d / w + title_inches) + 0.4,
        ),
    )
    reliefs = {}
    for r, rp in enumerate(rows):
        for c, (name, view) in enumerate(views.items()):
            rel = relief_from_scene(scene, frame, view, params=rp, up=up, body=body)
            reliefs[name if r == 0 else f"{name} (linear)"] = rel
            ax = axes[r, c]
            ax.imshow(rel.shaded(), cmap="gray", vmin=0, vmax=1, interpolation="lanczos")
            ax.set_xticks([])
            ax.set_yticks([])
            vv = np.asarray(rel.meta["view"])
            label = f"{name}\nview ({vv[0]:+.2f}, {vv[1]:+.2f}, {vv[2]:+.2f})"
            if with_linear:
                label += "\nlinear" if r else "\ncompressed"
            ax.set_title(label, fontsize=9)
    src = int(frame)
    fig.suptitle(
        title
        or f"{getattr(scene, 'name', '') or 'scene'} — frame {src}: "
        f"{w:g} × {d:g} × {p.depth_mm:g} mm reliefs",
        fontsize=10,
    )
    fig.tight_layout()
    # matplotlib's Figure declares no such attribute: set it by name (documented above)
    setattr(fig, "reliefs", reliefs)  # noqa: B010
    return fig
