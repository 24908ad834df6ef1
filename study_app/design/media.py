"""The media of a scene's stimuli: the animation video (MP4 and WebM), the pickable
frames decoded from it, and the candidate view pictures.

Rendering uses ``snapcore.render.renderer`` (EGL, offline: see PLATFORM-NOTES, renderers
do not cross threads). Every picture of the study shows the default body.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from snapcore.select.view_methods import VIEW_METHODS

from .stimuli import PICK_KEYS, StimuliError

__all__ = [
    "FRAME_JPEG_QUALITY",
    "write_video",
    "write_frames",
    "view_renderer",
    "render_view",
    "contact_cue",
    "write_views",
    "shown_sheet",
]

#: JPEG quality of the pickable frames: visually lossless at study sizes, ~20 kB a frame.
FRAME_JPEG_QUALITY = 88


def write_video(
    scene,
    path: str | Path,
    *,
    fps: float,
    size: tuple[int, int],
    view=None,
    progress: bool = False,
    webm: str | Path | None = None,
) -> list[int]:
    """Stage 3: the animation video; returns the motion frame (source numbering) per video frame.

    ``webm``: also write the same frames as WebM/VP9 there (for browsers without H.264).

    ``view=None`` films from the renderer's neutral default (3/4 front of the
    characters' facing, slightly above): not from any of the three candidate views,
    so the video does not make one of them look familiar in the view task.
    """
    from snapcore.render.bodies import DEFAULT_BODY
    from snapcore.render.video import render_video

    # the study shows the default body everywhere (videos, views, and the
    # viewpoint-entropy baseline, ViewParams' default): no config option changes it
    vmap = render_video(
        scene, path, fps=fps, size=size, view=view, progress=progress, webm=webm, body=DEFAULT_BODY
    )
    return [int(m) for m in np.asarray(vmap, dtype=int)]


def write_frames(video: str | Path, folder: str | Path) -> list[Path]:
    """Stage 4: decode the video into one JPEG per frame (what the picker shows).

    Decoding the written video (instead of rendering again) makes each image exactly
    the frame the participant sees in the player.
    """
    import imageio.v3 as iio
    from PIL import Image

    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for i, frame in enumerate(
        iio.imiter(video, plugin="pyav") if _has_pyav() else iio.imiter(video)
    ):
        p = out / f"{i:05d}.jpg"
        Image.fromarray(np.asarray(frame)[..., :3]).save(p, quality=FRAME_JPEG_QUALITY)
        paths.append(p)
    if not paths:
        raise StimuliError(f"{video}: the video has no frames")
    return paths


def _has_pyav() -> bool:
    try:
        import av  # noqa: F401
    except ImportError:
        return False
    return True


def view_renderer(scene, size: tuple[int, int]):
    """The renderer of the candidate pictures: no floor and no shadows (see
    :func:`write_views`; :func:`render_view` adds the same contact shadow to each)."""
    from snapcore.render.bodies import DEFAULT_BODY
    from snapcore.render.renderer import SceneRenderer

    return SceneRenderer(scene, size=size, ground=False, shadows=False, body=DEFAULT_BODY)


#: The contact shadow under the figure in the candidate pictures: half axes as fractions
#: of the picture's width (across) and height (up and down), and its darkest shade, in
#: 0-255 levels under the background. Under the 30 levels at which
#: :func:`study_app.design.similarity.silhouette` counts a pixel as figure, so the
#: shadow is no part of the silhouettes compared.
CUE_HALF_WIDTH = 0.3
CUE_HALF_HEIGHT = 0.03
CUE_DEPTH = 24.0


def contact_cue(image: np.ndarray, centre, background) -> np.ndarray:
    """``image`` (H, W, 3) uint8 with a soft elliptical shadow centred at pixel
    ``centre`` (x, y) on its background pixels (the figure stays in front of it).

    The same ellipse, in size and shape, whatever the view: a floor or a shadow drawn
    in 3D is seen from above in one candidate, edge on in another and from below in a
    third, and the picture would tell the methods apart; a fixed flat ellipse says only
    that the figure stands on the ground there. It is kept inside the picture (2 px
    clear of the border), so every candidate has a plain border.
    """
    img = np.asarray(image[..., :3], float)
    h, w = img.shape[:2]
    rx, ry = CUE_HALF_WIDTH * w, max(CUE_HALF_HEIGHT * h, 1.5)
    cx = float(np.clip(centre[0], rx + 2, w - rx - 2))
    cy = float(np.clip(centre[1], ry + 2, h - ry - 2))
    yy, xx = np.mgrid[0:h, 0:w] + 0.5
    r = np.sqrt(((xx - cx) / rx) ** 2 + ((yy - cy) / ry) ** 2)
    shade = CUE_DEPTH * np.clip(1.0 - r, 0.0, 1.0) ** 0.7  # soft edge, darkest at the centre
    bg = np.round(np.asarray(background, float) * 255)
    plain = np.abs(img - bg).max(axis=-1) <= 3
    out = np.where(plain[..., None], img - shade[..., None], img)
    return np.clip(np.round(out), 0, 255).astype(np.uint8)


def render_view(scene, frame: int, direction, renderer) -> np.ndarray:
    """One candidate picture (source ``frame``, the file's own number), framed as all
    candidates are, with the contact shadow (:func:`contact_cue`) on the floor under the
    figure: the projection of the floor point under its lowest vertices."""
    from snapcore.render.camera import fit_camera
    from snapcore.render.renderer import BACKGROUND, render_still

    pts = np.asarray(renderer.body.vertices(frame - scene.frame_offset), float)
    camera = fit_camera(pts, direction, size=renderer.size)
    image = render_still(scene, frame, camera=camera, renderer=renderer)
    low = pts[pts[:, 1] <= np.percentile(pts[:, 1], 2.0)]
    under = np.array([low[:, 0].mean(), scene.ground, low[:, 2].mean()])
    return contact_cue(image, camera.project(under), BACKGROUND)


def write_views(
    scene, picks: dict, folder: str | Path, *, size: tuple[int, int], renderer=None
) -> dict:
    """Stage 5: the selected pose seen along each method's direction (same size and framing).

    Returns
    -------
    dict
        ``{method: {"file": Path, "direction": [x, y, z]}}`` for each of
        :data:`~snapcore.select.view_methods.VIEW_METHODS`.
    """
    from snapcore.render.renderer import save_png

    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    directions = {m: picks[PICK_KEYS[m]] for m in VIEW_METHODS}
    frame = int(picks["frame"])
    # Same size and the same framing rule for all three (the pose fitted tightly with
    # the same margin from each direction), so no view wins by being bigger. No floor
    # and no shadows: a tightly framed orthographic view shows the floor grid from
    # above, nothing of it near the horizon and the grid through the legs from below
    # (the methods may pick views down to 10 degrees under the horizon), so the
    # background alone would tell the three methods apart. What tells a viewer that the
    # figure stands on the ground is one flat contact shadow, the same in every
    # candidate (render_view, contact_cue).
    renderer = renderer or view_renderer(scene, size)
    views = {}
    for m in VIEW_METHODS:
        p = out / f"view_{m}.png"
        save_png(render_view(scene, frame, directions[m], renderer), p)
        views[m.value] = {"file": p, "direction": directions[m]}
    return views


def shown_sheet(manifest: dict, folder: str | Path, path: str | Path) -> Path:
    """A sheet of every scene's view-task pictures as shown, one row per scene, each
    picture titled with the methods it stands for (alike candidates merged), a scene
    without a view task marked so: to look at what participants compare.

    Parameters
    ----------
    manifest : dict
        The stimuli manifest (:attr:`~study_app.design.stimuli.Stimuli.manifest`).
    folder : path
        The stimuli folder (the manifest's paths are relative to it).
    path : path
        The PNG to write.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from PIL import Image

    root = Path(folder)
    scenes = manifest["scenes"]
    fig, axes = plt.subplots(len(scenes), 3, figsize=(9, 2.6 * len(scenes)), squeeze=False)
    for row, e in enumerate(scenes):
        groups = e.get("shown") or [[m.value] for m in VIEW_METHODS]
        for col, ax in enumerate(axes[row]):
            ax.axis("off")
            if col < len(groups):
                ax.imshow(Image.open(root / e["views"][groups[col][0]]["file"]))
                ax.set_title(" = ".join(m.replace("_", " ") for m in groups[col]), fontsize=9)
        note = "view task skipped" if e.get("view_task") == "skipped" else f"{len(groups)} pictures"
        axes[row][0].text(
            -0.05,
            0.5,
            f"{e['id']}\n({note})",
            transform=axes[row][0].transAxes,
            ha="right",
            va="center",
            fontsize=10,
        )
    fig.suptitle(
        f"Study {(manifest['study'].get('study') or {}).get('id', '')}: the pictures each "
        "view task shows, "
        "titled with the methods each stands for",
        fontsize=10,
    )
    fig.tight_layout()
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=80)
    plt.close(fig)
    return out
