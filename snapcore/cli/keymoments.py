"""``snapshot keymoments``: every pose selector against annotated key moments."""

from __future__ import annotations

from pathlib import Path

import click

__all__ = ["keymoments"]


def _methods(ctx, param, value):
    from snapcore.select.pose_methods import POSE_METHODS

    if value is None:
        return list(POSE_METHODS)
    names = [v.strip() for v in value.split(",") if v.strip()]
    bad = [n for n in names if n not in POSE_METHODS]
    if bad or not names:
        raise click.BadParameter(
            f"unknown method(s) {', '.join(bad) or '(none)'}; expected a "
            f"comma-separated list of {', '.join(POSE_METHODS)}"
        )
    return list(dict.fromkeys(names))


@click.command()
@click.argument("annotations", type=click.Path(dir_okay=False))
@click.option(
    "--data",
    type=click.Path(file_okay=False),
    default=None,
    help="Folder the annotated files are relative to (default: SNAPSHOT_DATA, "
    "else ../shared/motions).",
)
@click.option(
    "--methods",
    callback=_methods,
    default=None,
    metavar="A,B,...",
    help="Pose methods to compare (default: all: story, paper, stretch, fastest, "
    "middle, random, salient).",
)
@click.option(
    "-k",
    "k",
    type=click.IntRange(min=1),
    default=3,
    show_default=True,
    help="Picks per method (top-k).",
)
@click.option(
    "-o",
    "--output",
    type=click.Path(file_okay=False),
    default=None,
    help="Folder for keymoments.csv, keymoments.md, keymoments.json and keymoments_timeline.png.",
)
@click.option(
    "--json",
    "as_json",
    is_flag=True,
    help="Print the evaluation as JSON (data_schema/keymoments_evaluation.schema.json).",
)
def keymoments(annotations, data, methods, k, output, as_json):
    """Measure pose selectors against annotated key moments.

    ANNOTATIONS is a TSV (columns scene, files, fps, intervals, what; as in
    ../shared/keymoments/keymoments.tsv) or the same content as JSON
    (data_schema/keymoments.schema.json). Every method runs on every scene; a pick hits
    when it lies inside an interval widened by 0.1 s on each side. The table gives, per
    scene and overall, top-1 and top-3 hits, the distance (s) from the top pick to the
    nearest interval, and the chance rate (a random frame's top-1 hit rate).

    \b
    Example:
      snapshot keymoments ../shared/keymoments/keymoments.tsv -o results/keymoments
    """
    from snapcore.motion.load import data_dir
    from snapcore.select.keymoments import (
        overall_markdown,
        read_keymoments,
        run_keymoments,
        table_rows,
    )

    entries = read_keymoments(annotations)
    base = Path(data) if data else data_dir(required=True)
    doc = run_keymoments(
        entries,
        data=base,
        methods=methods,
        k=k,
        source=annotations,
        progress=None if as_json else (lambda s: click.echo(f"  running {s}...", err=True)),
    )
    from snapcore.schema import validate

    validate(doc, "keymoments_evaluation", source="snapshot keymoments output")
    rows = table_rows(doc)
    if output:
        import csv
        import json

        out = Path(output)
        out.mkdir(parents=True, exist_ok=True)
        with open(out / "keymoments.csv", "w", newline="", encoding="utf-8") as fh:
            w = csv.DictWriter(fh, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
        md = [
            "| scene | method | top-1 | top-3 | distance (s) | chance | frames |",
            "|---|---|---|---|---|---|---|",
        ]
        md += [
            f"| {r['scene']} | {r['method']} | {r['top1']} | {r['top3']} | "
            f"{r['distance_s']} | {r['chance']} | {r['frames']} |"
            for r in rows
        ]
        (out / "keymoments.md").write_text(
            "\n".join(md) + "\n\nOverall:\n\n" + overall_markdown(doc) + "\n", encoding="utf-8"
        )
        (out / "keymoments.json").write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
        from snapcore.render.keymoments_plot import plot_keymoment_timelines

        fig = plot_keymoment_timelines(doc)
        fig.savefig(out / "keymoments_timeline.png", dpi=120)
    if as_json:
        from snapcore.cli.common import echo_json

        echo_json(doc)
        return
    click.echo(
        f"{'scene':<14} {'method':<9} {'top1':>5} {'top3':>5} {'dist_s':>7} {'chance':>6}  frames"
    )
    for r in rows:
        click.echo(
            f"{r['scene']:<14} {r['method']:<9} {str(r['top1']):>5} {str(r['top3']):>5} "
            f"{r['distance_s']:>7.2f} {r['chance']:>6.2f}  {r['frames']}"
        )
    click.echo(
        "a pick hits inside an interval widened by 0.1 s; dist_s: top pick to the "
        "nearest interval; chance: a random frame's hit rate (ALL: expected hits)"
    )
    if output:
        click.echo(f"wrote {Path(output)}/keymoments.csv, .md, .json, keymoments_timeline.png")
