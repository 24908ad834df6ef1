"""``snapshot stimuli``: build and check the files a user study shows."""

from __future__ import annotations

from pathlib import Path

import click

__all__ = ["stimuli"]


@click.group()
def stimuli():
    """Build or verify the stimuli of a user study (videos, frames, candidate views).

    A stimuli folder holds per scene the animation video (H.264), one image per video
    frame, the three candidate views of the selected pose (ours, viewpoint entropy,
    motion area) and a manifest.json with the sha256 of every file, the motion frame
    shown at each video frame, the algorithm's picks and which method made which view.
    """


@stimuli.command("build")
@click.argument("config", type=click.Path(dir_okay=False, path_type=Path))
@click.option(
    "-o",
    "--out",
    "out",
    required=True,
    type=click.Path(file_okay=False, path_type=Path),
    help="Folder to write (must not exist unless --force).",
)
@click.option(
    "--force",
    is_flag=True,
    help="Point an existing folder at the new build (earlier builds are kept in FOLDER.sets/).",
)
@click.option("--quiet", "-q", is_flag=True, help="No progress bar.")
def build(config: Path, out: Path, force: bool, quiet: bool):
    """Run the selection on each scene of study CONFIG and write its stimuli to --out.

    CONFIG is a study TOML/JSON (data_schema/study.schema.json), e.g.
    study_app/configs/demo.toml (synthetic scenes) or study_app/configs/paper.toml
    (the paper's six analogues, needs SNAPSHOT_DATA).
    """
    from study_app.design.build import build_stimuli
    from study_app.design.protocol import load_study
    from study_app.design.stimuli import load_stimuli

    study = load_study(config)
    manifest = build_stimuli(study, out, force=force, quiet=quiet)
    s = load_stimuli(manifest.parent)
    n_files = len(s.manifest["files"])
    click.echo(f"{manifest}: {len(s.scenes)} scenes, {n_files} files, manifest sha256 {s.sha256}")
    # The angle between every pair of candidate views as shown: near-duplicates split votes.
    for e in s.manifest["scenes"]:
        angles = e.get("view_angles") or {}
        flag = "  NEAR-DUPLICATE" if e.get("near_duplicates") and "shown" not in e else ""
        if "shown" in e:  # merged: what the view task shows, each picture once
            flag = (
                "  shown: "
                + " | ".join(" = ".join(g) for g in e["shown"])
                + (" (view task skipped: all alike)" if e.get("view_task") == "skipped" else "")
            )
        click.echo(
            f"  {e['id']}: "
            + ", ".join(f"{k.replace('|', '/')} {v:.1f}°" for k, v in angles.items())
            + flag
        )
        # A replaced view: what it was too alike to, and the measure before and after.
        for r in e.get("replacements") or []:
            click.echo(
                f"    {r['method']} replaced (rank {r.get('rank', '?')} of its views): "
                + ", ".join(
                    f"IoU with {k.replace(r['method'], '').strip('|')} "
                    f"{r['iou_before'][k]:.2f} -> {r['iou_after'][k]:.2f}"
                    for k in r["iou_before"]
                )
            )


@stimuli.command("verify")
@click.argument("folder", type=click.Path(file_okay=False, path_type=Path))
def verify(folder: Path):
    """Check every file of a stimuli FOLDER against its manifest (exit 2 if any differs)."""
    from study_app.design.stimuli import load_stimuli

    s = load_stimuli(folder)
    click.echo(
        f"{folder}: ok ({len(s.manifest['files'])} files, study {s.study.id}, "
        f"manifest sha256 {s.sha256})"
    )


@stimuli.command("sheet")
@click.argument("folder", type=click.Path(file_okay=False, path_type=Path))
@click.option(
    "-o",
    "--out",
    "out",
    required=True,
    type=click.Path(dir_okay=False, path_type=Path),
    help="PNG to write.",
)
def sheet(folder: Path, out: Path):
    """Write a sheet of every scene's view-task pictures of stimuli FOLDER as shown (alike
    candidates once, titled with the methods each stands for)."""
    from study_app.design.media import shown_sheet
    from study_app.design.stimuli import load_stimuli

    s = load_stimuli(folder)
    click.echo(shown_sheet(s.manifest, s.folder, out))
