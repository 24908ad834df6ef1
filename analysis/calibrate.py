"""Does the report's evidence hold under the null? Whole simulated studies (``snapshot calibrate``).

A reviewer believes "people pick the algorithm's frame" or "people prefer our view" only
if the same analysis says nothing when people ignore the algorithm. This module
simulates whole studies of observers (:mod:`analysis.simulate`) under named *null*
conditions, where no claim of the report is true, and *alternative* conditions, where
some are; runs on each study the tests the report runs — the same functions with the
report's arguments (:func:`report_tests`) — and counts, per test family, how often a
claim is made:

- under a null, the *false-positive rate*: the share of scene-level tests the report
  calls significant (after Holm, where the report applies it), also without Holm
  (p < α: the test's own level), and the share of studies with any such claim;
- under an alternative, the *power*: the share of scene-level tests making the claim
  the condition makes true.

Rates come with Clopper–Pearson 95% intervals. A family *holds its level* under a null
when its rate is at most α plus 3.09 Monte-Carlo standard errors (a one-sided 0.1%
margin; the standard error is the larger of the binomial one and the one from the
spread of the studies' own rates, because the scenes of one study share participants).

Conditions (:data:`CONDITIONS`; every observer answers both tasks):

====================  =======================================  ========================
name                  pose task                                view task
====================  =======================================  ========================
``uniform``           any frame, uniformly (null)              any view, uniformly (null)
``centre``            clip position ~ Beta(2, 2) (null)        uniformly (null)
``habit``             a personal Beta(a, b) position (null)    uniformly (null)
``position``          uniformly (null)                         always the left view (null)
``track_0.2s`` ...    the algorithm's frame + N(0, σ) s        uniformly (null)
``ours_1.5`` ...      uniformly (null)                         Luce strength of ours ×k
====================  =======================================  ========================
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from . import frames as fr
from . import simulate as sim
from . import votes as vt
from .load import pose_choices, view_choices

__all__ = [
    "Condition",
    "CONDITIONS",
    "FAMILIES",
    "report_tests",
    "simulate_study",
    "calibrate",
    "summarise",
    "markdown_report",
    "console_table",
    "power_by_scene",
    "docs_header",
]

#: The report's test families: (task, family), the frame families being the rows of
#: :func:`analysis.frames.closeness_tests`.
FAMILIES = (
    *(("pose", c) for c in fr.COMPARISONS),
    ("view", "no preference (chi-square)"),
    ("view", "ours vs viewpoint_entropy"),
    ("view", "ours vs motion_area"),
    ("view", "agreement (Fleiss kappa)"),
)
#: The family of the Fleiss' kappa test (a null under every condition, see summarise).
KAPPA = "agreement (Fleiss kappa)"


@dataclass(frozen=True)
class Condition:
    """A kind of simulated observer and what is true of them.

    Attributes
    ----------
    name : str
    text : str
        What the observers do, for the tables.
    model : ObserverModel
    strengths : dict, optional
        Luce strengths of the view methods in every scene (None: the model's, equal).
    pose_null, view_null : bool
        Whether no claim of that task's tests is true for these observers.
    """

    name: str
    text: str
    model: sim.ObserverModel = field(default_factory=sim.ObserverModel)
    strengths: dict | None = None
    pose_null: bool = True
    view_null: bool = True


def _equal(**kw):
    return {"ours": 1.0, "viewpoint_entropy": 1.0, "motion_area": 1.0, **kw}


#: The named conditions, nulls first.
CONDITIONS = {
    c.name: c
    for c in (
        Condition("uniform", "random clickers", sim.ObserverModel(pose_model="uniform")),
        Condition(
            "centre",
            "ignore the motion, prefer the clip's middle (Beta(2,2))",
            sim.ObserverModel(pose_model="centre"),
        ),
        Condition(
            "habit",
            "a personal clip-position habit (Beta(a,b), a,b ~ U(0.5,4))",
            sim.ObserverModel(pose_model="habit"),
        ),
        Condition(
            "position",
            "always take the left view; random frames",
            sim.ObserverModel(pose_model="uniform", view_position=0),
        ),
        *(
            Condition(
                f"track_{s:g}s",
                f"the algorithm's frame + N(0, {s:g} s)",
                sim.ObserverModel(lapse=0.0, algorithm_weight=1.0, spread_s=s),
                pose_null=False,
            )
            for s in (0.2, 0.5, 1.0)
        ),
        *(
            Condition(
                f"ours_{k:g}",
                f"Luce strength of ours {k:g}× the baselines'",
                sim.ObserverModel(pose_model="uniform"),
                strengths=_equal(ours=k),
                view_null=False,
            )
            for k in (1.5, 2.0, 3.0)
        ),
    )
}


def report_tests(
    pose: pd.DataFrame,
    views: pd.DataFrame,
    scenes: dict,
    *,
    order=None,
    alpha: float = vt.ALPHA,
    seed: int = 0,
    n_permutations: int = fr.N_PERMUTATIONS,
) -> pd.DataFrame:
    """Every scene-level test the report states, run as the report runs it.

    The same functions with the same arguments as ``snapshot analyze``
    (:func:`analysis.sections._frame_section` and ``_vote_section``), except that the
    frame tests' effect intervals are not bootstrapped (``n_boot=0``: no claim rests on
    them, the p-values do not depend on them).

    Returns
    -------
    DataFrame
        ``task``, ``family`` (:data:`FAMILIES`), ``scene``, ``p_value`` (unadjusted),
        ``significant`` (the report's verdict: Holm where the report applies it),
        ``for_algorithm`` (the significant claim favours the algorithm / ours).
    """
    parts = []
    if not pose.empty:
        t = fr.closeness_tests(
            pose, scenes, n_boot=0, seed=seed, alpha=alpha, n_permutations=n_permutations
        )
        t = t[t["p_value"].notna()]
        parts.append(
            pd.DataFrame(
                {
                    "task": "pose",
                    "family": t["comparison"],
                    "scene": t["scene"],
                    "p_value": t["p_value"],
                    "significant": t["significant"].astype(bool),
                    "for_algorithm": t["significant"].astype(bool),
                }
            )
        )
    if not views.empty:
        counts = vt.vote_counts(views, order=order)
        chi = vt.chisquare_no_preference(counts, alpha=alpha)
        parts.append(
            pd.DataFrame(
                {
                    "task": "view",
                    "family": "no preference (chi-square)",
                    "scene": chi["scene"],
                    "p_value": chi["p_value"],
                    "significant": chi["significant"].astype(bool),
                    "for_algorithm": chi["significant"].astype(bool)
                    & (counts["ours"].to_numpy() == counts.max(axis=1).to_numpy()),
                }
            )
        )
        pair = vt.ours_vs_baselines(counts, alpha=alpha)
        parts.append(
            pd.DataFrame(
                {
                    "task": "view",
                    "family": "ours vs " + pair["baseline"].astype(str),
                    "scene": pair["scene"],
                    "p_value": pair["p_value"],
                    "significant": pair["significant"].astype(bool),
                    "for_algorithm": pair["verdict"] == "ours preferred",
                }
            )
        )
        k = vt.fleiss_kappa(counts).iloc[0]
        parts.append(
            pd.DataFrame(
                {
                    "task": "view",
                    "family": ["agreement (Fleiss kappa)"],
                    "scene": ["ALL"],
                    "p_value": [float(k["p_value"])],
                    "significant": [bool(k["p_value"] < alpha)],
                    "for_algorithm": [bool(k["p_value"] < alpha)],
                }
            )
        )
    return pd.concat(parts, ignore_index=True) if parts else pd.DataFrame()


def simulate_study(design, condition: Condition, n: int, seed: int) -> pd.DataFrame:
    """One simulated study of ``n`` observers of ``condition``: export-shaped rows."""
    if condition.strengths is not None:
        design = sim.with_strengths(design, condition.strengths)
    people = sim.simulate_participants(design, n, seed=seed, model=condition.model)
    return sim.simulated_rows(people)


def calibrate(
    manifest,
    *,
    conditions=tuple(CONDITIONS),
    n_participants: int = 100,
    n_studies: int = 400,
    n_permutations: int = 999,
    alpha: float = vt.ALPHA,
    seed: int = 0,
    progress: bool = False,
    n_studies_alternative: int | None = None,
) -> pd.DataFrame:
    """Run the report's tests on ``n_studies`` simulated studies per condition.

    Under an alternative only the task it is an alternative for is analysed (its other
    task repeats a null the null conditions measure already).

    Parameters
    ----------
    manifest : str, Path or dict
        The stimuli manifest: the scenes, their algorithm and baseline frames.
    conditions : sequence of str
        Names in :data:`CONDITIONS`.
    n_participants : int
        Observers per study (all finish).
    n_studies : int
        Studies per null condition.
    n_studies_alternative : int, optional
        Studies per alternative (default ``n_studies``).
    n_permutations : int
        Permutations of each frame test (the report's default is
        :data:`analysis.frames.N_PERMUTATIONS`; the Monte-Carlo p-value is valid at
        every B, a smaller B only coarsens it).
    seed : int
        Seed of everything: study ``j`` of condition ``c`` is simulated from
        ``SeedSequence([seed, c, j])``, its permutations from ``seed + j``.

    Returns
    -------
    DataFrame
        One row per scene-level test of every study: ``condition``, ``study`` and the
        columns of :func:`report_tests`.
    """
    from tqdm import tqdm

    from .stimuli import stimuli_scenes

    unknown = [c for c in conditions if c not in CONDITIONS]
    if unknown:
        raise ValueError(f"conditions: unknown {unknown}; expected some of {list(CONDITIONS)}")
    design = sim.design_from_stimuli(manifest)
    order = list(stimuli_scenes(manifest)["scene"])
    extra = fr.baselines_from_stimuli(manifest)
    out = []
    n_alt = n_studies if n_studies_alternative is None else n_studies_alternative

    def studies(c):
        return n_studies if c.pose_null and c.view_null else n_alt

    bar = tqdm(
        total=sum(studies(CONDITIONS[c]) for c in conditions),
        desc="calibrate",
        unit="study",
        disable=not progress,
    )
    for ci, name in enumerate(conditions):
        cond = CONDITIONS[name]
        scenes = None
        for j in range(studies(cond)):
            study_seed = int(np.random.SeedSequence([seed, ci, j]).generate_state(1)[0])
            df = simulate_study(design, cond, n_participants, study_seed)
            pose, views = pose_choices(df), view_choices(df)
            if not cond.pose_null:
                views = views.iloc[:0]
            elif not cond.view_null:
                pose = pose.iloc[:0]
            if scenes is None:  # the same for every study of the design: read once
                scenes = fr.scene_frames_from_rows(pose_choices(df), extra=extra, order=order)
            t = report_tests(
                pose,
                views,
                scenes,
                order=order,
                alpha=alpha,
                seed=seed + j,
                n_permutations=n_permutations,
            )
            out.append(t.assign(condition=name, study=j))
            bar.update()
    bar.close()
    return pd.concat(out, ignore_index=True)


def _cp(k: int, n: int) -> tuple[float, float]:
    from scipy import stats

    if n == 0:
        return float("nan"), float("nan")
    ci = stats.binomtest(int(k), int(n)).proportion_ci(method="exact")
    return float(ci.low), float(ci.high)


#: One-sided normal quantile of the level check's Monte-Carlo margin (0.1%).
MARGIN_Z = 3.09


def summarise(results: pd.DataFrame, *, alpha: float = vt.ALPHA) -> pd.DataFrame:
    """Per condition and family: the false-positive rate (nulls) or power (alternatives).

    Returns
    -------
    DataFrame
        ``condition``, ``task``, ``family``, ``role`` ("null" / "alternative"),
        ``studies``, ``tests``; ``rate`` (share of tests the report calls significant —
        under an alternative, significant *for* the algorithm/ours) with ``rate_low`` /
        ``rate_high`` (Clopper–Pearson 95%); ``unadjusted`` (p < α) with its interval;
        ``any_study`` (share of studies with a significant test) with its interval;
        ``bound`` (α + 3.09 Monte-Carlo SE; nulls only) and ``holds`` (``rate`` and
        ``unadjusted`` both at most ``bound``; nulls only).
    """
    rows = []
    for (cond, task, family), g in results.groupby(["condition", "task", "family"], sort=False):
        c = CONDITIONS[cond]
        # Fleiss' kappa asks whether scenes differ in their vote shares; every condition
        # here gives every scene the same strengths, so its null holds in all of them.
        null = (c.pose_null if task == "pose" else c.view_null) or family == KAPPA
        hit = g["significant"] if null else g["for_algorithm"]
        raw = g["p_value"] < alpha
        per_study = hit.groupby(g["study"]).mean()
        raw_study = raw.groupby(g["study"]).mean()
        n, s = len(g), int(per_study.size)
        row = {
            "condition": cond,
            "task": task,
            "family": family,
            "role": "null" if null else "alternative",
            "studies": s,
            "tests": n,
            "rate": float(hit.mean()),
        }
        row["rate_low"], row["rate_high"] = _cp(int(hit.sum()), n)
        row["unadjusted"] = float(raw.mean())
        row["unadjusted_low"], row["unadjusted_high"] = _cp(int(raw.sum()), n)
        anys = hit.groupby(g["study"]).any()
        row["any_study"] = float(anys.mean())
        row["any_study_low"], row["any_study_high"] = _cp(int(anys.sum()), s)
        if null:
            spread = max(float(per_study.std(ddof=1)), float(raw_study.std(ddof=1))) if s > 1 else 0
            se = max(np.sqrt(alpha * (1 - alpha) / n), spread / np.sqrt(max(s, 1)))
            row["bound"] = alpha + MARGIN_Z * se
            row["holds"] = bool(row["rate"] <= row["bound"] and row["unadjusted"] <= row["bound"])
        else:
            row["bound"], row["holds"] = float("nan"), None
        rows.append(row)
    return pd.DataFrame(rows)


def power_by_scene(results: pd.DataFrame) -> pd.DataFrame:
    """Under each alternative, the power of each family in each scene (rows: condition
    and family; columns: scenes) — where a family's power comes from."""
    alt = results[
        [
            not (CONDITIONS[c].pose_null if t == "pose" else CONDITIONS[c].view_null) and f != KAPPA
            for c, t, f in zip(
                results["condition"], results["task"], results["family"], strict=True
            )
        ]
    ]
    if alt.empty:
        return pd.DataFrame()
    out = alt.pivot_table(
        index=["condition", "task", "family"],
        columns="scene",
        values="for_algorithm",
        aggfunc="mean",
        sort=False,
    )
    out.columns.name = None
    return out.reset_index()


def _cell(v, lo, hi) -> str:
    return f"{v:.3f} [{lo:.3f}, {hi:.3f}]"


def markdown_report(
    summary: pd.DataFrame, *, header: str = "", by_scene: pd.DataFrame | None = None
) -> str:
    """The calibration tables as Markdown: false-positive rates under the nulls, then
    power (and, given :func:`power_by_scene`, the power per scene)."""
    lines = [header.rstrip(), ""] if header else []
    nulls = summary[summary["role"] == "null"]
    alts = summary[summary["role"] == "alternative"]
    if not nulls.empty:
        lines += [
            "### False-positive rates under the nulls",
            "",
            "Share of scene-level tests the report calls significant (Holm where the report "
            "applies it) / the same without Holm (p < α) / share of studies with any "
            "significant test; Clopper–Pearson 95% intervals. *holds*: both rates at most "
            "α + 3.09 Monte-Carlo standard errors (the bound shown).",
            "",
            "| null | family | tests | as reported | p < α | studies with any | bound | holds |",
            "|---|---|---:|---|---|---|---:|---|",
        ]
        for r in nulls.itertuples():
            lines.append(
                f"| {r.condition} | {r.task}: {r.family} | {r.tests} | "
                f"{_cell(r.rate, r.rate_low, r.rate_high)} | "
                f"{_cell(r.unadjusted, r.unadjusted_low, r.unadjusted_high)} | "
                f"{_cell(r.any_study, r.any_study_low, r.any_study_high)} | "
                f"{r.bound:.3f} | {'yes' if r.holds else '**no**'} |"
            )
        lines.append("")
    if not alts.empty:
        lines += [
            "### Power under the alternatives",
            "",
            "Share of scene-level tests the report calls significant *in favour of* the "
            "algorithm (pose) or of ours (view), Clopper–Pearson 95%; and the share of "
            "studies with at least one such test.",
            "",
            "| alternative | family | tests | power | studies with any |",
            "|---|---|---:|---|---|",
        ]
        for r in alts.itertuples():
            lines.append(
                f"| {r.condition} | {r.task}: {r.family} | {r.tests} | "
                f"{_cell(r.rate, r.rate_low, r.rate_high)} | "
                f"{_cell(r.any_study, r.any_study_low, r.any_study_high)} |"
            )
        lines.append("")
    if by_scene is not None and not by_scene.empty:
        scenes = [c for c in by_scene.columns if c not in ("condition", "task", "family")]
        lines += [
            "### Power per scene",
            "",
            "Share of studies in which the scene's test is significant in favour of the "
            "algorithm / ours (empty: not tested, e.g. a baseline on the algorithm's frame).",
            "",
            "| alternative | family | " + " | ".join(scenes) + " |",
            "|---|---|" + "---:|" * len(scenes),
        ]
        for r in by_scene.to_dict(orient="records"):
            cells = ["" if pd.isna(r[s]) else f"{r[s]:.2f}" for s in scenes]
            lines.append(
                f"| {r['condition']} | {r['task']}: {r['family']} | " + " | ".join(cells) + " |"
            )
        lines.append("")
    return "\n".join(lines)


def console_table(summary: pd.DataFrame) -> pd.DataFrame:
    """The summary narrowed for the terminal (rates rounded, ``holds`` as yes / NO)."""
    return summary.assign(
        family=summary["task"] + ": " + summary["family"],
        holds=summary["holds"].map({True: "yes", False: "NO"}).fillna(""),
    )[
        [
            "condition",
            "role",
            "family",
            "tests",
            "rate",
            "rate_low",
            "rate_high",
            "unadjusted",
            "any_study",
            "holds",
        ]
    ].round(3)


def docs_header(command: str, manifest: dict, conditions) -> str:
    """The Markdown header of the docs table: the command, the stimuli, the conditions."""
    from datetime import UTC, datetime

    scenes = [s["id"] for s in manifest.get("scenes", [])]
    return (
        "<!-- written by `snapshot calibrate --write-docs`; do not edit by hand -->\n"
        "## Calibration of the report's tests\n\n"
        f"`{command}` on {datetime.now(UTC):%Y-%m-%d}, over the {len(scenes)} scenes of "
        f"the stimuli ({', '.join(scenes)}). Conditions: "
        + "; ".join(f"**{n}**: {CONDITIONS[n].text}" for n in conditions)
        + ". How the tests work and why: [frame-tests.md](frame-tests.md).\n"
    )
