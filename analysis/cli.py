"""The analysis subcommands of ``snapshot``: analyze, simulate, power, figures
(calibrate is in :mod:`analysis.calibrate_cli`).

Registered as entry points in ``pyproject.toml`` (``analysis.cli:analyze`` ...). Thin:
parse options, call the library, print a short summary. Errors are
:class:`~snapcore.errors.SnapshotError` subclasses, which ``snapshot`` turns into one
``error:`` line.
"""

from __future__ import annotations

import hashlib
import math
from pathlib import Path

import click

from snapcore.cli.common import FiniteFloatRange
from snapcore.errors import SnapshotError

__all__ = ["analyze", "simulate", "power", "figures"]


class AnalysisError(SnapshotError):
    """A request the analysis commands cannot carry out."""


def _parse_strengths(text: str | None) -> dict | None:
    """``"ours=0.5,viewpoint_entropy=0.2,motion_area=0.3"`` → dict (checked)."""
    if not text:
        return None
    from snapcore.select.view_methods import VIEW_METHODS

    out = {}
    for part in text.split(","):
        name, _, value = part.partition("=")
        name = name.strip()
        if name not in VIEW_METHODS:
            raise click.BadParameter(
                f"unknown method '{name}' (expected {', '.join(VIEW_METHODS)})",
                param_hint="--strengths",
            )
        try:
            out[name] = float(value)
        except ValueError:
            raise click.BadParameter(
                f"'{part}' is not method=number", param_hint="--strengths"
            ) from None
    if set(out) != set(VIEW_METHODS) or any(not 0 < v < math.inf for v in out.values()):
        raise click.BadParameter(
            f"give a positive finite strength for each of {', '.join(VIEW_METHODS)}",
            param_hint="--strengths",
        )
    return out


