"""``snapshot relief``: carve the selected pose, seen from the selected view, into a printable STL."""

from __future__ import annotations

from pathlib import Path

import click
import numpy as np

from snapcore.cli.common import (
    POSITIVE,
    body_option,
    echo_json,
    internal_frame,
    output_callback,
    scene_arguments,
    scene_from_options,
    vector_callback,
)

__all__ = ["relief", "parse_size", "default_pose_and_view"]


def _size_callback(ctx, param, value):
    try:
        return parse_size(value)
    except click.BadParameter as err:  # name the option as click does for its own errors
        raise click.BadParameter(err.message, param=param) from None


def parse_size(text: str) -> tuple[float, float]:
    """``"100"`` → (100, 100); ``"120x80"`` → (120, 80) millimetres."""
    parts = text.lower().replace("×", "x").split("x")
    try:
        vals = [float(p) for p in parts]
    except ValueError:
        vals = []
    if len(vals) == 1:
        vals = vals * 2
    if len(vals) != 2 or not all(np.isfinite(v) and v > 0 for v in vals):
        raise click.BadParameter(
            f"expected a size in mm like 100 or 120x80, got '{text}'", param_hint="--size"
        )
    return vals[0], vals[1]


def default_pose_and_view(scene, *, need_frame: bool, need_view: bool):
    """The selected pose (source frame number) and view of ``scene`` from the pipeline.

    Uses :func:`snapcore.pipeline.take_snapshot` (story information + Projected Motion Area;
    the baselines are not needed here and are skipped: viewpoint entropy renders).
    Returns ``(source_frame or None, view or None)`` for what was asked.
    """
    from snapcore.pipeline import ViewParams, take_snapshot

    snap = take_snapshot(scene, view=ViewParams(baselines=False) if need_view else None)
    frame = snap.source_frame if need_frame else None
    view = np.asarray(snap.view, float) if need_view else None
    return frame, view


@click.command()
@scene_arguments
@click.option(
    "--frame",
    "-f",
    type=int,
    default=None,
    help="Pose: frame number in the source file's numbering (0-based). "
    "Default: the pose selected by story information (the default pose method).",
)
@click.option(
    "--view",
    "view_text",
    default=None,
    metavar="X,Y,Z",
    callback=vector_callback,
    help="View direction from the scene towards the viewer (world, Y up). "
    "Default: the view selected by Projected Motion Area.",
)
@click.option(
    "--output",
    "-o",
    type=click.Path(dir_okay=False),
    default="relief.stl",
    show_default=True,
    callback=output_callback(".stl"),
    help="STL file to write (.stl; binary, millimetres).",
)
@click.option(
    "--size",
    "size_text",
    default="100",
    show_default=True,
    metavar="W[xD]",
    callback=_size_callback,
    help="Footprint in mm (one number: square).",
)
@click.option(
    "--depth",
    type=POSITIVE,
    default=4.0,
    show_default=True,
    help="Relief depth in mm above the plate.",
)
@click.option(
    "--base", type=POSITIVE, default=2.0, show_default=True, help="Base plate thickness in mm."
)
@click.option(
    "--resolution",
    type=click.IntRange(16, 4096),
    default=512,
    show_default=True,
    help="Height-field pixels along the longer side (STL size grows as its square: 512 → ~25 MB).",
)
@click.option(
    "--linear",
    is_flag=True,
    help="Plain linear depth compression instead of the gradient-domain method (for comparison).",
)
@click.option(
    "--preview",
    type=click.Path(dir_okay=False),
    default=None,
    callback=output_callback(".png", what="relief writes its preview as"),
    help="Shaded preview PNG (.png; default: beside the STL, same name with .png).",
)
@click.option(
    "--json", "as_json", is_flag=True, help="Print a JSON summary (data_schema/relief.schema.json)."
)
@click.option("--quiet", "-q", is_flag=True, help="Print nothing but errors.")
def relief(
    paths,
    fps,
    scale,
    frame,
    view_text,
    output,
    size_text,
    depth,
    base,
    resolution,
    linear,
    preview,
    as_json,
    quiet,
):
    """Carve a pose into a bas-relief STL (the paper's §4.3, Fig. 11-12).

    PATH is one or more BVH files (several = one multi-character scene, all carved
    together) or one scene manifest. The pose's body mesh is rendered as an orthographic
    depth map along the view, compressed in the gradient domain (Weyrich et al. 2007,
    with a cross-bilateral detail filter on height and view angle), and closed into a
    watertight solid: SIZE footprint, DEPTH relief on a BASE plate (default
    100 x 100 mm, 4 mm on 2 mm). A raking-light preview PNG is written beside the STL.

    Example: snapshot relief two_person/60_01_scaled.bvh two_person/61_01_scaled.bvh
    --fps 60 --frame 900 --view 0.3,0.2,1 -o salsa.stl
    """
    from snapcore.relief.height_field import ReliefParams
    from snapcore.relief.scene import relief_from_scene

    size = size_text  # parsed by _size_callback
    view = view_text  # a unit vector or None (vector_callback)
    out = Path(output)
    png = Path(preview) if preview else out.with_suffix(".png")
    if png.resolve() == out.resolve():  # the suffix checks rule it out; never lose the STL
        raise click.UsageError(f"--preview {preview}: must differ from -o/--output {output}")
    params = ReliefParams(
        size_mm=size,
        depth_mm=depth,
        base_mm=base,
        resolution=resolution,
        method="linear" if linear else "compressed",
    )
    scene = scene_from_options(paths, fps, scale)
    if frame is not None:
        internal_frame(scene, frame)  # before the pipeline picks the view
    picked = []
    if frame is None or view is None:
        auto_frame, auto_view = default_pose_and_view(
            scene, need_frame=frame is None, need_view=view is None
        )
        if frame is None:
            frame = int(auto_frame)
            picked.append("frame")
        if view is None:
            view = auto_view / np.linalg.norm(auto_view)
            picked.append("view")
    rel = relief_from_scene(scene, frame, view, params=params, body=body_option())
    rel.write_stl(out)
    rel.write_preview(png)
    summary = {
        "stl": str(out),
        "preview": str(png),
        "frame": int(frame),
        "view": [float(x) for x in view],
        "selected": picked,
        "method": params.method,
        "size_mm": list(params.size_mm),
        "depth_mm": params.depth_mm,
        "base_mm": params.base_mm,
        "grid": list(rel.height_mm.shape),
        "pixel_mm": list(rel.pixel_mm),
        "n_triangles": rel.n_triangles,
        "scene_pixel_m": rel.meta["pixel_size_m"],
        "characters": len(scene.characters),
    }
    from snapcore.schema import validate

    validate(summary, "relief", source="snapshot relief output")
    if as_json:
        echo_json(summary)
    elif not quiet:
        fsel = " (selected pose)" if "frame" in picked else ""
        vsel = " (selected view)" if "view" in picked else ""
        click.echo(
            f"relief      frame {frame}{fsel}, view ({view[0]:+.3f}, {view[1]:+.3f}, "
            f"{view[2]:+.3f}){vsel}, {params.method}"
        )
        click.echo(
            f"print box   {size[0]:g} x {size[1]:g} mm, relief {depth:g} mm on a {base:g} mm plate, "
            f"{rel.height_mm.shape[1]}x{rel.height_mm.shape[0]} grid"
        )
        click.echo(f"wrote       {out} ({rel.n_triangles:,} triangles), preview {png}")
