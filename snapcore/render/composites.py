"""Composite figures: a contact sheet of poses and views side by side.

- :func:`contact_sheet` — the top-k poses of a clip in a row (the paper's Fig. 5 strip):
  one panel per frame, all from one view and at one scale, labelled with the source
  frame number, the time and (optionally) the pose entropy.
- :func:`compare_views` — one pose seen from several directions (the paper's Fig. 8-10:
  ours / viewpoint entropy / motion area), labelled, same panel size and the same scale
  (metres per pixel) in every panel, each centred on the pose, so no view looks better
  by being bigger.

Both return an (H, W, 3) uint8 image; :func:`snapcore.render.renderer.save_png` writes it.
Frames are *source* frames, the file's own numbers (``Snapshot.source_frames``, the
JSON's ``frames``), as the captions show them.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from snapcore.errors import RenderError
from snapcore.render.bodies import DEFAULT_BODY, BodyKind
from snapcore.render.camera import (
    FRAME_MARGIN,
    Camera,
    check_size,
    default_view,
    fit_camera,
    view_basis,
)
from snapcore.render.renderer import ORTHO_HORIZON_DEG, SceneRenderer, scene_index
from snapcore.select.view_methods import view_label

if TYPE_CHECKING:
    from snapcore.motion.scene import Scene

__all__ = [
    "contact_sheet",
    "compare_views",
    "common_cameras",
    "floor_aligned",
    "floor_contacts",
    "tile_panels",
    "PANEL_GAP",
    "CAPTION_HEIGHT",
]

#: Pixels between panels.
PANEL_GAP = 8
#: Caption strip under each panel, as a fraction of the panel height.
CAPTION_HEIGHT = 0.11
_PAPER = (255, 255, 255)
_INK = (35, 35, 35)


def common_cameras(
    points_per_panel: Sequence[np.ndarray],
    views: Sequence[ArrayLike],
    *,
    size: tuple[int, int],
    projection: str = "orthographic",
    margin: float | None = None,
) -> list[Camera]:
    """One camera per panel, all at the same scale, each centred on its own points.

    Parameters
    ----------
    points_per_panel : list of array of shape (P_i, 3)
    views : list of array of shape (3,)
    size : (int, int)
    projection : {"orthographic", "perspective"}
        Orthographic panels share metres per pixel; perspective panels share the
        camera distance (the largest any panel needs).

    Returns
    -------
    list of Camera
    """
    kw = {} if margin is None else {"margin": margin}
    cams = [
        fit_camera(p, v, size=size, projection=projection, **kw)
        for p, v in zip(points_per_panel, views)
    ]
    if projection == "orthographic":
        from dataclasses import replace

        # fit_camera with half_height=hh: the same camera with only its half-height
        # set (an orthographic fit's place and depth range do not depend on it)
        hh = float(max(c.half_height for c in cams))
        return [replace(c, half_height=hh) for c in cams]
    targets = [_target(c, p) for c, p in zip(cams, points_per_panel)]
    dists = [float(np.linalg.norm(c.position - t)) for c, t in zip(cams, targets)]
    d = max(dists)
    return [
        Camera(
            t + c.back * d,
            c.right,
            c.up,
            c.back,
            c.size,
            c.projection,
            c.half_height,
            c.yfov,
            max(c.znear + d - di, 0.02),
            c.zfar + d - di,
        )
        for c, t, di in zip(cams, targets, dists)
    ]


def floor_aligned(
    cams: list[Camera],
    points_per_panel: Sequence[np.ndarray],
    feet: Sequence[np.ndarray],
    *,
    margin: float | None = None,
) -> list[Camera]:
    """Orthographic cameras of one view moved up or down so that every panel's floor
    point (``feet[i]``, on the floor under panel i's pose) falls on the same image row.

    A contact sheet of a jump then shows the floor as one line across the panels and
    the jump as height above it; each panel stays centred left-right on its own pose.
    The half-height grows where the aligned poses need more room, so all panels keep
    one scale. Perspective cameras are returned unchanged.
    """
    if not cams or cams[0].projection != "orthographic":
        return cams

    up = cams[0].up
    fill = max(1.0 - 2.0 * (FRAME_MARGIN if margin is None else margin), 0.05)
    # each pose's vertical extent measured from its own floor point
    rel = [
        np.asarray(p, float).reshape(-1, 3) @ up - float(np.asarray(f, float) @ up)
        for p, f in zip(points_per_panel, feet)
    ]
    lo = min(float(r.min()) for r in rel)
    hi = max(float(r.max()) for r in rel)
    hh = max(max(c.half_height for c in cams), (hi - lo) / 2 / fill)
    out = []
    for c, f in zip(cams, feet):
        # image centre at the same height above each panel's floor point
        shift = (float(np.asarray(f, float) @ up) + (lo + hi) / 2) - float(c.position @ up)
        out.append(
            Camera(
                c.position + up * shift,
                c.right,
                c.up,
                c.back,
                c.size,
                c.projection,
                hh,
                c.yfov,
                c.znear,
                c.zfar,
            )
        )
    return out


def floor_contacts(pts: np.ndarray, ground: float, cams: list[Camera]) -> list[np.ndarray]:
    """Per camera, the floor point under the pose that its picture shows lowest: of the
    pose's points within :data:`CONTACT_M` of its lowest (the feet that stand), the one
    lowest along the camera's up, dropped onto the floor ``y = ground``. Where a
    "horizon" picture puts its horizon, every standing figure's feet are on it (for a
    pair, the nearer one's in a view from above)."""
    p = np.asarray(pts, float).reshape(-1, 3)
    low = p[p[:, 1] <= p[:, 1].min() + CONTACT_M]
    out = []
    for c in cams:
        f = low[np.argmin(low @ c.up)].copy()
        f[1] = ground
        out.append(f)
    return out


#: Points of a pose this close to its lowest (metres) stand on the floor.
CONTACT_M = 0.03


def _horizon_aligned(
    cams: list[Camera], pts: np.ndarray, feet: Sequence[np.ndarray]
) -> list[Camera]:
    """Orthographic cameras moved along their own up so each panel's floor point
    ``feet[i]`` (where the renderer's horizon passes) falls on the same image row: one
    horizon across panels of different views. The half-height grows as needed to keep
    the pose inside the margin, the same for all panels."""
    if not cams or cams[0].projection != "orthographic":
        return cams
    p = np.asarray(pts, float).reshape(-1, 3)
    feet = [np.asarray(f, float) for f in feet]
    fill = max(1.0 - 2.0 * FRAME_MARGIN, 0.05)
    # per panel: the pose's extent along the camera's up, measured from the floor point
    rel = [(p - f) @ c.up for c, f in zip(cams, feet)]
    lo, hi = min(float(r.min()) for r in rel), max(float(r.max()) for r in rel)
    hh = max(max(c.half_height for c in cams), (hi - lo) / 2 / fill)
    out = []
    for c, foot in zip(cams, feet):
        shift = (float(foot @ c.up) + (lo + hi) / 2) - float(c.position @ c.up)
        out.append(
            Camera(
                c.position + c.up * shift,
                c.right,
                c.up,
                c.back,
                c.size,
                c.projection,
                hh,
                c.yfov,
                c.znear,
                c.zfar,
            )
        )
    return out


def _target(cam: Camera, pts: np.ndarray) -> np.ndarray:
    """The point a fitted camera looks at (centre of the points along its axis)."""
    p = np.asarray(pts, float).reshape(-1, 3)
    z = p @ cam.back
    zc = (z.min() + z.max()) / 2
    return cam.position - cam.back * (cam.position @ cam.back - zc)


def _font(px: int) -> Any:
    from PIL import ImageFont

    return ImageFont.load_default(size=max(int(px), 8))


def _wrap(text: str, font: Any, width: int) -> list[str]:
    """``text`` broken into lines no wider than ``width`` pixels in ``font``: at
    spaces, and inside a word only where the word alone is wider."""
    lines: list[str] = []
    line = ""
    for word in text.split():
        while font.getlength(word) > width and len(word) > 1:
            if line:
                lines.append(line)
                line = ""
            fits = [k for k in range(2, len(word)) if font.getlength(word[:k]) <= width]
            cut = fits[-1] if fits else 1
            lines.append(word[:cut])
            word = word[cut:]
        trial = f"{line} {word}" if line else word
        if line and font.getlength(trial) > width:
            lines.append(line)
            line = word
        else:
            line = trial
    if line:
        lines.append(line)
    return lines


def tile_panels(
    panels: Sequence[np.ndarray],
    captions: Sequence[str | Sequence[str]] | None = None,
    *,
    columns: int | None = None,
    title: str | None = None,
) -> np.ndarray:
    """Lay out equally sized (H, W, 3) uint8 panels in a grid with captions under each.

    Parameters
    ----------
    panels : list of ndarray (H, W, 3)
    captions : list of str or list of list of str, optional
        One caption per panel (several lines allowed as a list).
    columns : int, optional
        Panels per row (default: all in one row).
    title : str, optional
        A line above the grid (wrapped onto more lines where wider than the grid).

    Returns
    -------
    ndarray of uint8, shape (H_total, W_total, 3)
    """
    from PIL import Image, ImageDraw

    if not panels:
        raise RenderError("no panels to lay out")
    h, w = panels[0].shape[:2]
    if any(p.shape[:2] != (h, w) for p in panels):
        raise RenderError("panels must all have the same size")
    n = len(panels)
    cols = n if columns is None else max(1, min(int(columns), n))
    rows = -(-n // cols)
    cap_h = int(round(h * CAPTION_HEIGHT)) if captions is not None else 0
    lines = []
    if captions is not None:
        lines = [c if isinstance(c, (list, tuple)) else [c] for c in captions]
        cap_h = max(cap_h, int(round(h * 0.055 * max(len(x) for x in lines) + h * 0.035)))
    gap = PANEL_GAP
    W = cols * w + (cols + 1) * gap
    fpx = max(int(h * 0.045), 11)
    font = _font(fpx)
    tf = _font(int(fpx * 1.2))
    # a title wider than the sheet is wrapped onto more lines (it was cut off)
    title_lines = _wrap(str(title), tf, W - 2 * gap) if title else []
    step = int(round(fpx * 1.2 * 1.3))
    title_h = max(int(round(h * 0.10)), len(title_lines) * step + gap) if title else 0
    H = title_h + rows * (h + cap_h) + (rows + 1) * gap
    sheet = Image.new("RGB", (W, H), _PAPER)
    draw = ImageDraw.Draw(sheet)
    top = gap + (title_h - len(title_lines) * step) // 2
    for k, text in enumerate(title_lines):
        draw.text((gap, top + k * step + step // 2), text, fill=_INK, font=tf, anchor="lm")
    for i, p in enumerate(panels):
        r, c = divmod(i, cols)
        x = gap + c * (w + gap)
        y = title_h + gap + r * (h + cap_h + gap)
        sheet.paste(Image.fromarray(np.asarray(p, np.uint8)), (x, y))
        if lines:
            for k, text in enumerate(lines[i]):
                f = _font(int(fpx * 1.1)) if k == 0 else font
                draw.text(
                    (x + w // 2, y + h + int(fpx * 0.4) + k * int(fpx * 1.35)),
                    str(text),
                    fill=_INK if k == 0 else (90, 90, 90),
                    font=f,
                    anchor="ma",
                )
    return np.asarray(sheet)


def contact_sheet(
    scene: Scene,
    frames: Sequence[int],
    *,
    view: ArrayLike | None = None,
    entropy: Sequence[float] | np.ndarray | None = None,
    size: tuple[int, int] = (480, 540),
    projection: str = "orthographic",
    columns: int | None = None,
    title: str | None = None,
    labels: bool = True,
    ranked: bool = True,
    ground: bool = True,
    shadows: bool = True,
    captions: Sequence[str | Sequence[str]] | None = None,
    body: BodyKind = DEFAULT_BODY,
) -> np.ndarray:
    """Poses of a clip side by side, one view, one scale, the floor on one row across
    the panels (the paper's Fig. 5 strip).

    Parameters
    ----------
    scene : Scene
    frames : sequence of int
        Source frames (the file's own numbers, ``Snapshot.source_frames``), in display
        order (e.g. the top-k poses, best first).
    view : array of shape (3,), optional
        From the scene to the camera; default :func:`snapcore.render.camera.default_view`.
    entropy : sequence of float, optional
        The paper's pose entropy of each frame (same order as ``frames``), shown in the
        caption as ``entropy <value>``.
    captions : sequence of str, optional
        Instead of ``entropy``: a caption per frame naming its score in the pose
        method's own terms (:meth:`snapcore.select.pose_selection.PoseScores.caption`, e.g.
        ``story 14.9 bits``).
    size : (int, int)
        Size of each panel, pixels.
    projection : {"orthographic", "perspective"}
    columns : int, optional
        Panels per row (default one row).
    title : str, optional
    labels : bool
        Caption each panel with ``#rank``, source frame number, time and entropy.
    ranked : bool
        ``frames`` are ranked (best first) and captions start with ``#1``, ``#2``...;
        False for frames picked by hand (no rank shown).
    ground, shadows : bool
    body : {"human", "mannequin"}
        What the characters wear (:data:`snapcore.render.bodies.BodyKind`).

    Returns
    -------
    ndarray of uint8, shape (H, W, 3)

    Examples
    --------
    Three poses of the synthetic walk in one row of 120 × 160 pixel panels:

    >>> from snapcore import contact_sheet
    >>> from snapcore.motion.synth import synth_scene
    >>> sheet = contact_sheet(synth_scene("walk"), [0, 45, 90], size=(120, 160))
    >>> sheet.dtype.name, sheet.shape[1] >= 3 * 120, sheet.shape[0] >= 160
    ('uint8', True, True)
    """
    size = check_size(size)
    frames = [int(f) for f in np.asarray(frames).reshape(-1)]
    if not frames:
        raise RenderError("contact_sheet needs at least one frame")
    indices = [scene_index(scene, f) for f in frames]
    if entropy is not None and len(entropy) != len(frames):
        raise RenderError(f"entropy has {len(entropy)} values for {len(frames)} frames")
    if captions is not None and len(captions) != len(frames):
        raise RenderError(f"captions has {len(captions)} values for {len(frames)} frames")
    if captions is None and entropy is not None:
        captions = [f"entropy {float(e):.3g}" for e in entropy]
    if view is None:
        view = default_view(scene)
    view_basis(view)  # validates
    sr = SceneRenderer(scene, size=size, ground=ground, shadows=shadows, body=body)
    pts = [sr.body.vertices(i) for i in indices]
    cams = common_cameras(pts, [view] * len(frames), size=size, projection=projection)
    # the floor on one row across the panels: under each pose's mean root position
    feet = [np.mean([c.positions[i, 0] for c in scene.characters], axis=0) for i in indices]
    for ft in feet:  # fresh arrays from np.mean: set their height in place
        ft[1] = scene.ground
    cams = floor_aligned(cams, pts, feet)
    panels = [sr.render(i, c) for i, c in zip(indices, cams)]
    lines = None
    if labels:
        lines = []
        for k, (f, i) in enumerate(zip(frames, indices)):
            first = (f"#{k + 1}   " if ranked else "") + f"frame {f}"
            second = f"{i / scene.fps:.2f} s"
            if captions is not None:
                second += f"   {captions[k]}"
            lines.append([first, second])
    return tile_panels(panels, lines, columns=columns, title=title)


def compare_views(
    scene: Scene,
    frame: int,
    views: Mapping[str, ArrayLike],
    *,
    size: tuple[int, int] = (480, 540),
    projection: str = "orthographic",
    columns: int | None = None,
    title: str | None = None,
    labels: bool = True,
    ground: bool = True,
    shadows: bool = True,
    captions: dict | None = None,
    body: BodyKind = DEFAULT_BODY,
) -> np.ndarray:
    """One pose from several directions, side by side (the paper's Fig. 8-10).

    Parameters
    ----------
    scene : Scene
    frame : int
        Source frame (the file's own number, ``Snapshot.source_frame``).
    views : dict of ViewMethod or str to array of shape (3,)
        Panel → view direction (scene to camera), in display order: keyed by
        :class:`~snapcore.select.view_methods.ViewMethod` (``Snapshot.views``; the panel
        shows its label, e.g. "viewpoint entropy") or by a free-form name shown as is.
    size : (int, int)
        Size of each panel, pixels (the same for all).
    projection : {"orthographic", "perspective"}
    columns : int, optional
        Panels per row (default one row).
    title : str, optional
    labels : bool
        Caption each panel with its label and direction.
    ground, shadows : bool
    captions : dict of ViewMethod or str to str, optional
        Extra caption line per key of ``views`` (e.g. a score).
    body : {"human", "mannequin"}
        What the characters wear (:data:`snapcore.render.bodies.BodyKind`).

    Returns
    -------
    ndarray of uint8, shape (H, W, 3)

    Notes
    -----
    Same framing in every panel: one scale for all panels (the largest any single view
    needs to fit the pose with the standard margin), each centred on the pose.

    Examples
    --------
    One pose of the synthetic walk from the side and from the front, two panels in a row:

    >>> from snapcore import compare_views
    >>> from snapcore.motion.synth import synth_scene
    >>> views = {"side": [1.0, 0.0, 0.0], "front": [0.0, 0.0, 1.0]}
    >>> image = compare_views(synth_scene("walk"), 45, views, size=(120, 160))
    >>> image.dtype.name, image.shape[1] >= 2 * 120, image.shape[0] >= 160
    ('uint8', True, True)
    """
    size = check_size(size)
    index = scene_index(scene, frame)
    if not views:
        raise RenderError("compare_views needs at least one view")
    names = list(views)
    dirs = []
    for name in names:
        r, u, b = view_basis(views[name])
        dirs.append(b)
    # One background for every panel: a view under the floor or nearly level cannot show
    # the grid (it would cut through the legs, or be a row of dashes), so then none of
    # them does, each showing the floor as a horizon at the feet instead.
    low = [float(np.degrees(np.arcsin(np.clip(d[1], -1, 1)))) < ORTHO_HORIZON_DEG for d in dirs]
    floor = "horizon" if ground and any(low) else "auto"
    sr = SceneRenderer(scene, size=size, ground=ground, shadows=shadows, floor=floor, body=body)
    pts = sr.body.vertices(index)
    cams = common_cameras([pts] * len(dirs), dirs, size=size, projection=projection)
    feet = floor_contacts(pts, scene.ground, cams)
    if floor == "horizon":
        # each panel's horizon at its own figure's feet (the floor under the middle of
        # the motion is elsewhere: a dancer 50 px above it in a view from above)
        cams = _horizon_aligned(cams, pts, feet)
    panels = []
    for c, foot in zip(cams, feet):
        sr.horizon_point = foot
        panels.append(sr.render(index, c))
    caps = None
    if labels:
        caps = []
        for name, d in zip(names, dirs):
            line2 = f"view ({d[0]:+.2f}, {d[1]:+.2f}, {d[2]:+.2f})"
            if captions and name in captions:
                line2 = f"{captions[name]}   {line2}"
            caps.append([view_label(name), line2])
    if title is None and labels:
        title = f"{scene.name}: frame {int(frame)} ({index / scene.fps:.2f} s)"
    return tile_panels(panels, caps, columns=columns, title=title)
