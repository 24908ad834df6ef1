"""The sections of ``snapshot analyze``'s report: for the view votes, the chosen frames,
the pose selectors, near-duplicate candidates and replaced views, each writes its tables
and figures and returns its HTML sections (and summary entries); also the participants
table, the page's compact versions of wide tables, and the Methods text.
"""

from __future__ import annotations

import html
import math

import numpy as np
import pandas as pd

from . import frames as fr
from . import votes as vt
from .load import completed_participants
from .tables import _fmt, write_table


def _ci(v, lo, hi) -> str:
    return f"{v:.2f} [{lo:.2f}, {hi:.2f}]"


def _compact_pairwise(pair: pd.DataFrame) -> pd.DataFrame:
    """The pairwise table narrowed for the page (the CSV keeps every column)."""
    return pd.DataFrame(
        {
            "scene": pair["scene"],
            "baseline": pair["baseline"],
            "votes ours : baseline": [
                f"{a} : {b}"
                for a, b in zip(pair["reference_votes"], pair["baseline_votes"], strict=True)
            ],
            "share of ours [95% CP]": [
                _ci(v, lo, hi)
                for v, lo, hi in zip(
                    pair["share_reference"], pair["ci_low"], pair["ci_high"], strict=True
                )
            ],
            "p_value": pair["p_value"],
            "p_holm": pair["p_holm"],
            "verdict": pair["verdict"],
        }
    )


def _pct(v, lo=None, hi=None) -> str:
    if lo is None or (isinstance(lo, float) and math.isnan(lo)):
        return f"{100 * v:.0f}%"
    return f"{100 * v:.0f}% [{100 * lo:.0f}, {100 * hi:.0f}]"


def _compact_hits(hits: pd.DataFrame, tolerances=fr.TOLERANCES_S) -> pd.DataFrame:
    """Hit rates for the page: one ``rate [low, high]`` cell per tolerance."""
    out = pd.DataFrame(
        {
            "scene": hits["scene"],
            "predictor": hits["predictor"],
            "frame": hits["predicted_frame"],
            "mean |Δ| s": hits["mean_abs_error_s"],
            "median |Δ| s": hits["median_abs_error_s"],
        }
    )
    for t in tolerances:
        c = f"hit_{t:g}s"
        out[f"within ±{t:g} s"] = [
            _pct(v, lo, hi)
            for v, lo, hi in zip(hits[c], hits[c + "_low"], hits[c + "_high"], strict=True)
        ]
    return out


def _compact_tests(tests: pd.DataFrame) -> pd.DataFrame:
    """The frame tests for the page (the CSV keeps every column)."""
    return pd.DataFrame(
        {
            "scene": tests["scene"],
            "test": np.where(
                tests["comparison"] == "agreement",
                "agreement",
                "closer than " + tests["comparison"].astype(str),
            ),
            "n": tests["n"],
            "mean |Δ| algorithm s": tests["algorithm_mean_abs_s"],
            "mean |Δ| baseline s": tests["baseline_mean_abs_s"],
            "beyond habits s [95% CI]": [
                _ci(v, lo, hi)
                for v, lo, hi in zip(
                    tests["beyond_habit_s"],
                    tests["beyond_habit_low"],
                    tests["beyond_habit_high"],
                    strict=True,
                )
            ],
            "p_value": tests["p_value"],
            "p_holm": tests["p_holm"],
            "significant": tests["significant"],
            "note": tests["note"],
        }
    )


def _compact_strengths(strengths: pd.DataFrame) -> pd.DataFrame:
    """Strengths as scenes × methods, each cell ``value [low, high]``."""
    cell = strengths.assign(
        text=[
            _ci(v, lo, hi)
            for v, lo, hi in zip(
                strengths["strength"], strengths["ci_low"], strengths["ci_high"], strict=True
            )
        ]
    )
    wide = cell.pivot(index="scene", columns="method", values="text")
    wide = wide.loc[
        list(dict.fromkeys(strengths["scene"])), list(dict.fromkeys(strengths["method"]))
    ]
    wide.columns.name = None
    return wide.reset_index()


def _figure(make, stem, *, figures: bool) -> list:
    """``[the PNG's path]`` of the figure ``make()`` draws, written as PNG and PDF at
    ``stem``; ``[]`` when the report is made without figures (nothing is drawn)."""
    if not figures:
        return []
    from .plots import save_figure

    return [save_figure(make(), stem)[0]]


