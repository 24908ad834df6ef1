"""``snapshot info``: what is in a motion file or scene."""

from __future__ import annotations

import click

from snapcore.cli.common import echo_json, scene_arguments, scene_from_options

__all__ = ["info", "scene_summary"]


def scene_summary(scene) -> dict:
    """A JSON-ready summary of a scene: characters, joints, frames, fps, sizes (metres)."""
    lo, hi = scene.bounds()
    return {
        "name": scene.name,
        "n_characters": scene.n_characters,
        "n_frames": scene.n_frames,
        "fps": scene.fps,
        "duration_s": scene.duration,
        "frame_offset": scene.frame_offset,
        "ground_m": scene.ground,
        "bounds_m": {"min": lo.tolist(), "max": hi.tolist()},
        "characters": [
            {
                "name": c.name,
                "n_joints": c.n_joints,
                "n_end_sites": int(c.skeleton.end_site.sum()),
                "height_m": c.height,
                "scale_m_per_unit": c.scale,
                "unit": c.meta.get("unit", "given"),
                "source": c.source.path if c.source is not None else c.meta.get("path"),
                "animation": c.meta.get("animation"),
                "animations": list(c.meta.get("animations", [])),
            }
            for c in scene.characters
        ],
    }


@click.command()
@scene_arguments
@click.option(
    "--json",
    "as_json",
    is_flag=True,
    help="Print machine-readable JSON (data_schema/info.schema.json).",
)
def info(paths, fps, scale, as_json):
    """Summarise a scene: characters, joints, frames, fps, duration, height, bounds.

    PATH is one or more BVH, glTF/GLB or FBX files (several = one multi-character scene)
    or one scene manifest (.toml/.json). For glTF and FBX characters it lists the
    animations.
    """
    scene = scene_from_options(paths, fps, scale)
    s = scene_summary(scene)
    from snapcore.schema import validate

    validate(s, "info", source="snapshot info output")
    if as_json:
        echo_json(s)
        return
    click.echo(f"scene       {s['name']}")
    click.echo(
        f"frames      {s['n_frames']} at {s['fps']:g} fps = {s['duration_s']:.2f} s"
        + (f" (source frames from {s['frame_offset']})" if s["frame_offset"] else "")
    )
    click.echo(f"ground      y = {s['ground_m']:.3f} m")
    lo, hi = s["bounds_m"]["min"], s["bounds_m"]["max"]
    sx, sy, sz = (h - low for h, low in zip(hi, lo))
    click.echo(
        f"bounds      x {lo[0]:.2f}..{hi[0]:.2f}  y {lo[1]:.2f}..{hi[1]:.2f}  "
        f"z {lo[2]:.2f}..{hi[2]:.2f} m  ({sx:.2f} x {sy:.2f} x {sz:.2f} m)"
    )
    for c in s["characters"]:
        click.echo(
            f"character   {c['name']}: {c['n_joints']} joints ({c['n_end_sites']} end sites), "
            f"height {c['height_m']:.2f} m, {c['scale_m_per_unit']:.4g} m/unit ({c['unit']})"
        )
        if c["animations"]:
            click.echo(
                f"animations  {', '.join(c['animations'])} (playing {c['animation']}; "
                "--animation NAME picks one)"
            )
