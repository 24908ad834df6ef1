"""``snapshot render``, ``snapshot video`` and ``snapshot sheet``: pictures of a scene.

Frame numbers on the command line and in every output are SOURCE frame numbers (as in
the BVH file; ``snapshot select`` prints the same numbers), as the drawing functions
take them; each is checked against the frames the scene keeps first (one line, exit 2).
"""

from __future__ import annotations

import json
import sys
import warnings
from pathlib import Path

import click
import numpy as np

from snapcore.cli.common import (
    POSITIVE,
    FiniteFloatRange,
    body_option,
    body_options,
    internal_frame,
    output_callback,
    parse_vector,
    refuse_inputs,
    scene_arguments,
    scene_from_options,
    view_callback,
)
from snapcore.render.bodies import DEFAULT_BODY, BodyKind
from snapcore.select.view_methods import ViewMethod

__all__ = ["render", "video", "sheet", "parse_size", "pipeline_picks"]


def parse_size(text: str, name: str = "--size") -> tuple[int, int]:
    """Parse ``"1280x720"`` into ``(1280, 720)``, with a one-line error naming ``name``."""
    try:
        w, h = (int(t) for t in text.lower().replace("×", "x").split("x"))
    except ValueError:
        raise click.BadParameter(
            f"expected WIDTHxHEIGHT like 1280x720, got '{text}'", param_hint=name
        ) from None
    if not (8 <= w <= 8192 and 8 <= h <= 8192):
        raise click.BadParameter(
            f"width and height must be 8..8192 pixels, got '{text}'", param_hint=name
        )
    return w, h


def _note(text: str) -> None:
    click.echo(text, err=True)


def _frame_option(scene, frame, *, views: bool, body: BodyKind = DEFAULT_BODY):
    """The source frame of ``--frame`` (checked against the scene), else the selected pose's.

    Returns ``(frame, picks)``; ``picks`` is the pipeline's result when it ran, else None.
    """
    if frame is not None:
        internal_frame(scene, frame)  # a frame the scene does not keep: one line, exit 2
        return int(frame), None
    picks = pipeline_picks(scene, views=views, body=body)
    _note(f"frame {picks['frame']} ({picks['how']})")
    return picks["frame"], picks


def pipeline_picks(
    scene,
    *,
    k: int = 3,
    views: bool = True,
    baselines: bool = True,
    body: BodyKind = DEFAULT_BODY,
) -> dict:
    """What the pipeline (:func:`snapcore.pipeline.take_snapshot`) picks for a scene.

    ``views=False`` skips the view stage, ``baselines=False`` the two baseline views
    (viewpoint entropy renders the ``body`` kind: the slow part). The pipeline's warnings (a
    static clip, a skipped baseline) are silenced: pictures only need the picks.

    Returns
    -------
    dict
        ``frame`` (source numbering), ``frames`` (top-k, source numbering), ``index`` and
        ``indices`` (the same into the scene's arrays), ``captions`` (each
        pick's score in its method's terms, :meth:`PoseScores.caption`), ``views``
        (unit vectors by :class:`~snapcore.select.view_methods.ViewMethod`, those
        computed), ``how`` (one line).
    """
    from snapcore.pipeline import ViewParams, take_snapshot
    from snapcore.select.pose_methods import PoseParams

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        snap = take_snapshot(
            scene,
            pose=PoseParams(k=k),
            view=ViewParams(baselines=baselines, body=body) if views else None,
        )
    sc = snap.pose.scores
    out = {
        "frame": snap.source_frame,
        "frames": snap.source_frames,
        "index": int(snap.index),
        "indices": [int(i) for i in snap.indices],
        "captions": [sc.caption(sc.total[i]) for i in snap.indices],
        "views": {},
        "how": "selected pose",
    }
    if not views:
        return out
    out["views"] = {m: v / np.linalg.norm(v) for m, v in snap.views.items()}
    return out


def _view_option(value, scene, *, default="auto"):
    """Resolve a --view value: a unit vector (parsed by :func:`.common.view_callback`),
    'auto' (the selected view) or 'default' (3/4)."""
    from snapcore.render.camera import default_view

    value = default if value is None else value
    if isinstance(value, str) and value == "default":
        return default_view(scene), "default 3/4 view"
    if isinstance(value, str) and value == "auto":
        view = pipeline_picks(scene, baselines=False)["views"][ViewMethod.OURS]
        return view, "selected view (projected motion area)"
    if isinstance(value, str):
        value = parse_vector(value, "--view")
    return np.asarray(value, float), "given view"


