"""The ``snapshot calibrate`` subcommand: the report's tests run on simulated studies.

Registered as an entry point in ``pyproject.toml`` (``analysis.calibrate_cli:calibrate``).
Thin, like :mod:`analysis.cli`: parse options, call :mod:`analysis.calibrate`, print the
table. Errors are :class:`~snapcore.errors.SnapshotError` subclasses, which ``snapshot``
turns into one ``error:`` line.
"""

from __future__ import annotations

from pathlib import Path

import click

from snapcore.cli.common import FiniteFloatRange

__all__ = ["calibrate"]


@click.command(name="calibrate")
@click.option(
    "--stimuli",
    type=click.Path(),
    default="var/stimuli/demo",
    show_default=True,
    help="Stimuli manifest (or its folder): the scenes, the algorithm's and the "
    "baselines' frames of the simulated studies.",
)
@click.option(
    "--conditions",
    default=None,
    metavar="NAMES",
    help="Comma-separated subset of the conditions (default: all; see below).",
)
@click.option(
    "--participants",
    "n_participants",
    type=click.IntRange(2),
    default=100,
    show_default=True,
    help="Simulated participants per study (all finish).",
)
@click.option(
    "--studies",
    "n_studies",
    type=click.IntRange(1),
    default=400,
    show_default=True,
    help="Simulated studies per condition.",
)
@click.option(
    "--alternative-studies",
    "n_alt",
    type=click.IntRange(1),
    default=None,
    help="Simulated studies per alternative (default: --studies).",
)
@click.option(
    "--permutations",
    "n_permutations",
    type=click.IntRange(19),
    default=999,
    show_default=True,
    help="Permutations of each frame test (the report uses 9999; the p-value is valid "
    "at any number, fewer only coarsen it).",
)
@click.option(
    "--alpha",
    type=FiniteFloatRange(0, 1, min_open=True, max_open=True),
    default=0.05,
    show_default=True,
    help="Significance level, as in snapshot analyze.",
)
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of the simulation.")
@click.option(
    "--write-docs",
    "docs",
    type=click.Path(dir_okay=False),
    default=None,
    help="Write the tables, with how they were made, to this Markdown file "
    "(e.g. docs/calibration.md).",
)
@click.option(
    "--csv",
    "csv_path",
    type=click.Path(dir_okay=False),
    default=None,
    help="Write the summary (one row per condition and family) as CSV.",
)
@click.option("-q", "--quiet", is_flag=True, help="No progress bar.")
def calibrate(
    stimuli,
    conditions,
    n_participants,
    n_studies,
    n_alt,
    n_permutations,
    alpha,
    seed,
    docs,
    csv_path,
    quiet,
):
    """Check that the report's tests hold their level: simulate whole studies under
    nulls (no claim true) and alternatives, run the tests the report runs, and print
    every test family's false-positive rate (nulls) or power (alternatives) with
    Clopper-Pearson 95% intervals.

    \b
    Conditions (every observer answers both tasks):
      uniform      random frames, random views                       (null, null)
      centre       frames at clip position ~ Beta(2,2), random views (null, null)
      habit        a personal Beta(a,b) clip position, random views  (null, null)
      position     random frames, always the left view               (null, null)
      track_0.2s, track_0.5s, track_1s
                   the algorithm's frame + Gaussian noise of that SD (power, null)
      ours_1.5, ours_2, ours_3
                   random frames, Luce strength of ours 1.5/2/3x     (null, power)

    \b
    A null family "holds" when its rate is at most alpha + 3.09 Monte-Carlo standard
    errors. Exit code 1 when one does not. See analysis/calibrate.py and
    docs/frame-tests.md.

    \b
    Examples:
      snapshot calibrate --studies 40 --participants 50
      snapshot calibrate --write-docs docs/calibration.md
      snapshot calibrate --conditions uniform,centre --participants 300 --studies 8
    """
    import sys

    from . import calibrate as cb
    from .stimuli import read_stimuli
    from .tables import to_markdown

    names = tuple(cb.CONDITIONS) if not conditions else [c.strip() for c in conditions.split(",")]
    unknown = [c for c in names if c not in cb.CONDITIONS]
    if unknown or not names:
        raise click.BadParameter(
            f"unknown condition(s) {', '.join(unknown)} (expected {', '.join(cb.CONDITIONS)})",
            param_hint="--conditions",
        )
    doc, _ = read_stimuli(stimuli)
    results = cb.calibrate(
        doc,
        conditions=names,
        n_participants=n_participants,
        n_studies=n_studies,
        n_studies_alternative=n_alt,
        n_permutations=n_permutations,
        alpha=alpha,
        seed=seed,
        progress=not quiet,
    )
    summary = cb.summarise(results, alpha=alpha)
    click.echo(to_markdown(cb.console_table(summary)), nl=False)
    if csv_path:
        Path(csv_path).parent.mkdir(parents=True, exist_ok=True)
        summary.to_csv(csv_path, index=False)
        click.echo(f"wrote {csv_path}")
    if docs:
        command = (
            f"snapshot calibrate --stimuli {stimuli} --participants {n_participants} "
            f"--studies {n_studies}"
            + (f" --alternative-studies {n_alt}" if n_alt else "")
            + f" --permutations {n_permutations} --alpha {alpha:g} --seed {seed}"
            + (f" --conditions {','.join(names)}" if conditions else "")
        )
        Path(docs).parent.mkdir(parents=True, exist_ok=True)
        Path(docs).write_text(
            cb.markdown_report(
                summary,
                header=cb.docs_header(command, doc, names),
                by_scene=cb.power_by_scene(results),
            ),
            encoding="utf-8",
        )
        click.echo(f"wrote {docs}")
    bad = summary[summary["holds"] == False]  # noqa: E712 (None for alternatives)
    if not bad.empty:
        click.echo(
            "level NOT held: "
            + "; ".join(f"{r.condition} / {r.task}: {r.family}" for r in bad.itertuples()),
            err=True,
        )
        sys.exit(1)
    click.echo(f"every null family holds its level (alpha {alpha:g})")