def _vote_section(counts, out, *, labels, n_boot, seed, alpha, choices=None, figures=True):
    """Every vote table and figure; returns (html sections, summary dict)."""
    from .plots import plot_strengths, plot_votes

    tables, figs = out / "tables", out / "figures"
    table = vt.vote_table(counts)
    chi = vt.chisquare_no_preference(counts, alpha=alpha, choices=choices)
    pair = vt.ours_vs_baselines(counts, alpha=alpha, choices=choices)
    choices = vt.choices_from_counts(counts) if choices is None else choices
    strengths = vt.luce_strengths(choices, n_boot=n_boot, seed=seed, order=list(counts.index))
    kappa = vt.fleiss_kappa(counts)
    claims = vt.claim_summary(pair, alpha=alpha, labels=labels)
    write_table(
        table,
        tables / "votes",
        caption="Votes per method per scene with shares and 95% Wilson intervals."
        + (
            " Alike candidate pictures were shown once: a choice of such a picture is a "
            "vote for each method it stood for (so a scene's votes can exceed its "
            "choices, n, and shares are of choices); a test between two methods leaves "
            "out the trials where they shared a picture."
            if (table["n"] < table.groupby("scene")["votes"].transform("sum")).any()
            else ""
        ),
    )
    write_table(
        chi,
        tables / "chisquare",
        caption="Chi-square goodness-of-fit test against no preference, per scene.",
    )
    write_table(
        pair,
        tables / "pairwise",
        caption="Ours vs each baseline: exact two-sided binomial test among the two "
        "methods' votes, Holm-adjusted over all scenes and baselines.",
    )
    write_table(
        strengths,
        tables / "strengths",
        caption=f"Luce strengths (choix ilsr_top1) with 95% percentile bootstrap "
        f"intervals ({n_boot} resamples, seed {seed}).",
    )
    write_table(kappa, tables / "agreement", caption="Fleiss' kappa over scenes.")
    f_votes = _figure(
        lambda: plot_votes(table, pairwise=pair, labels=labels), figs / "votes", figures=figures
    )
    f_str = _figure(
        lambda: plot_strengths(strengths, labels=labels), figs / "strengths", figures=figures
    )
    k = kappa.iloc[0]
    wide = counts.copy()
    wide.insert(0, "scene", [labels.get(s, s) for s in counts.index])
    sections = [
        (
            "Views: which method's view do people prefer?",
            [wide.reset_index(drop=True), *f_votes]
            + [f"<div class='claim'>{html.escape(c)}</div>" for c in claims],
        ),
        ("No preference? Chi-square per scene", [chi]),
        ("Ours vs each baseline (exact binomial, Holm)", [_compact_pairwise(pair)]),
        (
            "Method strengths (Luce model: probability of being chosen, 95% bootstrap CI)",
            [_compact_strengths(strengths), *f_str],
        ),
        (
            "Agreement",
            [
                f"Fleiss' kappa over {int(k['n_items'])} scenes = {k['kappa']:.3f} "
                f"(chance-corrected agreement on the best view; 0 = chance, 1 = all "
                f"agree); z = {k['z']:.2f}, one-sided p = {_fmt('p_value', k['p_value'])}."
            ],
        ),
    ]
    summary = {
        "claims": claims,
        "votes": {s: {m: int(v) for m, v in row.items()} for s, row in counts.iterrows()},
        "chisquare_p": dict(zip(chi["scene"], chi["p_value"].astype(float), strict=True)),
        "pairwise": pair[["scene", "baseline", "p_value", "p_holm", "verdict"]].to_dict(
            orient="records"
        ),
        "fleiss_kappa": float(k["kappa"]),
    }
    return sections, summary