@click.command(name="analyze")
@click.option(
    "--db",
    "db",
    default=None,
    metavar="URL",
    help="Study store URL (SQLAlchemy, e.g. sqlite:///var/study.db or "
    "postgresql+psycopg://...). Default: $SNAPSHOT_DB, else the app's default store.",
)
@click.option(
    "--input",
    "input_path",
    type=click.Path(dir_okay=False),
    default=None,
    help="An export file (snapshot export: .csv or .jsonl) instead of the store. A "
    "Psych-DS data file (data/study-<id>_data.csv) brings its participants file (who "
    "finished, who was excluded and why), the dataset's withdrawals and its "
    "materials/manifest.json: the same analysis as --db on the database it came from.",
)
@click.option(
    "--participants",
    "participants_path",
    type=click.Path(dir_okay=False),
    default=None,
    help="With --input: the participants export (snapshot export --participants) that "
    "says who finished and who was excluded (default: the Psych-DS participants file "
    "beside --input; without one, finished = answered the last trial and exclusions "
    "are unknown).",
)
@click.option(
    "--paper-table2",
    is_flag=True,
    help="Analyse the paper's own published Table 2 counts (no study data needed).",
)
@click.option(
    "-o",
    "--out",
    "out_dir",
    type=click.Path(file_okay=False),
    default="results",
    show_default=True,
    help="Output folder (tables/, figures/, report.html).",
)
@click.option(
    "--stimuli",
    type=click.Path(),
    default=None,
    help="Stimuli manifest (or its folder): scene titles, top-k picks, the motion "
    "for the fastest / most-stretched baselines (the manifest's selector picks) and near-duplicate "
    "candidates. Default: var/stimuli/<study id> when it exists.",
)
@click.option(
    "--include-simulated",
    is_flag=True,
    help="Analyse simulated participants too (excluded by default).",
)
@click.option(
    "--exclude-failed-attention",
    is_flag=True,
    help="Drop participants who failed the attention check.",
)
@click.option(
    "--exclude-unwatched",
    is_flag=True,
    help="Leave out pose answers picked on the frame slider (the video did not play) "
    "or before the animation was watched; the report says how many.",
)
@click.option(
    "--include-incomplete",
    is_flag=True,
    help="Analyse participants who started but did not finish too (by default "
    "only completed participants count).",
)
@click.option(
    "--boot",
    "n_boot",
    type=click.IntRange(0),
    default=1000,
    show_default=True,
    help="Bootstrap resamples for the strengths' intervals.",
)
@click.option(
    "--seed",
    type=int,
    default=0,
    show_default=True,
    help="Seed of the bootstrap resamples (the intervals of the strengths and of the "
    "frame differences).",
)
@click.option(
    "--alpha",
    type=FiniteFloatRange(0, 1, min_open=True, max_open=True),
    default=0.05,
    show_default=True,
    help="Significance level (family-wise, Holm).",
)
@click.option(
    "--figures/--no-figures",
    default=True,
    show_default=True,
    help="Draw the figures (PNG and PDF). --no-figures writes the tables, summary.json "
    "and the report without them, in a fraction of the time (a quick look while data "
    "comes in); the numbers are the same.",
)
@click.option("-q", "--quiet", is_flag=True, help="Print only the output folder.")
def analyze(
    db,
    input_path,
    participants_path,
    paper_table2,
    out_dir,
    stimuli,
    include_simulated,
    exclude_failed_attention,
    exclude_unwatched,
    include_incomplete,
    n_boot,
    seed,
    alpha,
    figures,
    quiet,
):
    """Analyse the study: tables (CSV, Markdown, LaTeX), figures (PNG, PDF) and a
    one-page HTML report in OUT.

    \b
    Views (Table 2): votes with 95% Wilson intervals, chi-square against no
    preference, ours vs each baseline by exact binomial tests (Holm), Luce strengths
    with bootstrap intervals, Fleiss' kappa.
    Poses (Fig. 13): chosen-frame histograms, distances to the algorithm's pick and to
    baselines, hit rates within 0.25/0.5/1 s, permutation tests.

    \b
    Examples:
      snapshot analyze --db sqlite:///var/study.db -o results/
      snapshot analyze --input responses.csv --stimuli stimuli/ -o results/
      snapshot analyze --paper-table2 -o results/paper/
    """
    from . import report

    if sum(x is not None and x is not False for x in (db, input_path, paper_table2 or None)) > 1:
        raise click.UsageError("give one of --db, --input and --paper-table2")
    if participants_path is not None and input_path is None:
        raise click.UsageError("--participants goes with --input")
    if paper_table2:
        from .votes import paper_counts
        from .votes import paper_table2 as table

        t = table()
        labels = dict(zip(t["scene"], t["scene_label"], strict=True))
        summary = report.analyze_counts(
            paper_counts(),
            out_dir,
            labels=labels,
            n_boot=n_boot,
            seed=seed,
            alpha=alpha,
            title="Action Snapshot: the paper's Table 2 re-analysed",
            figures=figures,
            source="the paper's published Table 2 (100 participants; analysis/data/paper_table2.csv)",
        )
    else:
        source = input_path if input_path is not None else _store_url(db)
        summary = report.analyze(
            source,
            out_dir,
            include_simulated=include_simulated,
            stimuli=stimuli,
            exclude_failed_attention=exclude_failed_attention,
            n_boot=n_boot,
            seed=seed,
            alpha=alpha,
            completed_only=not include_incomplete,
            exclude_unwatched=exclude_unwatched,
            figures=figures,
            participants=participants_path,
        )
    if not quiet:
        if "participants" in summary:
            click.echo(
                f"{summary['participants']} participants"
                + (
                    f" analysed of {summary['started_participants']} started"
                    if summary.get("started_participants", summary["participants"])
                    != summary["participants"]
                    else ""
                )
                + (
                    f" ({summary['simulated_participants']} simulated)"
                    if summary.get("simulated_participants")
                    else ""
                )
                + f", {summary['responses']} responses"
            )
        if "left_out" in summary:
            click.echo(_left_out_line(summary["left_out"]))
        if "excluded_answers" in summary:
            ex = summary["excluded_answers"]
            click.echo(
                f"left out {ex['slider']} pose answers picked on the frame slider and "
                f"{ex['not_watched']} given before the animation was watched"
            )
        for line in summary.get("claims", []):
            click.echo(line)
        if "frame_verdict" in summary:
            click.echo(summary["frame_verdict"])
    click.echo(f"wrote {Path(out_dir) / 'report.html'}")