def _size_callback(ctx, param, value):
    try:
        return parse_size(value)
    except click.BadParameter as err:  # name the option as click does for its own errors
        raise click.BadParameter(err.message, param=param) from None


def _frame_range_callback(ctx, param, value):
    """``--frames A:B`` → ``(A, B)`` source frames (checked against the scene later)."""
    if value is None:
        return None
    try:
        a, b = (int(t) for t in value.split(":"))
    except ValueError:
        raise click.BadParameter(
            f"expected A:B source frames, got '{value}'", param=param
        ) from None
    if b < a:
        raise click.BadParameter(f"B must not be before A, got '{value}'", param=param)
    return a, b


def _render_options(f):
    opts = [
        click.option(
            "--perspective", is_flag=True, help="Perspective camera (default: orthographic)."
        ),
        click.option("--no-ground", is_flag=True, help="No floor grid (and no shadows)."),
        click.option("--no-shadows", is_flag=True, help="No shadows on the floor."),
    ]
    for opt in reversed(opts):
        f = opt(f)
    return f


@click.command()
@scene_arguments
@click.option(
    "--frame",
    type=int,
    default=None,
    metavar="N",
    help="Source frame number (as in the BVH file). Default: the selected pose.",
)
@click.option(
    "--view",
    default=None,
    metavar="x,y,z|auto|default",
    callback=view_callback,
    help="Direction from the scene to the camera (Y up), 'auto' = the selected "
    "view (projected motion area) [default], 'default' = a 3/4 front view.",
)
@click.option(
    "-o",
    "--output",
    type=click.Path(dir_okay=False),
    required=True,
    callback=output_callback(".png"),
    help="PNG file to write (.png).",
)
@click.option(
    "--size",
    default="1280x720",
    show_default=True,
    metavar="WxH",
    callback=_size_callback,
    help="Image size in pixels.",
)
@click.option(
    "--fit",
    type=click.Choice(["frame", "motion"]),
    default="frame",
    show_default=True,
    help="Frame the pose tightly, or the whole motion (as videos do).",
)
@_render_options
def render(paths, fps, scale, frame, view, output, size, fit, perspective, no_ground, no_shadows):
    """Render one frame of a scene to a PNG.

    \b
    Example:
      snapshot render walk_run/02_01.bvh --frame 120 --view 1,0.3,0.4 -o pose.png
    """
    from snapcore.render.renderer import render_still, save_png

    w, h = size
    scene = scene_from_options(paths, fps, scale)
    f, _ = _frame_option(scene, frame, views=False)
    v, how = _view_option(view, scene)
    _note(f"view {np.round(v, 3).tolist()} ({how})")
    img = render_still(
        scene,
        f,
        v,
        size=(w, h),
        projection="perspective" if perspective else "orthographic",
        fit=fit,
        ground=not no_ground,
        shadows=not (no_shadows or no_ground),
        body=body_option(),
    )
    save_png(img, output)
    click.echo(output)