def _frame_section(pose, out, *, scenes, n_permutations, seed, alpha, figures=True):
    from .plots import plot_error_distributions, plot_frame_histograms

    tables, figs = out / "tables", out / "figures"
    hits = fr.hit_rates(pose, scenes)
    tests = fr.closeness_tests(pose, scenes, seed=seed, alpha=alpha, n_permutations=n_permutations)
    dist = fr.frame_distances(pose, scenes)
    write_table(
        hits,
        tables / "frame_hits",
        caption="Distance of chosen frames to each predictor and hit rates within "
        "±0.25/0.5/1 s (Wilson 95% intervals).",
    )
    write_table(
        tests,
        tables / "frame_tests",
        caption="Do people's picks follow the algorithm's frame? Per scene: agreement "
        "(closeness to the algorithm's frame) and closer-than-X (distance to X minus "
        "distance to the algorithm), each against what the same participants' "
        f"clip-position habits predict: one-sided within-participant permutation over "
        f"scenes ({n_permutations} permutations), effect beyond habits (s) with a 95% "
        "bootstrap interval over participants; Holm over the tests (a baseline on the "
        "algorithm's frame is not tested); closer-than-X is significant only when people "
        "are also closer to the algorithm on average.",
    )
    f_hist = _figure(
        lambda: plot_frame_histograms(pose, scenes),
        figs / "fig13_frame_histograms",
        figures=figures,
    )
    f_err = _figure(
        lambda: plot_error_distributions(dist, scenes, hits=hits),
        figs / "frame_distances",
        figures=figures,
    )
    algo = hits[hits["predictor"] == "algorithm"]
    lines = [
        f"{scenes[r['scene']].title or r['scene']}: median |chosen − algorithm| = "
        f"{r['median_abs_error_s']:.2f} s; {100 * r['hit_0.5s']:.0f}% of people within "
        f"±0.5 s, {100 * r['hit_1s']:.0f}% within ±1 s."
        for r in algo.to_dict(orient="records")
    ]
    verdict = _frame_verdict(tests, scenes, alpha)
    missing = [s for s, i in scenes.items() if not i.baseline_frames]
    note = (
        "The fastest and most-stretched baselines are the selectors' picks recorded in "
        f"the stimuli manifest; they are missing for {', '.join(missing)} (pass "
        "--stimuli manifest.json)."
        if missing
        else ""
    )
    sections = [
        (
            "Poses: which frame do people pick?",
            [
                *f_hist,
                *lines,
                f"<div class='claim'>{html.escape(verdict)}</div>",
                _compact_hits(hits),
                _compact_tests(tests),
                *f_err,
            ]
            + ([f"<p class='note'>{html.escape(note)}</p>"] if note else []),
        )
    ]
    summary = {
        "frames": algo[
            ["scene", "n", "median_abs_error_s", "hit_0.25s", "hit_0.5s", "hit_1s"]
        ].to_dict(orient="records"),
        "frame_verdict": verdict,
    }
    sections += _selector_section(pose, out, scenes=scenes, figures=figures)
    return sections, summary


def _frame_verdict(tests: pd.DataFrame, scenes: dict, alpha: float) -> str:
    """One sentence: where the picks follow the algorithm beyond position habits."""

    def name(s):
        return scenes[s].title or s

    def listed(rows):
        return ", ".join(name(s) for s in rows["scene"]) or "none"

    tested = tests[tests["p_value"].notna()]
    agree = tested[tested["comparison"] == "agreement"]
    text = (
        f"Beyond the participants' clip-position habits (within-participant permutation "
        f"over scenes, Holm, α = {alpha:g}), picks gather at the algorithm's frame in: "
        f"{listed(agree[agree['significant']])}; not significantly in: "
        f"{listed(agree[~agree['significant']])}."
    )
    closer = tested[(tested["comparison"] != "agreement") & tested["significant"]]
    text += (
        " Closer to the algorithm than to "
        + (
            ", ".join(
                f"{b} in {name(s)}"
                for s, b in zip(closer["scene"], closer["comparison"], strict=True)
            )
            or "no baseline in any scene"
        )
        + "."
    )
    return text


def _selector_section(pose, out, *, scenes, figures=True):
    """Every pose selector against the people's choices (when the manifest has them)."""
    agree = fr.selector_agreement(pose, scenes)
    if agree.empty:
        return []
    write_table(
        agree,
        out / "tables" / "selector_agreement",
        caption="Each pose selector's top pick against the people's chosen frames: "
        "share of choices within ±0.5 s (Wilson 95%) and median distance.",
    )
    overall = agree[agree["scene"] == "ALL"].sort_values(
        ["hit", "median_abs_error_s"], ascending=[False, True]
    )
    best = overall.iloc[0]
    text = (
        f"Across scenes, the selector whose pick agrees with people best is "
        f"{best['selector']}: {100 * best['hit']:.0f}% of choices within ±0.5 s "
        f"(median distance {best['median_abs_error_s']:.2f} s)."
    )
    parts = [text, overall.round(3)]
    doc = fr.selector_timeline_document(pose, scenes)
    if doc is not None:

        def timeline():
            from snapcore.render.keymoments_plot import plot_keymoment_timelines

            extra = {
                s: pose.loc[pose["scene"] == s, "chosen_frame"].astype(int).tolist() for s in scenes
            }
            fig = plot_keymoment_timelines(doc, extra=extra)
            # The shared plot's title describes key-moment intervals (green), which this
            # figure has none of: say what is drawn.
            fig.axes[0].set_title(
                "each selector's picks (filled: top pick, hollow: picks 2..k) "
                "and the people's chosen frames (grey ticks)",
                fontsize=9,
            )
            return fig

        parts[:0] = _figure(timeline, out / "figures" / "selector_timeline", figures=figures)
    return [("Poses: which selector agrees with people?", parts)]