def _left_out_line(c: dict) -> str:
    """One line: who was left out (summary ``left_out``)."""
    parts = []
    if c["excluded"] is not None:
        why = ", ".join(f"{r}: {n}" for r, n in c["exclusion_reasons"].items())
        parts.append(f"{c['excluded']} excluded" + (f" ({why})" if why else ""))
    if c["withdrawn"] is not None:
        parts.append(f"{c['withdrawn']} withdrawn")
    parts.append(f"{c['unfinished']} not finished")
    if c["failed_attention_excluded"]:
        parts.append(f"{c['failed_attention_excluded']} failed the attention check")
    unknown = " (exclusions and withdrawals unknown: no participants file)"
    return (
        f"{c['started']} started, {c['analysed']} analysed; "
        + ", ".join(parts)
        + (unknown if c["excluded"] is None else "")
    )


def _store_url(db):
    if db is not None:
        from study_app.data.database import normalize_url

        # A bare .db/.sqlite path is a SQLite store, as for export, withdraw and backup.
        return normalize_url(db).render_as_string(hide_password=False)
    try:
        from study_app.data.store import default_url
    except ImportError as err:
        raise AnalysisError(
            f"no --db or --input given and the study store is unavailable ({err})"
        ) from err
    return default_url()


@click.command(name="simulate")
@click.option("--n", "n", type=click.IntRange(1), required=True, help="Participants to simulate.")
@click.option(
    "--db",
    "db",
    default=None,
    metavar="URL",
    help="Study store URL to write to (default: $SNAPSHOT_DB, else the app's store).",
)
@click.option(
    "--stimuli",
    type=click.Path(),
    default=None,
    help="Stimuli manifest (or its folder) giving the scenes; default: the paper's six "
    "animations (Table 1 lengths, Table 2 shares as strengths).",
)
@click.option(
    "--strengths",
    default=None,
    metavar="ours=S,viewpoint_entropy=S,motion_area=S",
    help="Luce strengths of the methods for every scene (default: the paper's Table 2 "
    "shares per scene for the paper design, equal strengths for a manifest).",
)
@click.option(
    "--spread",
    "spread_s",
    type=FiniteFloatRange(0),
    default=0.5,
    show_default=True,
    help="SD (seconds) of a frame choice around the salient moment aimed at.",
)
@click.option(
    "--lapse",
    type=FiniteFloatRange(0, 1),
    default=0.1,
    show_default=True,
    help="Probability of a uniformly random frame.",
)
@click.option(
    "--algorithm-weight",
    type=FiniteFloatRange(0, 1),
    default=0.7,
    show_default=True,
    help="Probability that the moment aimed at is the algorithm's pick (else another "
    "salient moment, when the scene has some).",
)
@click.option(
    "--pose-model",
    type=click.Choice(["salient", "uniform", "centre", "habit"]),
    default="salient",
    show_default=True,
    help="Pose-task observer: near a salient moment (the options above), or one who "
    "ignores the motion: uniform (any frame), centre (clip position ~ Beta(2,2)), habit "
    "(a personal Beta(a,b) position, the same in every scene).",
)
@click.option(
    "--view-position",
    type=click.IntRange(0, 2),
    default=None,
    help="View-task observer who always takes this screen position (0 = left) "
    "instead of choosing by the strengths.",
)
@click.option(
    "--study-id",
    default=None,
    help="Study id to store (default: the manifest's, or paper-simulated).",
)
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of the simulation.")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar.")
def simulate(
    n,
    db,
    stimuli,
    strengths,
    spread_s,
    lapse,
    algorithm_weight,
    pose_model,
    view_position,
    study_id,
    seed,
    quiet,
):
    """Simulate N participants from a documented observer model and store them, marked
    simulated (real analyses leave them out unless --include-simulated).

    \b
    Pose task: a frame near a salient moment (the algorithm's pick, or another top-k
    peak) with Gaussian spread --spread seconds, or with probability --lapse any frame.
    View task: Luce choice among the three shown views from the method strengths.
    Null observers for checking the tests: --pose-model uniform|centre|habit,
    --view-position N (see also snapshot calibrate).
    See analysis/simulate.py for the full model.

    \b
    Example:
      snapshot simulate --n 100 --db sqlite:///var/sim.db --seed 1
      snapshot analyze --db sqlite:///var/sim.db --include-simulated -o results/sim/
    """
    from . import simulate as sim

    model = sim.ObserverModel(
        spread_s=spread_s,
        lapse=lapse,
        algorithm_weight=algorithm_weight,
        pose_model=pose_model,
        view_position=view_position,
    )
    chosen = _parse_strengths(strengths)
    attention = None
    if stimuli is not None:
        from .stimuli import read_stimuli

        doc, base = read_stimuli(stimuli)
        design = sim.design_from_stimuli(doc, strengths=chosen)
        # manifest["study"] is the study config document: {"study": {"id": ...}, ...}
        study_id = (
            study_id or ((doc.get("study") or {}).get("study") or {}).get("id") or "simulated"
        )
        path = Path(stimuli) / "manifest.json" if Path(stimuli).is_dir() else Path(stimuli)
        digest = hashlib.sha256(path.read_bytes()).hexdigest()
        att = (doc.get("study") or {}).get("attention")
        if isinstance(att, dict) and "options" in att and "answer" in att:
            attention = att
    else:
        design = sim.paper_design()
        if chosen is not None:
            design = sim.with_strengths(design, chosen)
        study_id = study_id or "paper-simulated"
        digest = sim.design_sha256(design, model)
    try:
        from study_app.data.store import Store
    except ImportError as err:
        raise AnalysisError(f"the study store is unavailable ({err})") from err
    people = sim.simulate_participants(design, n, seed=seed, model=model, attention=attention)
    store = Store(db)
    ids = sim.store_simulation(
        store, people, study_id=study_id, manifest_sha256=digest, progress=not quiet
    )
    click.echo(
        f"stored {len(ids)} simulated participants ({sum(len(p['rows']) for p in people)} "
        f"responses, study '{study_id}') in {store.url}"
    )