@click.command()
@click.argument("paths", nargs=-1, required=True, type=click.Path(dir_okay=False))
@click.option(
    "-o",
    "--output",
    type=click.Path(dir_okay=False),
    required=True,
    callback=output_callback(".mp4"),
    help="MP4 file to write (.mp4; H.264, yuv420p, faststart).",
)
@click.option(
    "--fps",
    "video_fps",
    type=FiniteFloatRange(min=1, max=240),
    default=24.0,
    show_default=True,
    help="Frame rate of the VIDEO; the motion is resampled (nearest frame).",
)
@click.option(
    "--motion-fps",
    "fps",
    type=POSITIVE,
    default=None,
    help="Frame rate override for the MOTION (what --fps means in the other "
    "commands; some headers are wrong, e.g. CMU salsa is 60).",
)
@click.option(
    "--scale",
    type=POSITIVE,
    default=None,
    help="Metres per file unit (default: inferred from the characters' stature).",
)
@click.option(
    "--size",
    default="1280x720",
    show_default=True,
    metavar="WxH",
    callback=_size_callback,
    help="Video size in pixels (even numbers).",
)
@click.option(
    "--view",
    default=None,
    metavar="x,y,z|auto|default",
    callback=view_callback,
    help="Direction from the scene to the camera. Default: 'default' = a neutral "
    "3/4 front view; 'auto' = the selected view.",
)
@click.option(
    "--frames",
    "frame_range",
    default=None,
    metavar="A:B",
    callback=_frame_range_callback,
    help="Only the span of source frames A..B (inclusive), resampled to the "
    "video's rate by nearest frame: at a lower rate the last frame shown "
    "may fall a little before B (see --frame-map).",
)
@click.option("--frame-numbers", is_flag=True, help="Print source frame number and time.")
@click.option(
    "--frame-map",
    type=click.Path(dir_okay=False),
    default=None,
    callback=output_callback(".json", what="the frame map is written as"),
    help="Also write the video-frame → source-frame map as JSON (.json; "
    "data_schema/frame_map.schema.json).",
)
@click.option(
    "--detail",
    type=click.Choice(["reduced", "full"]),
    default="reduced",
    show_default=True,
    help="Human bodies: the reduced mesh (a third of the triangles, the same picture "
    "at video sizes, ~40%% faster) or the full one (close-ups).",
)
@click.option("-q", "--quiet", is_flag=True, help="No progress bar.")
@body_options
@_render_options
def video(
    paths,
    output,
    video_fps,
    fps,
    scale,
    size,
    view,
    frame_range,
    frame_numbers,
    frame_map,
    detail,
    quiet,
    perspective,
    no_ground,
    no_shadows,
):
    """Render a scene to an H.264 MP4 that plays in Chrome and Firefox.

    One fixed camera frames the whole motion. Prints the number of video frames; the
    frame map (which source frame each video frame shows) goes to --frame-map.
    Note: here --fps is the VIDEO's rate; the motion's is --motion-fps.

    \b
    Example:
      snapshot video two_person/60_01_scaled.bvh two_person/61_01_scaled.bvh \\
          --motion-fps 60 -o salsa.mp4 --fps 30 --frame-numbers
    """
    from snapcore.render.video import render_video

    w, h = size
    if w % 2 or h % 2:
        raise click.BadParameter(
            f"video width and height must be even, got {w}x{h}", param_hint="--size"
        )
    refuse_inputs(paths, **{"--frame-map": frame_map})
    scene = scene_from_options(paths, fps, scale)
    rng = None
    if frame_range:
        a, b = frame_range
        internal_frame(scene, a, "--frames")  # frames the scene does not keep: one line
        internal_frame(scene, b, "--frames")
        rng = (a, b + 1)
    v, how = _view_option(view, scene, default="default")
    if not quiet:
        _note(f"view {np.round(v, 3).tolist()} ({how})")
    fmap = render_video(
        scene,
        output,
        fps=video_fps,
        size=(w, h),
        view=v,
        projection="perspective" if perspective else "orthographic",
        frame_numbers=frame_numbers,
        progress=not quiet,
        frame_range=rng,
        ground=not no_ground,
        shadows=not (no_shadows or no_ground),
        body=body_option(),
        detail=detail,
    )
    if frame_map:
        doc = {
            "video": str(output),
            "fps": float(video_fps),
            "size": [w, h],
            "motion_fps": float(scene.fps),
            "source_frames": [int(x) for x in fmap],
        }
        from snapcore.schema import validate

        validate(doc, "frame_map", source="snapshot video frame map")
        Path(frame_map).write_text(json.dumps(doc) + "\n")
    click.echo(
        f"{output}: {len(fmap)} frame{'s' if len(fmap) != 1 else ''} at {video_fps:g} fps "
        f"(source frames {int(fmap[0])}..{int(fmap[-1])})"
    )


def _parse_frames(text: str) -> list[int]:
    try:
        return [int(t) for t in text.split(",") if t.strip()]
    except ValueError:
        raise click.BadParameter(
            f"expected source frame numbers like 120,340,560, got '{text}'", param_hint="--frames"
        ) from None


