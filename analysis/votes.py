"""View-task votes (the paper's Table 2) with the statistics the paper left out.

All functions take vote *counts* as a wide DataFrame — one row per scene (the index),
one column per method (``ours``, ``viewpoint_entropy``, ``motion_area``) — made by
:func:`vote_counts` from view-task choices or by :func:`paper_counts` from the paper's
published table, and return tidy DataFrames whose columns are documented below. The
Luce model (:func:`luce_strengths`) works from the individual choices instead, because
it uses which methods were on screen.

Choices of method made here, stated once:

- Per-method vote shares get **Wilson score** 95% intervals (no continuity
  correction): ``scipy.stats.binomtest(k, n).proportion_ci(method="wilson")``.
- "No preference" is Pearson's chi-square goodness-of-fit test against equal shares.
- Merged candidates (``study.near_duplicate = "merge"``: alike pictures shown once, the
  row's ``shown_groups`` says which methods each picture stood for): a choice of such a
  picture is a vote for **each** method it stood for in the vote table (so a scene's
  votes may sum to more than its choices; shares are of choices, ``n``), and a pairwise
  test between two methods takes nothing from a trial where they shared a picture.
- Ours vs each baseline is the **exact two-sided binomial test** of ours' share among the
  votes cast for the two (conditional on ``ours + baseline`` votes; null share 1/2), with
  a **Clopper–Pearson** interval for that share, and the **Holm** step-down adjustment
  over the whole family (every scene × every baseline) by default.
- Strengths: the Luce choice model fitted with ``choix.ilsr_top1`` (maximum likelihood,
  tiny ridge ``LUCE_ALPHA`` so that a method nobody chose stays finite), reported as
  the probability of being chosen when all methods are shown; percentile bootstrap
  intervals from resampling choices (seeded).
- Agreement: Fleiss' kappa with scenes as the rated items, methods as categories and
  participants as raters.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable, Mapping, Sequence
from importlib.resources import files
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike
from scipy import stats

from snapcore.select.view_methods import VIEW_METHODS

from .load import SceneOrder, ordered_scenes

__all__ = [
    "ALPHA",
    "LUCE_ALPHA",
    "MIN_EXPECTED",
    "paper_table2",
    "paper_counts",
    "vote_counts",
    "credited_methods",
    "pair_votes",
    "choices_from_counts",
    "wilson_interval",
    "merge_near_duplicates",
    "holm_adjust",
    "vote_table",
    "chisquare_no_preference",
    "ours_vs_baselines",
    "luce_strengths",
    "fleiss_kappa",
    "claim_summary",
]

#: Significance level used for every "significant" column and sentence.
ALPHA = 0.05
#: Ridge added by ``choix.ilsr_top1`` (its ``alpha``): keeps a zero-vote method finite.
#: With 100 votes it moves a share by < 1e-4, far below the bootstrap spread.
LUCE_ALPHA = 1e-3
#: Pearson's chi-square is approximate; below this expected count per cell it is flagged.
MIN_EXPECTED = 5.0


# ----------------------------------------------------------------- counts


def paper_table2() -> pd.DataFrame:
    """The paper's Table 2 as tidy rows (package data, with its source).

    Returns
    -------
    DataFrame
        Columns ``scene`` (id), ``scene_label`` (the paper's caption), ``method``,
        ``figure`` (the paper's figure showing that method's view), ``votes`` (of 100
        participants), ``source``.
    """
    path = files("analysis") / "data" / "paper_table2.csv"
    with path.open("r", encoding="utf-8") as fh:
        return pd.read_csv(fh)


def paper_counts() -> pd.DataFrame:
    """The paper's Table 2 as wide counts (scenes × methods), in the paper's order."""
    t = paper_table2()
    wide = t.pivot(index="scene", columns="method", values="votes")
    wide = wide.loc[list(dict.fromkeys(t["scene"])), list(VIEW_METHODS)]
    wide.columns.name = None
    return wide.astype(int)


def _groups(row: Mapping[str, Any]) -> list[tuple[str, ...]]:
    """The methods each picture of a view trial stood for: the row's ``shown_groups``,
    else each method of ``shown_order`` alone (rows before merging), else the chosen
    method alone (a count table)."""
    groups = row.get("shown_groups")
    if isinstance(groups, list | tuple) and len(groups):
        return [tuple(g) for g in groups]
    order = row.get("shown_order")
    if isinstance(order, list | tuple) and len(order):
        return [(m,) for m in order]
    return [(row["chosen_method"],)]


def credited_methods(row: Mapping[str, Any]) -> tuple[str, ...]:
    """The methods a view-task choice is a vote for: every method the chosen picture
    stood for (its ``shown_groups`` entry), else the chosen method alone."""
    for g in _groups(row):
        if row["chosen_method"] in g:
            return g
    return (row["chosen_method"],)


def vote_counts(
    choices: pd.DataFrame, *, methods: Sequence[str] = VIEW_METHODS, order: SceneOrder = None
) -> pd.DataFrame:
    """View-task choices → wide counts (scenes × ``methods``).

    A choice of a merged picture (alike candidates shown once, ``shown_groups``) counts
    for each method it stood for (:func:`credited_methods`); ``counts.attrs["choices"]``
    keeps the choices per scene (the shares' denominator, :func:`vote_table`).

    Parameters
    ----------
    choices : DataFrame
        Rows with ``scene`` and ``chosen_method``, optionally ``shown_groups`` and
        ``shown_order`` (e.g. :func:`analysis.load.view_choices`).
    order : sequence of str, optional
        Preferred scene order (see :func:`analysis.load.ordered_scenes`).
    """
    methods = [str(m) for m in methods]
    unknown = set(choices["chosen_method"].dropna()) - set(methods)
    if unknown:
        raise ValueError(f"chosen_method: unknown method(s) {sorted(unknown)}; expected {methods}")
    scenes = ordered_scenes(choices["scene"], order)
    rows = choices[choices["chosen_method"].notna()]
    credit = [
        (scene, m)
        for scene, row in zip(rows["scene"], rows.to_dict("records"), strict=True)
        for m in credited_methods(row)
    ]
    tab = pd.crosstab(
        pd.Series([c[0] for c in credit], dtype=object, name="scene"),
        pd.Series([c[1] for c in credit], dtype=object, name="chosen_method"),
    )
    tab = tab.reindex(index=scenes, columns=methods, fill_value=0)
    tab.index.name, tab.columns.name = "scene", None
    tab = tab.astype(int)
    tab.attrs["choices"] = rows.groupby("scene").size().reindex(scenes, fill_value=0).to_dict()
    return tab


def pair_votes(
    choices: pd.DataFrame, reference: str, baselines: Iterable[str], *, order: SceneOrder = None
) -> pd.DataFrame:
    """Votes for ``reference`` and each baseline, from the trials where the two had
    pictures of their own: a trial where they shared a picture (alike candidates merged)
    gives neither a vote (its choice says nothing about one against the other).

    Returns
    -------
    DataFrame
        ``scene``, ``baseline``, ``reference_votes``, ``baseline_votes``, ``shared``
        (trials left out because the two shared a picture).
    """
    scenes = ordered_scenes(choices["scene"], order)
    tally = {(s, b): [0, 0, 0] for s in scenes for b in baselines}
    for row in choices[choices["chosen_method"].notna()].to_dict("records"):
        credited = credited_methods(row)
        for b in baselines:
            t = tally[(row["scene"], b)]
            if any(reference in g and b in g for g in _groups(row)):
                t[2] += 1
            elif reference in credited:
                t[0] += 1
            elif b in credited:
                t[1] += 1
    return pd.DataFrame(
        [
            {"scene": s, "baseline": b, "reference_votes": k, "baseline_votes": j, "shared": n}
            for (s, b), (k, j, n) in tally.items()
        ]
    )


def choices_from_counts(counts: pd.DataFrame) -> pd.DataFrame:
    """Counts → one choice row per vote, every method shown (for the Luce fit).

    Returns
    -------
    DataFrame
        Columns ``scene``, ``chosen_method``, ``shown_order`` (tuple of all methods).
    """
    methods = tuple(counts.columns)
    scene, chosen = [], []
    for s, row in counts.iterrows():
        for m in methods:
            scene += [s] * int(row[m])
            chosen += [m] * int(row[m])
    return pd.DataFrame(
        {"scene": scene, "chosen_method": chosen, "shown_order": [methods] * len(scene)}
    )


# ----------------------------------------------------------------- small kernels


def wilson_interval(
    k: ArrayLike, n: ArrayLike, *, confidence: float = 0.95
) -> tuple[np.ndarray, np.ndarray]:
    """Wilson score interval for a binomial proportion ``k / n``.

    Parameters
    ----------
    k, n : array_like of int
        Successes and trials (broadcast together); ``n = 0`` gives ``(0, 1)``.
    confidence : float
        Coverage, e.g. 0.95.

    Returns
    -------
    low, high : ndarray of float

    Notes
    -----
    ``scipy.stats.binomtest(k, n).proportion_ci(confidence, method="wilson")`` per
    element: ``(p + z²/2n ± z sqrt(p(1-p)/n + z²/4n²)) / (1 + z²/n)`` with ``p = k/n``
    and ``z`` the two-sided normal quantile (Wilson 1927), without continuity correction.
    """
    k, n = np.broadcast_arrays(np.asarray(k, dtype=int), np.asarray(n, dtype=int))
    low, high = np.zeros(k.shape), np.ones(k.shape)
    for i in np.ndindex(k.shape):
        if n[i] > 0:
            ci = stats.binomtest(int(k[i]), int(n[i])).proportion_ci(confidence, method="wilson")
            low[i], high[i] = ci.low, ci.high
    return low, high


def holm_adjust(pvalues: ArrayLike) -> np.ndarray:
    """Holm (1979) step-down adjusted p-values, in the input's order.

    Sort ascending ``p_(1) <= ... <= p_(m)``; ``adj_(i) = max_{j<=i} min(1, (m-j+1) p_(j))``.
    Reject ``H_(i)`` at level α iff ``adj_(i) <= α``, which controls the family-wise error.
    """
    p = np.asarray(pvalues, dtype=float)
    m = p.size
    if m == 0:
        return p.copy()
    order = np.argsort(p, kind="stable")
    scaled = np.minimum(1.0, (m - np.arange(m)) * p[order])
    adjusted = np.maximum.accumulate(scaled)
    out = np.empty(m)
    out[order] = adjusted
    return out


# ----------------------------------------------------------------- tables


def vote_table(counts: pd.DataFrame, *, confidence: float = 0.95) -> pd.DataFrame:
    """Votes per method per scene with shares and Wilson intervals.

    Returns
    -------
    DataFrame
        ``scene``, ``method``, ``votes``, ``n`` (choices in the scene:
        ``counts.attrs["choices"]`` when a merged picture's choice counted for several
        methods, else the votes' sum), ``share`` (votes / n: the share of choices that
        went to a picture standing for the method), ``ci_low``, ``ci_high`` (Wilson
        score interval of the share at ``confidence``), ``rank`` (1 = most votes; ties
        share the best rank).
    """
    long = counts.reset_index().melt(
        id_vars=counts.index.name or "index", var_name="method", value_name="votes"
    )
    long = long.rename(columns={counts.index.name or "index": "scene"})
    scene_order = {s: i for i, s in enumerate(counts.index)}
    method_order = {m: i for i, m in enumerate(counts.columns)}
    long = long.sort_values(
        by=["scene", "method"],
        key=lambda c: c.map(scene_order if c.name == "scene" else method_order),
    )
    n = long.groupby("scene")["votes"].transform("sum")
    choices = counts.attrs.get("choices")
    if choices:
        n = long["scene"].map(choices).fillna(n)
    long["n"] = n.astype(int)
    long["share"] = long["votes"] / long["n"].where(long["n"] > 0)
    low, high = wilson_interval(long["votes"], long["n"], confidence=confidence)
    long["ci_low"], long["ci_high"] = low, high
    long["rank"] = long.groupby("scene")["votes"].rank(ascending=False, method="min").astype(int)
    return long.reset_index(drop=True)


def chisquare_no_preference(
    counts: pd.DataFrame, *, alpha: float = ALPHA, choices: pd.DataFrame | None = None
) -> pd.DataFrame:
    """Pearson's chi-square test per scene against "every method equally often chosen".

    With ``choices`` whose pictures were merged (``shown_groups``), a scene's test is of
    its pictures as shown ("every picture equally often chosen", one cell per picture:
    a merged picture's choice counted once), since its method counts credit one choice
    to several methods and are no sample of choices.

    Returns
    -------
    DataFrame
        ``scene``, ``n``, ``chi2``, ``dof`` (methods − 1), ``p_value``,
        ``min_expected`` (n / methods), ``significant`` (p < alpha), ``note``
        (a warning when the expected count is below ``MIN_EXPECTED``).

    Notes
    -----
    ``chi2 = Σ_j (O_j − E)² / E`` with ``E = n / k``; p from the chi-square
    distribution with ``k − 1`` degrees of freedom (same as
    ``scipy.stats.chisquare(observed)``).
    """
    if choices is not None and any(
        len(g) > 1 for r in choices.to_dict("records") for g in _groups(r)
    ):
        return _chisquare_pictures(counts, choices, alpha=alpha)
    obs = counts.to_numpy(dtype=float)
    k = obs.shape[1]
    n = obs.sum(axis=1)
    expected = n / k
    with np.errstate(invalid="ignore", divide="ignore"):
        chi2 = ((obs - expected[:, None]) ** 2 / expected[:, None]).sum(axis=1)
    p = np.where(n > 0, stats.chi2.sf(chi2, k - 1), 1.0)
    chi2 = np.where(n > 0, chi2, 0.0)
    note = np.where(
        expected < MIN_EXPECTED,
        f"expected count below {MIN_EXPECTED:g}: chi-square approximation is rough",
        "",
    )
    return pd.DataFrame(
        {
            "scene": counts.index,
            "n": n.astype(int),
            "chi2": chi2,
            "dof": k - 1,
            "p_value": p,
            "min_expected": expected,
            "significant": p < alpha,
            "note": note,
        }
    )


def _chisquare_pictures(
    counts: pd.DataFrame, choices: pd.DataFrame, *, alpha: float
) -> pd.DataFrame:
    """:func:`chisquare_no_preference` over each scene's pictures as shown."""
    rows = []
    chosen = choices[choices["chosen_method"].notna()].to_dict("records")
    for scene in counts.index:
        mine = [r for r in chosen if r["scene"] == scene]
        options = sorted({g for r in mine for g in _groups(r)})
        obs = np.array([sum(credited_methods(r) == g for r in mine) for g in options], float)
        n, k = obs.sum(), max(len(options), 1)
        e = n / k
        chi2 = float(((obs - e) ** 2 / e).sum()) if n > 0 and k > 1 else 0.0
        p = float(stats.chi2.sf(chi2, k - 1)) if n > 0 and k > 1 else 1.0
        rows.append(
            {
                "scene": scene,
                "n": int(n),
                "chi2": chi2,
                "dof": k - 1,
                "p_value": p,
                "min_expected": e,
                "significant": p < alpha,
                "note": (
                    f"expected count below {MIN_EXPECTED:g}: chi-square approximation is rough"
                    if e < MIN_EXPECTED
                    else ""
                )
                + (
                    f"; {k} pictures shown (alike candidates merged)" if k < counts.shape[1] else ""
                ),
            }
        )
    return pd.DataFrame(rows)


def ours_vs_baselines(
    counts: pd.DataFrame,
    *,
    reference: str = "ours",
    baselines: Sequence[str] | None = None,
    alpha: float = ALPHA,
    family: str = "all",
    confidence: float = 0.95,
    choices: pd.DataFrame | None = None,
) -> pd.DataFrame:
    """Exact binomial tests of ``reference`` against each baseline, Holm-adjusted.

    Parameters
    ----------
    counts : DataFrame
        Wide vote counts (scenes × methods).
    reference : str
        The method whose preference is claimed (the paper: ``"ours"``).
    baselines : sequence of str, optional
        Methods to compare against (default: every other column).
    alpha : float
        Family-wise error rate for ``significant`` / ``verdict``.
    family : {"all", "scene"}
        Holm over every scene × baseline test (default), or within each scene.
    confidence : float
        Coverage of the Clopper–Pearson interval of ``share_reference``.
    choices : DataFrame, optional
        The choices ``counts`` came from: the pair's votes are then taken from the
        trials where the two methods did not share a picture (:func:`pair_votes`; with
        merged candidates the counts credit a shared picture to both).

    Returns
    -------
    DataFrame
        ``scene``, ``baseline``, ``reference_votes``, ``baseline_votes``, ``n_pair``
        (their sum), ``share_reference`` (reference / n_pair), ``ci_low``, ``ci_high``
        (Clopper–Pearson), ``p_value`` (exact two-sided, null share 1/2), ``p_holm``,
        ``significant`` (p_holm < alpha), ``verdict`` (``"ours preferred"``,
        ``"baseline preferred"`` or ``"no significant difference"`` — with the real
        method names).
    """
    if reference not in counts.columns:
        raise ValueError(f"reference: '{reference}' is not a column of counts")
    if family not in ("all", "scene"):
        raise ValueError(f"family: expected 'all' or 'scene', got {family!r}")
    baselines = (
        [m for m in counts.columns if m != reference] if baselines is None else list(baselines)
    )
    pairs = (
        None
        if choices is None
        else pair_votes(choices, reference, baselines, order=list(counts.index)).set_index(
            ["scene", "baseline"]
        )
    )
    rows = []
    for scene, row in counts.iterrows():
        for b in baselines:
            if pairs is None:
                k, j = int(row[reference]), int(row[b])
            else:
                got = pairs.loc[(scene, b)]
                k, j = int(got["reference_votes"]), int(got["baseline_votes"])
            n = k + j
            if n > 0:
                p = stats.binomtest(k, n, 0.5).pvalue
                # Clopper-Pearson as beta quantiles: binomtest's proportion_ci(method=
                # "exact") finds the same bounds by root search, 50x slower.
                q = (1 - confidence) / 2
                lo = stats.beta.ppf(q, k, n - k + 1) if k > 0 else 0.0
                hi = stats.beta.ppf(1 - q, k + 1, n - k) if k < n else 1.0
            else:
                lo, hi, p = 0.0, 1.0, 1.0
            rows.append(
                {
                    "scene": scene,
                    "baseline": b,
                    "reference_votes": k,
                    "baseline_votes": j,
                    "n_pair": n,
                    "share_reference": k / n if n else np.nan,
                    "ci_low": lo,
                    "ci_high": hi,
                    "p_value": p,
                }
            )
    out = pd.DataFrame(rows)
    if family == "all":
        out["p_holm"] = holm_adjust(out["p_value"])
    else:
        out["p_holm"] = out.groupby("scene")["p_value"].transform(lambda s: holm_adjust(s))
    out["significant"] = out["p_holm"] < alpha
    better = out["reference_votes"] > out["baseline_votes"]
    out["verdict"] = np.where(
        ~out["significant"],
        "no significant difference",
        np.where(better, f"{reference} preferred", out["baseline"] + " preferred"),
    )
    return out


def claim_summary(
    pairwise: pd.DataFrame,
    *,
    reference: str = "ours",
    alpha: float = ALPHA,
    labels: dict | None = None,
) -> list[str]:
    """Plain sentences: where the claim "``reference`` is preferred" holds, per baseline.

    Parameters
    ----------
    pairwise : DataFrame
        Output of :func:`ours_vs_baselines`.
    labels : dict, optional
        Scene id → display name.
    """
    labels = labels or {}
    name = lambda s: str(labels.get(s, s))  # noqa: E731
    lines = []
    for b, g in pairwise.groupby("baseline", sort=False):
        yes = [name(s) for s in g.loc[g["verdict"] == f"{reference} preferred", "scene"]]
        rev = [name(s) for s in g.loc[g["verdict"] == f"{b} preferred", "scene"]]
        no = [name(s) for s in g.loc[~g["significant"], "scene"]]
        text = (
            f"{reference} vs {b} (exact binomial, Holm-adjusted, alpha={alpha:g}): "
            f"{reference} is significantly preferred in {len(yes)} of {len(g)} scenes"
            + (f" ({', '.join(yes)})" if yes else "")
        )
        if no:
            text += f"; not significant in {', '.join(no)}"
        if rev:
            text += f"; {b} is significantly preferred in {', '.join(rev)}"
        lines.append(text + ".")
    return lines


# ----------------------------------------------------------------- Luce model


def _fit_shares(
    n_items: int, data: list, alpha: float, initial: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    import choix

    theta = choix.ilsr_top1(n_items, data, alpha=alpha, max_iter=1000, initial_params=initial)
    w = np.exp(theta - theta.max())
    return w / w.sum(), theta


def luce_strengths(
    choices: pd.DataFrame,
    *,
    methods: Sequence[str] = VIEW_METHODS,
    n_boot: int = 1000,
    seed: int = 0,
    confidence: float = 0.95,
    pooled: bool = True,
    luce_alpha: float = LUCE_ALPHA,
    order: SceneOrder = None,
) -> pd.DataFrame:
    """Luce (Plackett–Luce top-1 / Bradley–Terry) method strengths with bootstrap CIs.

    Parameters
    ----------
    choices : DataFrame
        Columns ``scene``, ``chosen_method`` and optionally ``shown_order`` (the
        methods on screen; missing/None = all ``methods``). Use
        :func:`choices_from_counts` for a count table.
    n_boot : int
        Bootstrap resamples (choices resampled with replacement within each scene).
    seed : int
        Seed of the bootstrap's ``numpy.random.Generator``.
    pooled : bool
        Add rows for scene ``"all"``: one model over every scene's choices. Its bootstrap
        resamples participants (all their choices together; one person's choices in
        several scenes are not independent) when ``choices`` has ``participant_id``,
        else choices stratified by scene (a count table has no people).
    order : sequence of str, optional
        Preferred scene order (:func:`analysis.load.ordered_scenes`).

    Returns
    -------
    DataFrame
        ``scene``, ``method``, ``n`` (choices), ``strength`` (probability of being
        chosen when all methods are shown = softmax of the log-strengths; sums to 1),
        ``log_strength`` (choix's parameters, centred to mean 0), ``ci_low``,
        ``ci_high`` (percentile bootstrap interval of ``strength``).

    Notes
    -----
    Luce's choice axiom: ``P(m | shown S) = s_m / Σ_{j∈S} s_j``. Maximum likelihood by
    iterative Luce spectral ranking (``choix.ilsr_top1``; Maystre & Grossglauser 2015).
    When all methods are always shown, the ML strengths equal the vote shares.

    A resample is drawn as counts per choice type (winner, shown set) — a multinomial
    over the scene's types, or over the distinct participants' count vectors for the
    pooled row — and all resamples are fitted at once (:mod:`analysis.luce`): the same
    bootstrap distribution as drawing rows, independent of row order and participant
    labels.
    """
    from . import luce

    methods = [str(m) for m in methods]
    index = {m: i for i, m in enumerate(methods)}
    rng = np.random.default_rng(seed)
    shown_col = choices["shown_order"] if "shown_order" in choices else [None] * len(choices)
    shown = np.zeros((len(choices), len(methods)), dtype=bool)
    for i, s in enumerate(shown_col):
        on_screen = s if isinstance(s, list | tuple) and len(s) else methods
        shown[i, [index[m] for m in on_screen]] = True
    chosen = np.array([index[m] for m in choices["chosen_method"]], dtype=int)
    shown[np.arange(len(chosen)), chosen] = True
    scenes = np.asarray(list(choices["scene"]), dtype=object)
    type_winner, type_shown, of_choice = luce.choice_types(chosen, shown)
    n_types = len(type_winner)
    q = (1 - confidence) / 2
    rows = []

    def emit(scene: str, strata: list[np.ndarray], clusters: np.ndarray | None = None) -> None:
        """One model over the choices ``strata`` (a list of index arrays, one per
        stratum resampled on its own, or whole ``clusters``)."""
        flat = np.concatenate(strata)
        n_of = np.bincount(of_choice[flat], minlength=n_types)
        # The estimate by choix itself: every type as often as it was chosen.
        data = [
            (
                int(type_winner[t]),
                tuple(int(j) for j in np.flatnonzero(type_shown[t]) if j != type_winner[t]),
            )
            for t in range(n_types)
            for _ in range(n_of[t])
        ]
        share, theta = _fit_shares(len(methods), data, luce_alpha)
        if n_boot > 0:
            if clusters is not None:  # whole participants, with all their choices
                vectors, mult = luce.cluster_counts(of_choice[flat], clusters[flat], n_types)
                draws = rng.multinomial(mult.sum(), mult / mult.sum(), size=n_boot)
                counts = draws @ vectors
            else:
                counts = np.zeros((n_boot, n_types), dtype=np.int64)
                for idx in strata:
                    k = np.bincount(of_choice[idx], minlength=n_types)
                    counts += rng.multinomial(len(idx), k / len(idx), size=n_boot)
            # Starting from the full-data estimate only saves iterations (same optimum).
            boots = luce.shares(
                luce.fit_counts(counts, type_winner, type_shown, alpha=luce_alpha, initial=theta)
            )
            lo, hi = np.quantile(boots, [q, 1 - q], axis=0)
            # A method chosen by none (or by all) of n: every resample repeats that, so
            # the percentile interval collapses to [0, 0] (or [1, 1]) as if the share
            # were known exactly. Use the exact Clopper-Pearson end instead:
            # 1 - (q)^(1/n) for k = 0 (and q^(1/n) for k = n).
            k = np.bincount(chosen[flat], minlength=len(methods))
            n_flat = len(flat)
            lo[k == 0], hi[k == 0] = 0.0, 1 - q ** (1 / n_flat)
            lo[k == n_flat], hi[k == n_flat] = q ** (1 / n_flat), 1.0
        else:
            lo = hi = np.full(len(methods), np.nan)
        for m, i in index.items():
            rows.append(
                {
                    "scene": scene,
                    "method": m,
                    "n": len(flat),
                    "strength": share[i],
                    "log_strength": theta[i] - theta.mean(),
                    "ci_low": lo[i],
                    "ci_high": hi[i],
                }
            )

    groups = {s: np.flatnonzero(scenes == s) for s in ordered_scenes(list(scenes), order)}
    for scene, idx in groups.items():
        emit(scene, [idx])
    if pooled and len(groups) > 1:
        clusters = None
        if "participant_id" in choices and choices["participant_id"].notna().all():
            clusters = choices["participant_id"].to_numpy()
        emit("all", list(groups.values()), clusters)
    return pd.DataFrame(rows)


# ----------------------------------------------------------------- agreement


def merge_near_duplicates(counts: pd.DataFrame, duplicates: dict) -> pd.DataFrame:
    """Votes with near-duplicate candidates counted as one option (a sensitivity analysis).

    When two candidates of a scene are nearly the same picture, a participant who likes
    that picture may click either, so their votes split. Counting the pair as one option
    asks whether the conclusions survive that.

    Parameters
    ----------
    counts : DataFrame
        :func:`vote_counts` (scenes × methods).
    duplicates : dict of str to list of (str, str)
        Per scene, the pairs of methods whose views are near-duplicates
        (:func:`analysis.stimuli.near_duplicate_scenes`).

    Returns
    -------
    DataFrame
        ``scene``, ``option`` (a method, or ``"a = b"`` for a merged pair), ``votes``,
        ``n`` (votes in the scene), ``options`` (distinct pictures in the scene),
        ``chisquare_p`` (goodness of fit against equal votes per distinct picture; NaN
        with a single option). Scenes without duplicates keep their three options.
    """
    rows = []
    for scene, row in counts.iterrows():
        groups = {m: [m] for m in counts.columns}
        for a, b in duplicates.get(scene, ()):
            if a in groups and b in groups and groups[a] is not groups[b]:
                merged = groups[a] + [m for m in groups[b] if m not in groups[a]]
                for m in merged:
                    groups[m] = merged
        options = list({id(g): g for g in groups.values()}.values())
        votes = [int(sum(int(row[m]) for m in g)) for g in options]
        n = int(sum(votes))
        p = stats.chisquare(votes).pvalue if len(votes) > 1 and n > 0 else float("nan")
        for g, v in zip(options, votes, strict=True):
            rows.append(
                {
                    "scene": scene,
                    "option": " = ".join(g),
                    "votes": v,
                    "n": n,
                    "options": len(options),
                    "chisquare_p": float(p),
                }
            )
    return pd.DataFrame(rows)


def fleiss_kappa(counts: pd.DataFrame) -> pd.DataFrame:
    """Fleiss' kappa: do participants agree on which method is best, beyond chance?

    Items are scenes (rows), categories are methods (columns), raters are the people
    who voted on a scene.

    Returns
    -------
    DataFrame
        One row: ``kappa``, ``n_items``, ``raters_per_item`` (mean), ``p_observed``
        (mean pairwise agreement P̄), ``p_chance`` (P̄_e), ``se0`` (standard error under
        κ = 0, Fleiss, Nee & Landis 1979), ``z``, ``p_value`` (one-sided, κ > 0).

    Notes
    -----
    ``P_i = (Σ_j n_ij² − n_i) / (n_i (n_i − 1))``, ``P̄ = mean_i P_i``,
    ``p_j = Σ_i n_ij / Σ_i n_i``, ``P̄_e = Σ_j p_j²``, ``κ = (P̄ − P̄_e)/(1 − P̄_e)``
    (Fleiss 1971; unequal ``n_i`` allowed in κ, the SE uses their mean).
    """
    x = counts.to_numpy(dtype=float)
    x = x[x.sum(axis=1) > 1]
    if x.shape[0] == 0:
        warnings.warn("fleiss_kappa: no scene with two or more votes; kappa is NaN", stacklevel=2)
        return pd.DataFrame(
            [
                {
                    "kappa": np.nan,
                    "n_items": 0,
                    "raters_per_item": np.nan,
                    "p_observed": np.nan,
                    "p_chance": np.nan,
                    "se0": np.nan,
                    "z": np.nan,
                    "p_value": np.nan,
                }
            ]
        )
    n_i = x.sum(axis=1)
    p_i = ((x**2).sum(axis=1) - n_i) / (n_i * (n_i - 1))
    p_bar = p_i.mean()
    p_j = x.sum(axis=0) / n_i.sum()
    p_e = (p_j**2).sum()
    kappa = (p_bar - p_e) / (1 - p_e) if p_e < 1 else np.nan
    n, N = n_i.mean(), x.shape[0]
    pq = p_j * (1 - p_j)
    spq = pq.sum()
    var0 = (
        2 / (N * n * (n - 1)) * (spq**2 - (pq * (1 - 2 * p_j)).sum()) / spq**2
        if spq > 0
        else np.nan
    )
    se0 = np.sqrt(var0) if var0 == var0 and var0 > 0 else np.nan
    z = kappa / se0 if se0 == se0 and se0 > 0 else np.nan
    return pd.DataFrame(
        [
            {
                "kappa": kappa,
                "n_items": N,
                "raters_per_item": n,
                "p_observed": p_bar,
                "p_chance": p_e,
                "se0": se0,
                "z": z,
                "p_value": stats.norm.sf(z) if z == z else np.nan,
            }
        ]
    )