_METHODS_TEXT = (
    "Methods. Vote shares: Wilson score 95% intervals. No preference: Pearson chi-square "
    "goodness of fit against equal shares. Ours vs each baseline: exact two-sided binomial test "
    "of ours' share among the votes for the two (null 1/2), Clopper–Pearson intervals, Holm "
    "adjustment over every scene × baseline. Strengths: Luce choice model fitted by iterative "
    "Luce spectral ranking (choix.ilsr_top1), percentile bootstrap over choices. Agreement: "
    "Fleiss' kappa (scenes = items, methods = categories). Frames: distances in seconds; hit "
    "rates within ±0.25/0.5/1 s (descriptive) of the algorithm's frame, the middle frame, a "
    "uniformly random frame (exact expectation) and the fastest and most-stretched poses (the "
    "pose selectors' picks). Frame tests: per scene, agreement (closeness to the algorithm's "
    "frame) and closer-than-X for each baseline X (distance to X minus distance to the "
    "algorithm), each a one-sided within-participant permutation test over scenes (Ernst "
    "2004, Statistical Science 19:676): every participant's chosen clip positions (the frame "
    "as a fraction of the clip) are permuted over the scenes they saw, so the null is that "
    "a person's clip position does not depend on the scene — random clicking, a preference "
    "for the middle of the clip or a personal habit — and a significant test says the picks "
    "in that scene follow the algorithm's frame more than those habits explain. Monte-Carlo "
    "p = (1 + #{T* ≥ T})/(1 + B); effects: the mean excess over the habits' prediction, "
    "percentile bootstrap over participants; Holm over the frame tests (a baseline on the "
    "algorithm's frame is reported, not tested); closer-than-X also needs people to be closer "
    "to the algorithm than to X on average. The tests have little power where the "
    "algorithm's frames sit at similar clip positions in every scene. False-positive rates "
    "and power by simulation: snapshot calibrate (docs/calibration.md). Rows pooled over "
    "scenes: intervals from a bootstrap over participants."
)


def _duplicate_section(counts, dupes, out, *, labels, alpha):
    """Near-duplicate candidates: which scenes, and the votes with each pair as one option."""
    pairs = {}
    for r in dupes.itertuples():
        pairs.setdefault(r.scene, []).append((r.method_a, r.method_b))
    merged = vt.merge_near_duplicates(counts, pairs)
    write_table(
        dupes,
        out / "tables" / "near_duplicates",
        caption="Candidate views that are nearly the same picture (angle between their "
        "directions; over 90° means a near mirror image).",
    )
    write_table(
        merged,
        out / "tables" / "votes_duplicates_merged",
        caption="Sensitivity analysis: near-duplicate candidates counted as one option; "
        "chi-square against equal votes per distinct picture.",
    )
    keep = [s for s in counts.index if s not in pairs]
    text = [
        f"In {len(pairs)} scene(s) two candidates are nearly the same picture "
        f"({', '.join(labels.get(s, s) for s in pairs)}); votes may split between them."
    ]
    items = [dupes, *text, merged]
    if keep and len(keep) < len(counts):
        claims = vt.claim_summary(
            vt.ours_vs_baselines(counts.loc[keep], alpha=alpha), alpha=alpha, labels=labels
        )
        items += ["Without those scenes:"] + [
            f"<div class='claim'>{html.escape(c)}</div>" for c in claims
        ]
    return [("Near-duplicate candidates: sensitivity analysis", items)]


def _replaced_section(replaced, out):
    """Baseline views replaced at build time: which, why, and how far down its ranking."""
    write_table(
        replaced,
        out / "tables" / "replaced_views",
        caption="Baseline views replaced by the stimuli builder because their picture was "
        "nearly another candidate's (silhouette IoU, mirror images included): each by the "
        "best view of the same method's score whose picture is not.",
    )
    text = (
        f"{len(replaced)} baseline view(s) were replaced because their picture was nearly "
        "another candidate's; in those scenes a vote for that baseline is a vote for its "
        "best view unlike the others, not for its own pick."
    )
    return [("Replaced candidate views", [text, replaced])]


def _participants_table(
    df: pd.DataFrame, att: pd.DataFrame, *, done=None, records=None
) -> pd.DataFrame:
    """Participants (real, simulated): started (every record, else who answered),
    completed (``done``: finished, not excluded), their responses and attention."""
    g = df.groupby("simulated")
    rows = []
    done = completed_participants(df) if done is None else done
    for sim, part in g:
        started = (
            int(part["participant_id"].nunique())
            if records is None
            else sum(bool(r.get("simulated")) == bool(sim) for r in records)
        )
        rows.append(
            {
                "participants": "simulated" if sim else "real",
                "n": int(part["participant_id"].nunique()),
                "started": started,
                "completed": len(set(part["participant_id"]) & done),
                "responses": len(part),
                "pose_choices": int((part["task"] == "pose").sum()),
                "view_choices": int((part["task"] == "view").sum()),
                "attention_passed": int(
                    att[att["participant_id"].isin(part["participant_id"])]["passed"].sum()
                ),
                "median_response_time_s": float(part["response_time_s"].median()),
            }
        )
    return pd.DataFrame(rows)
