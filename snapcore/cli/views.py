"""``snapshot plot-views``: where each method looks from, on a map of the view sphere."""

from __future__ import annotations

from pathlib import Path

import click

from snapcore.cli.common import (
    FiniteFloatRange,
    body_option,
    output_callback,
    scene_arguments,
    scene_from_options,
)

__all__ = ["plot_views"]


@click.command("plot-views")
@scene_arguments
@click.option(
    "-o",
    "--output",
    type=click.Path(dir_okay=False, writable=True),
    required=True,
    callback=output_callback(".png", ".pdf", ".svg"),
    help="Image file to write (.png, .pdf, .svg).",
)
@click.option(
    "--frame",
    type=click.IntRange(min=0),
    default=None,
    help="Source frame of the pose (default: the story-information pick).",
)
@click.option(
    "--window",
    "window",
    type=FiniteFloatRange(min=0.0),
    default=None,
    metavar="SECONDS",
    help="Score PMA and motion area over the pose ± SECONDS (default: whole sequence).",
)
@click.option(
    "--projection",
    type=click.Choice(["mollweide", "equirect"]),
    default="mollweide",
    show_default=True,
    help="Map projection of the sphere.",
)
@click.option(
    "--n-views",
    type=click.IntRange(min=12),
    default=2562,
    show_default=True,
    help="Samples of the view sphere for PMA and motion area.",
)
@click.option(
    "--no-entropy", is_flag=True, help="Leave out the viewpoint-entropy map (no rendering)."
)
@click.option("--dpi", type=click.IntRange(min=30), default=120, show_default=True)
def plot_views(paths, fps, scale, output, frame, window, projection, n_views, no_entropy, dpi):
    """Map the view scores over the sphere with the three methods' picks.

    One heat map per method: Projected Motion Area (ours), motion area (Kwon & Lee)
    and viewpoint entropy (Vázquez et al., of the posed body at the frame), each with
    all three picks marked (star, triangle, circle; hollow at the antipode where the
    score cannot tell front from back) and the characters' facing as a dashed line.
    Longitude is the azimuth from +Z towards +X, latitude the camera's elevation.

    \b
    Example:
      snapshot plot-views walk_run/02_01.bvh -o views.png
    """
    scene = scene_from_options(paths, fps, scale)
    if frame is None:
        from snapcore.pipeline import take_snapshot

        frame = take_snapshot(scene, view=None).source_frame
    else:
        if not 0 <= frame - scene.frame_offset < scene.n_frames:
            raise click.BadParameter(
                f"source frame {frame} is outside {scene.frame_offset}.."
                f"{scene.frame_offset + scene.n_frames - 1}",
                param_hint="--frame",
            )
    from snapcore.render.view_plot import plot_views as draw
    from snapcore.render.view_plot import view_maps

    maps = view_maps(
        scene,
        frame=frame,
        window_s=window,
        n_views=n_views,
        entropy=not no_entropy,
        body=body_option(),
    )
    fig = draw(scene, frame=frame, window_s=window, projection=projection, maps=maps)
    out = Path(output)
    fig.savefig(out, dpi=dpi)
    picks = ", ".join(f"{m} ({', '.join(f'{x:+.2f}' for x in d['pick'])})" for m, d in maps.items())
    click.echo(f"wrote {out}  (frame {frame}: {picks})")
