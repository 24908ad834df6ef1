"""``snapshot blender-addon``: build the Blender extension (a zip to install in Blender)."""

from __future__ import annotations

import zipfile
from pathlib import Path

import click

from snapcore.cli.common import output_callback

#: The add-on's files (package data beside this module); the manifest sits at the
#: zip's top, as Blender's extension rules require.
ADDON_DIR = Path(__file__).resolve().parent / "blender_addon"
ADDON_FILES = ("__init__.py", "blender_manifest.toml")


def build_addon(out: Path) -> Path:
    """Write the extension zip to ``out``; returns ``out``."""
    with zipfile.ZipFile(out, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for name in ADDON_FILES:
            zf.write(ADDON_DIR / name, name)
    return out


@click.command("blender-addon")
@click.option(
    "-o",
    "--output",
    default="action_snapshot.zip",
    show_default=True,
    callback=output_callback(".zip"),
    help="The extension zip to write.",
)
def blender_addon(output):
    """Build the Blender add-on (a Blender 4.2+ extension zip).

    Install it in Blender (Edit > Preferences > Get Extensions > Install from Disk),
    select an armature with an action, and in the 3D view's sidebar (N), tab
    Snapshot, press "Snapshot the action": timeline markers go on the top-k story
    poses and a camera is set along the Projected Motion Area view, framing the
    character at the story pose; "Render still" renders it. The add-on runs this
    installed `snapshot` command (its path is a field of the panel).

    Example: snapshot blender-addon -o action_snapshot.zip
    """
    out = build_addon(Path(output))
    click.echo(f"wrote {out} (install it in Blender 4.2+: Preferences > Get Extensions)")
