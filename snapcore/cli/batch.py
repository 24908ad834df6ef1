"""``snapshot batch``: a whole motion library → snapshots, thumbnails, an index, a gallery."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from snapcore.cli.common import POSITIVE, FiniteFloatRange
from snapcore.cli.render import parse_size
from snapcore.cli.select import pose_options, pose_params_from_options
from snapcore.render.bodies import BODY_KINDS

__all__ = ["batch", "snapshot_kwargs"]

#: ``snapshot select`` option names → field names of the pipeline's parameter objects
#: (``PoseParams``, ``ViewParams``; an option not listed here keeps its own name).
_SNAPSHOT_KW = {"min_separation": "min_separation_s", "smooth": "smooth_s"}


def snapshot_kwargs(pose: dict, *, window=None, baselines=True) -> dict:
    """The batch's options table (:attr:`BatchOptions.snapshot`, read by
    :func:`snapcore.pipeline.snapshot_params`) from the pose options of
    ``snapshot select``: a plain dict, so the options hash of a library stays the same."""
    kw = {_SNAPSHOT_KW.get(k, k): v for k, v in pose.items()}
    kw.update(window_s=window, baselines=bool(baselines))
    return kw


def _size(ctx, param, value):
    try:
        return parse_size(value, "/".join(param.opts))
    except click.BadParameter as err:
        raise click.BadParameter(err.message, param=param) from None


def _scheduler(ctx, param, value):
    if value is not None and "://" not in value:
        raise click.BadParameter(
            f"expected an address like tcp://HOST:8786, got '{value}'", param=param
        )
    return value


def _out_folder(ctx, param, value):
    p = Path(value)
    if p.exists() and not p.is_dir():
        raise click.BadParameter(f"{value}: is a file, expected a folder", param=param)
    if not p.exists() and not p.parent.resolve().is_dir():
        raise click.BadParameter(f"{value}: folder {p.parent} does not exist", param=param)
    return p


def _notify(message: str) -> None:
    """A message during the run (workers lost), printed above the progress bar."""
    from tqdm import tqdm

    tqdm.write(message, file=sys.stderr)


def _progress(quiet: bool):
    """A tqdm bar in scenes/s with ETA; returns the factory :func:`run_batch` wants."""
    from tqdm import tqdm

    bars = []

    def start(total: int):
        bar = tqdm(
            total=total,
            unit="scenes",
            desc="batch",
            disable=quiet or total == 0,
            file=sys.stderr,
            dynamic_ncols=True,
        )
        bars.append(bar)
        errors = [0]

        def tick(row):
            if row["status"] != "ok":
                errors[0] += 1
                bar.set_postfix(errors=errors[0], refresh=False)
            bar.update(1)

        return tick

    def close():
        for b in bars:
            b.close()

    return start, close


@click.command()
@click.argument("sources", nargs=-1, required=True, metavar="SOURCE...")
@click.option(
    "-o",
    "--output",
    "out",
    required=True,
    callback=_out_folder,
    metavar="OUT/",
    help="Output folder: index.csv, index.html and scenes/ (created).",
)
@click.option(
    "--jobs",
    type=click.IntRange(min=1),
    default=1,
    show_default=True,
    help="Worker processes on this machine (one GL renderer each).",
)
@click.option(
    "--scheduler",
    default=None,
    metavar="tcp://HOST:8786",
    callback=_scheduler,
    help="Run on this Dask distributed cluster instead (workers need the library "
    "at the same path; start them with --nthreads 1).",
)
@click.option(
    "--sheet",
    is_flag=True,
    help="Also render each scene's top-k contact sheet (added later, only the sheets "
    "are rendered; dropped, nothing is redone).",
)
@click.option(
    "--preview",
    type=click.IntRange(min=0),
    default=12,
    show_default=True,
    metavar="N",
    help="Panels of each scene's preview strip: the whole motion at N evenly spaced "
    "frames, small, scrubbed through in the gallery by moving over a card (0: none).",
)
@click.option(
    "--size",
    default="320x360",
    show_default=True,
    metavar="WxH",
    callback=_size,
    help="Thumbnail size in pixels.",
)
@click.option(
    "--sheet-size",
    default="320x360",
    show_default=True,
    metavar="WxH",
    callback=_size,
    help="Size of each contact-sheet panel in pixels.",
)
@click.option(
    "--fps",
    type=POSITIVE,
    default=None,
    help="Frame rate override for EVERY scene (per-scene rates go in scene manifests).",
)
@click.option(
    "--scale",
    type=POSITIVE,
    default=None,
    help="Metres per file unit for every scene (default: inferred per scene).",
)
@click.option(
    "--body",
    type=click.Choice(BODY_KINDS),
    default=None,
    help="Body drawn on skeletons: the MakeHuman 'human' mesh (default; glTF "
    "characters wear their own), the capsule 'mannequin' (faster), or 'makehuman': "
    "the MakeHuman mesh on glTF and FBX skeletons too.",
)
@click.option(
    "--animation",
    default=None,
    metavar="NAME",
    help="glTF/GLB characters: the animation to play (name or index; default the first).",
)
@pose_options
@click.option(
    "--window",
    type=FiniteFloatRange(min=0.0),
    default=None,
    metavar="SECONDS",
    help="Score the view over the selected pose ± SECONDS (default: whole sequence).",
)
@click.option(
    "--baselines/--no-baselines",
    default=False,
    show_default=True,
    help="Also compute the motion-area and viewpoint-entropy baselines in each "
    "JSON (off by default in a batch: the viewpoint-entropy baseline was 56% "
    "of a scene's time; `snapshot select` computes them for one clip).",
)
@click.option("--force", is_flag=True, help="Redo every scene, even those already done.")
@click.option(
    "--prune",
    is_flag=True,
    help="Drop from the index (and OUT/scenes/) the scenes of earlier runs that "
    "are not among this run's SOURCEs (default: keep them, so a run over one "
    "folder updates only that folder's rows).",
)
@click.option(
    "--retry-errors",
    is_flag=True,
    help="Redo the scenes that failed before (e.g. after installing a reader).",
)
@click.option(
    "--title",
    default="Action Snapshot gallery",
    show_default=True,
    help="Title of the gallery page.",
)
@click.option(
    "--profile",
    is_flag=True,
    help="Measure instead: the batch with --jobs 1 and --jobs N (N = --jobs, at "
    "least 2) into OUT/profile/, and a loop of separate `snapshot select` + "
    "`snapshot render` calls; prints a table and writes OUT/profile.json.",
)
@click.option(
    "--profile-loop",
    type=click.IntRange(min=0),
    default=3,
    show_default=True,
    metavar="N",
    help="Scenes in the --profile loop of separate calls.",
)
@click.option("-q", "--quiet", is_flag=True, help="No progress bar.")
def batch(
    sources,
    out,
    jobs,
    scheduler,
    sheet,
    preview,
    size,
    sheet_size,
    fps,
    scale,
    body,
    animation,
    window,
    baselines,
    force,
    prune,
    retry_errors,
    title,
    profile,
    profile_loop,
    quiet,
    **pose,
):
    """Snapshot a whole motion library: per scene the `select --json` document and a
    thumbnail of the chosen pose from the chosen view; an index and a gallery.

    SOURCE is a folder (walked recursively), a glob ('lib/**/*.bvh', quoted), a list
    file (.txt: one path per line) or a file. BVH, glTF and FBX files are scenes, and so
    are scene manifests (.toml/.json) for multi-character scenes; files a manifest
    names are not also run alone.

    \b
    OUT/index.csv   one row per scene (data_schema/batch_index.schema.json)
    OUT/index.parquet  the same index as Parquet
    OUT/index.html  the gallery: open it in a browser (or `snapshot gallery OUT`)
    OUT/scenes/     <path>.json, .png, .preview.png and, with --sheet, .sheet.png
    OUT/library.json   the library root scene keys are relative to (sub-folder runs)
    OUT/thumb-choices.csv  frames chosen as thumbnails in the gallery: a re-run
                    renders them and keeps them, also with --force or another method

    A re-run skips scenes whose files and options are unchanged (--force redoes them).
    Rows of scenes an earlier run did and this one does not cover stay in the index
    (--prune drops them).
    A file that cannot be read is a row with its error; the rest go on. Ctrl-C stops
    and writes the index of what finished.

    \b
    Examples:
      snapshot batch "$SNAPSHOT_DATA" -o gallery/ --jobs 2 --sheet
      snapshot batch lib/ -o gallery/ --scheduler tcp://scheduler:8786
    """
    from snapcore.batch import BatchInterrupted, BatchOptions, discover, run_batch
    from snapcore.batch.discover import BatchError
    from snapcore.batch.run import library_root

    root = library_root(out, sources)
    found = discover(sources, exclude=[out], root=root)
    manifests = found.left_out
    if manifests:
        click.echo(
            f"{len(manifests)} .json/.toml file(s) skipped, not scene manifests "
            f"(first: {manifests[0][0]}: {manifests[0][1]}); the gallery's summary lists them",
            err=True,
        )
    if not found.scenes:
        raise BatchError(f"no scenes (BVH, glTF or scene manifests) in {', '.join(sources)}")
    pose_params_from_options(**pose)  # a paper-only flag with another method: exit 2 here
    options = BatchOptions(
        snapshot=snapshot_kwargs(pose, window=window, baselines=baselines),
        fps=fps,
        scale=scale,
        size=size,
        sheet=sheet,
        preview=preview,
        sheet_size=sheet_size,
        body=body,
        animation=animation,
    )
    if profile:
        from snapcore.batch.profile import format_profile, profile_batch

        result = profile_batch(
            found.scenes, out, options, loop=profile_loop, jobs=max(jobs, 2), quiet=quiet
        )
        for line in format_profile(result):
            click.echo(line)
        return
    start, close = _progress(quiet)
    try:
        report = run_batch(
            found.scenes,
            out,
            options,
            jobs=jobs,
            scheduler=scheduler,
            force=force,
            retry_errors=retry_errors,
            prune=prune,
            progress=start,
            title=title,
            root=root,
            notify=_notify,
            skipped=manifests,
        )
    except BatchInterrupted as stop:
        close()
        r = stop.report
        click.echo(
            f"interrupted: {out / 'index.csv'} lists the {len(r.rows)} scenes that "
            f"finished ({r.done} in this run)",
            err=True,
        )
        sys.exit(130)
    close()
    rate = f", {report.done / report.elapsed_s:.2f} scenes/s" if report.done else ""
    others = len(report.rows) - report.done - report.reused
    # no --prune hint for other folders' rows: after a run over one folder it would
    # delete the rest of the library; only for rows whose files are gone from the
    # folders this run walked (renamed or deleted clips)
    kept = f" (+{others} rows of other scenes kept from earlier runs" if others else ""
    if others and report.errors_elsewhere:
        kept += f", {report.errors_elsewhere} of them with errors"
    kept += ")" if others else ""
    click.echo(
        f"{report.done + report.reused} scenes: {report.done} processed{rate}, "
        f"{report.reused} already done, {report.errors} with errors{kept}; index "
        f"{out / 'index.csv'}, gallery {out / 'index.html'}"
    )
    gone = stale_rows(report.rows, {s.key for s in found.scenes}, sources, root)
    if gone:
        click.echo(
            f"{len(gone)} row(s) of clips no longer under {', '.join(sources)} (renamed or "
            f"deleted? first: {gone[0]}); --prune drops them and their pictures",
            err=True,
        )


def stale_rows(rows, keys, sources, root) -> list[str]:
    """Keys of index rows that are not among this run's scenes although their file would
    lie inside one of the folders this run walked, and is not there: a clip renamed or
    deleted since. Rows of folders the run did not walk are not stale."""
    if root is None:
        return []
    folders = [Path(s).expanduser().resolve() for s in sources if Path(s).is_dir()]
    base = Path(root).resolve()
    gone = []
    for r in rows:
        if r["path"] in keys:
            continue
        f = base / r["path"]
        if any(f.is_relative_to(d) for d in folders) and not f.exists():
            gone.append(r["path"])
    return gone