def _parse_named_view(text: str) -> tuple[str, np.ndarray]:
    if "=" not in text:
        raise click.BadParameter(f"expected NAME=x,y,z, got '{text}'", param_hint="--views")
    name, vec = text.split("=", 1)
    return name.strip(), parse_vector(vec, "--views")


def _named_views_callback(ctx, param, values):
    try:
        return [_parse_named_view(t) for t in values]
    except click.BadParameter as err:
        raise click.BadParameter(err.message, param=param) from None


def _frames_callback(ctx, param, value):
    return None if value is None else _parse_frames(value)


@click.command()
@scene_arguments
@click.option(
    "-o",
    "--output",
    type=click.Path(dir_okay=False),
    required=True,
    callback=output_callback(".png"),
    help="PNG file to write (.png).",
)
@click.option(
    "--frames",
    "frames",
    default=None,
    metavar="A,B,C",
    callback=_frames_callback,
    help="Contact sheet of these source frames (default: the top poses).",
)
@click.option(
    "--top",
    type=click.IntRange(min=1, max=12),
    default=3,
    show_default=True,
    help="Contact sheet of the K most informative poses (story information).",
)
@click.option(
    "--view",
    default=None,
    metavar="x,y,z|auto|default",
    callback=view_callback,
    help="View of the contact sheet (default: 'auto' = the selected view).",
)
@click.option(
    "--views",
    "named_views",
    multiple=True,
    metavar="NAME=x,y,z",
    callback=_named_views_callback,
    help="Compare views instead: one panel per NAME=x,y,z (repeat the option).",
)
@click.option(
    "--compare",
    is_flag=True,
    help="Compare the three methods' views (ours / viewpoint entropy / motion "
    "area, as far as available) at --frame.",
)
@click.option(
    "--frame",
    type=int,
    default=None,
    metavar="N",
    help="Source frame for --views/--compare (default: the selected pose).",
)
@click.option(
    "--size",
    default="480x540",
    show_default=True,
    metavar="WxH",
    callback=_size_callback,
    help="Size of each panel in pixels.",
)
@click.option(
    "--columns", type=click.IntRange(min=1), default=None, help="Panels per row (default: one row)."
)
@click.option("--title", default=None, help="Title line above the panels.")
@_render_options
def sheet(
    paths,
    fps,
    scale,
    output,
    frames,
    top,
    view,
    named_views,
    compare,
    frame,
    size,
    columns,
    title,
    perspective,
    no_ground,
    no_shadows,
):
    """Composite pictures: a contact sheet of poses, or one pose from several views.

    \b
    Contact sheet (the paper's Fig. 5 strip): the top poses, or --frames A,B,C.
    View comparison (Fig. 8-10): --compare, or --views ours=1,0,0 --views top=0,1,0.
    All panels share one size and one scale.

    \b
    Examples:
      snapshot sheet dance/05_06.bvh -o top3.png --top 3
      snapshot sheet dance/05_06.bvh -o views.png --compare
    """
    from snapcore.render.composites import compare_views, contact_sheet
    from snapcore.render.renderer import save_png

    w, h = size
    proj = "perspective" if perspective else "orthographic"
    scene = scene_from_options(paths, fps, scale)
    body = body_option()
    common = dict(
        size=(w, h),
        projection=proj,
        ground=not no_ground,
        shadows=not (no_shadows or no_ground),
        columns=columns,
        body=body,
    )
    picks = None
    if named_views or compare:
        f, picks = _frame_option(scene, frame, views=compare, body=body)
        if named_views:
            views = dict(named_views)
        else:
            views = (picks or pipeline_picks(scene, body=body))["views"]
        img = compare_views(scene, f, views, title=title, **common)
    else:
        captions = None
        if frames:
            for f in frames:  # frames the scene does not keep: one line, exit 2
                internal_frame(scene, f, "--frames")
        else:
            picks = pipeline_picks(scene, k=top, views=False)
            frames, captions = picks["frames"], picks["captions"]
        v, how = _view_option(view, scene)
        _note(f"view {np.round(v, 3).tolist()} ({how})")
        img = contact_sheet(
            scene,
            frames,
            view=v,
            captions=captions,
            title=title,
            ranked=captions is not None,
            **common,
        )  # --frames: no ranks
    save_png(img, output)
    click.echo(output)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(sheet())