@click.command(name="power")
@click.option(
    "--ours",
    "p_ours",
    type=FiniteFloatRange(0, 1),
    default=None,
    help="True vote share of ours (with --baseline).",
)
@click.option(
    "--baseline",
    "p_baseline",
    type=FiniteFloatRange(0, 1),
    default=None,
    help="True vote share of the baseline (the third method gets the rest).",
)
@click.option(
    "--third",
    type=FiniteFloatRange(0, 1, max_open=True),
    default=1 / 3,
    show_default="1/3",
    help="Share of the third method in the difference table.",
)
@click.option(
    "--alpha",
    type=FiniteFloatRange(0, 1, min_open=True, max_open=True),
    default=0.05,
    show_default=True,
    help="Family-wise significance level.",
)
@click.option(
    "--power",
    "target",
    type=FiniteFloatRange(0, 1, min_open=True, max_open=True),
    default=0.8,
    show_default=True,
    help="Target power.",
)
@click.option(
    "--comparisons",
    type=click.IntRange(1),
    default=12,
    show_default=True,
    help="Tests Holm-corrected together (the paper's design: 6 scenes x 2 baselines).",
)
@click.option(
    "-o",
    "--out",
    "out_dir",
    type=click.Path(file_okay=False),
    default=None,
    help="Write the result here: the table (CSV/Markdown/LaTeX), or with --ours "
    "and --baseline the power curve (PNG/PDF).",
)
def power(p_ours, p_baseline, third, alpha, target, comparisons, out_dir):
    """Participants needed to show that ours is preferred to a baseline.

    Exact power of the two-sided binomial test of ours vs the baseline among their
    votes, at level alpha / comparisons (Holm's first step, a lower bound). With
    --ours and --baseline: the N for those shares and a power curve; without: a table
    over vote-share differences 0.05-0.40 (third method at --third).

    \b
    Examples:
      snapshot power --ours 0.52 --baseline 0.40
      snapshot power -o results/power/
    """
    from . import power as pw

    if (p_ours is None) != (p_baseline is None):
        raise click.UsageError("give both --ours and --baseline, or neither")
    if p_ours is not None:
        if p_ours + p_baseline > 1:
            raise click.BadParameter("--ours + --baseline must be at most 1", param_hint="--ours")
        r = pw.sample_size(p_ours, p_baseline, alpha=alpha, power=target, comparisons=comparisons)
        if p_ours <= p_baseline:
            click.echo(
                "ours' share is not above the baseline's: no number of participants "
                "makes 'ours is preferred' likely."
            )
        elif r["n_stable"] is None:
            click.echo(
                f"more than {pw.N_MAX} participants needed (power {target:g} at level "
                f"{alpha:g}/{comparisons})."
            )
        else:
            click.echo(
                f"{r['n_stable']} participants give power {r['power_at_n']:.3f} >= {target:g} "
                f"to show ours ({p_ours:g}) beats the baseline ({p_baseline:g}) at level "
                f"{alpha:g}/{comparisons} (exact binomial)."
            )
        table = None
        top = max(50, int(1.5 * (r["n_stable"] or 300)))
        curve = pw.power_curve(
            p_ours,
            p_baseline,
            n_values=range(5, top + 1, max(1, top // 200)),
            alpha=alpha,
            comparisons=comparisons,
        )
    else:
        table = pw.power_table(
            third=third, alpha=alpha, power=target, comparisons=sorted({1, comparisons})
        )
        from .tables import to_markdown

        click.echo(to_markdown(table), nl=False)
        curve = None
    if out_dir is not None:
        from .plots import plot_power_curve, save_figure
        from .tables import write_table

        out = Path(out_dir)
        if table is not None:
            write_table(
                table,
                out / "power_table",
                caption=f"Participants needed for power {target:g}, exact binomial test "
                f"of ours vs a baseline, alpha {alpha:g} / comparisons.",
            )
        else:
            po, pb = p_ours, p_baseline
            write_table(
                curve,
                out / "power_curve",
                caption=f"Power against participants (ours {po:g}, baseline {pb:g}).",
            )
            save_figure(
                plot_power_curve(
                    curve,
                    target=target,
                    n_needed=r["n_stable"],
                    title=f"true shares: ours {po:g}, baseline {pb:g}; "
                    f"level {alpha:g}/{comparisons}",
                ),
                out / "power_curve",
            )
        click.echo(f"wrote {out}")


@click.command(name="figures")
@click.option(
    "-o",
    "--out",
    "out_dir",
    type=click.Path(file_okay=False),
    default="figures",
    show_default=True,
    help="Output folder.",
)
@click.option(
    "--only",
    default=None,
    metavar="NAMES",
    help="Comma-separated subset of: fig5, fig6, fig8-10, fig11, fig13, table1, table2.",
)
@click.option(
    "--db",
    "db",
    default=None,
    metavar="URL",
    help="Study store for Fig. 13 (default: simulated participants, labelled so).",
)
@click.option(
    "--input",
    "input_path",
    type=click.Path(exists=True, dir_okay=False),
    default=None,
    help="Export file for Fig. 13 instead of the store.",
)
@click.option("--include-simulated", is_flag=True, help="Use simulated participants from --db too.")
@click.option(
    "--repeats",
    type=click.IntRange(1),
    default=3,
    show_default=True,
    help="Timing repeats per clip for Table 1 (median reported).",
)
@click.option("-q", "--quiet", is_flag=True, help="No progress output.")
def figures(out_dir, only, db, input_path, include_simulated, repeats, quiet):
    """Regenerate the paper's figures and tables from the motion data in SNAPSHOT_DATA.

    \b
    fig5     pose entropy over each paper-analogue clip (Fig. 5)
    fig6     local and global pose entropy of the dance (Fig. 6)
    fig8-10  the selected pose seen from ours / viewpoint entropy / motion area
    fig11    reliefs of the dance pose from the three views
    fig13    chosen-frame histograms (study data, or simulated participants)
    table1   our selection timings beside the paper's (Table 1)
    table2   the paper's votes with our statistics (Table 2)

    A figure whose ingredients are missing (no motion data, a snapcore module not
    there) is skipped with the reason; the others are still made.
    """
    from . import figures as fg

    names = fg.FIGURES if not only else [s.strip() for s in only.split(",") if s.strip()]
    unknown = sorted(set(names) - set(fg.FIGURES))
    if unknown:
        raise click.BadParameter(
            f"unknown figure(s) {', '.join(unknown)} (expected {', '.join(fg.FIGURES)})",
            param_hint="--only",
        )
    source = input_path if input_path is not None else db
    if input_path is None and db is not None:
        from study_app.data.store import Store

        with Store(db, create=False):  # a wrong URL: one line, before minutes of figures
            pass
    results = fg.make_figures(
        out_dir,
        names=names,
        source=source,
        include_simulated=include_simulated,
        repeats=repeats,
        progress=not quiet,
    )
    for name, (paths, reason) in results.items():
        if paths:
            click.echo(f"{name}: " + ", ".join(str(p) for p in paths))
        else:
            click.echo(f"{name}: skipped ({reason})")
    if not any(p for p, _ in results.values()):
        raise AnalysisError(
            "no figure could be made: " + "; ".join(f"{k}: {r}" for k, (_, r) in results.items())
        )
