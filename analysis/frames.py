"""Pose-task choices against the algorithm's pick (the paper's Fig. 13), with baselines.

The question: when people pick "the most meaningful frame" of an animation, how close
are they to the frame the algorithm (pose entropy) picked — and is the algorithm closer
to them than simple rules would be?

Predictors compared with the people's choices, per scene:

- ``algorithm``: the algorithm's pick (``algorithm_frame`` of the rows);
- ``middle``: the middle frame of the clip;
- ``uniform_random``: a frame drawn uniformly from the clip (its *expected* distance
  and hit rate, computed exactly over every frame);
- ``fastest`` and ``stretch``: the pose selectors of the same names
  (:mod:`snapcore.select.pose_baselines`: the mean joint speed, and the mean joint
  distance from the joints' centroid, each over the stature) -- one definition for
  ``snapshot keymoments``, the stimuli and this analysis. :func:`baselines_from_stimuli`
  reads their top picks from the stimuli manifest (``picks.by_method``, recorded when
  the stimuli were built), never reloading a motion; :func:`motion_baselines` computes
  them on a :class:`snapcore.Scene` at hand. Without either they are left out (never
  guessed).

Distances are in seconds, ``|chosen − predictor| / fps``. Hit rates count choices within
±0.25, ±0.5 and ±1 s (``TOLERANCES_S``); they describe, they do not test (a central
frame is near many picks whatever people think). :func:`closeness_tests` asks, per
scene, whether people's picks gather at the algorithm's frame (*agreement*) and whether
they are closer to it than to each deterministic baseline (*closer than X*), each
beyond what the same people's clip-position habits explain: a within-participant
permutation over scenes (:mod:`analysis.scene_permutation`), valid for random
clickers, centre-biased clickers and personal habits alike, Holm over the table.
Effects are the mean excess over the habits' prediction with a bootstrap interval over
participants. The uniform-random predictor stays in the hit-rate table as a reference,
not as a test: "closer than a random frame" measures how central picks are.
Rows pooled over scenes (``scene == "ALL"``) have intervals from a bootstrap over
participants (:func:`cluster_bootstrap_ci`): one person's choices are not independent.

Frames are in source numbering; a clip covers frames ``frame_offset ..
frame_offset + n_frames − 1`` (``frame_offset`` 0 unless the stimuli manifest says).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike

from study_app.design.scenes import StudyScene

if TYPE_CHECKING:
    from snapcore.motion.scene import Scene

from . import scene_permutation as sp
from .load import ordered_scenes
from .scene_permutation import N_PERMUTATIONS
from .votes import holm_adjust, wilson_interval

__all__ = [
    "TOLERANCES_S",
    "N_PERMUTATIONS",
    "N_BOOT",
    "DETERMINISTIC_BASELINES",
    "scene_frames_from_rows",
    "motion_baselines",
    "baselines_from_stimuli",
    "SELECTOR_BASELINES",
    "predictor_frames",
    "frame_distances",
    "hit_rates",
    "closeness_tests",
    "COMPARISONS",
    "cluster_bootstrap_ci",
    "frame_histogram",
]

#: Hit-rate windows, seconds either side of the predicted frame.
TOLERANCES_S = (0.25, 0.5, 1.0)
#: Bootstrap resamples (over participants) of effect intervals and pooled rows.
N_BOOT = 2000
#: Baselines that predict one frame (each gets a "closer than X" test).
DETERMINISTIC_BASELINES = ("middle", "fastest", "stretch")
#: The pose selectors (:data:`snapcore.select.pose_methods.POSE_METHODS`) whose top pick
#: is a baseline here.
SELECTOR_BASELINES = ("fastest", "stretch")


def _mode(values: ArrayLike, name: str, scene: str) -> Any:
    v = pd.Series(values).dropna()
    if v.empty:
        return None
    counts = v.value_counts()
    if len(counts) > 1:
        warnings.warn(
            f"scene '{scene}': rows disagree on {name} ({sorted(counts.index)}); "
            f"using the most common, {counts.index[0]}",
            stacklevel=3,
        )
    return counts.index[0]


def scene_frames_from_rows(
    pose: pd.DataFrame, *, extra: dict | None = None, order: Iterable[str] | None = None
) -> dict:
    """Per-scene :class:`~study_app.design.scenes.StudyScene` from pose-task rows (fps, n_frames, algorithm_frame).

    Parameters
    ----------
    pose : DataFrame
        Pose-task rows (:func:`analysis.load.pose_choices`).
    extra : dict, optional
        scene → dict of further :class:`~study_app.design.scenes.StudyScene` fields (``frame_offset``,
        ``algorithm_frames``, ``baseline_frames``, ``title``), e.g. from the stimuli
        manifest.
    order : sequence of str, optional
        Preferred scene order (:func:`analysis.load.ordered_scenes`).
    """
    extra = extra or {}
    out = {}
    for scene in ordered_scenes(pose["scene"], order):
        g = pose[pose["scene"] == scene]
        fps = _mode(g["fps"], "fps", scene)
        n = _mode(g["n_frames"], "n_frames", scene)
        a = _mode(g["algorithm_frame"], "algorithm_frame", scene)
        if fps is None or n is None or a is None:
            warnings.warn(
                f"scene '{scene}': rows lack fps, n_frames or algorithm_frame; "
                "left out of the frame analysis",
                stacklevel=2,
            )
            continue
        kw = dict(extra.get(scene, {}))
        out[scene] = StudyScene(
            scene=scene, fps=float(fps), n_frames=int(n), algorithm_frame=int(a), **kw
        )
    return out


# ----------------------------------------------------------------- motion baselines


def motion_baselines(scene: Scene, *, window: tuple[int, int] | None = None) -> dict:
    """The selector baselines of a scene at hand, in source numbering.

    Parameters
    ----------
    scene : snapcore.Scene
        The motion shown in the stimulus.
    window : (int, int), optional
        Source frames ``[start, stop)`` the participants saw (default: the whole scene);
        the argmax is taken inside it.

    Returns
    -------
    dict
        ``{"fastest": int, "stretch": int}``: the frames of highest
        :func:`snapcore.select.pose_baselines.speed_score` and
        :func:`~snapcore.select.pose_baselines.stretch_score` (the ``fastest`` and
        ``stretch`` selectors' scores; over the whole scene, the selectors' top picks).
        A window of one frame returns that frame for both (with a warning).
    """
    from snapcore.select.pose_baselines import speed_score, stretch_score

    source = np.arange(scene.n_frames) + int(scene.frame_offset)
    keep = np.ones(scene.n_frames, dtype=bool)
    if window is not None:
        keep = (source >= window[0]) & (source < window[1])
    if not keep.any():
        raise ValueError(
            f"scene '{scene.name}': window {tuple(window or ())} holds no frame of the "
            f"motion (source frames {source[0]}..{source[-1]})"
        )
    frames = source[keep]
    if frames.size == 1:
        warnings.warn(
            f"scene '{scene.name}': one frame; the baselines are that frame", stacklevel=2
        )
    return {
        "fastest": int(frames[int(np.argmax(speed_score(scene)[keep]))]),
        "stretch": int(frames[int(np.argmax(stretch_score(scene)[keep]))]),
    }


def baselines_from_stimuli(manifest: str | Path | Mapping[str, Any]) -> dict:
    """The selector baselines, picks and frame offsets of each scene of a stimuli manifest.

    Parameters
    ----------
    manifest : str, Path or dict
        The stimuli manifest (``data_schema/stimuli.schema.json``) or its path.

    Returns
    -------
    dict
        scene id → ``{"frame_offset", "algorithm_frames", "title", "selector_frames",
        "baseline_frames"}`` (the ``extra`` argument of :func:`scene_frames_from_rows`).
        ``baseline_frames`` holds the top pick the manifest recorded for each of
        :data:`SELECTOR_BASELINES` (``picks.by_method``); a scene whose manifest entry
        has none gets no baseline frames, with a warning. No motion is loaded.
    """
    from .stimuli import read_stimuli

    doc, _ = read_stimuli(manifest)
    out = {}
    for entry in doc.get("scenes", []):
        sid = entry["id"]
        picks = entry.get("picks") or {}
        info: dict[str, object] = {
            "algorithm_frames": tuple(int(f) for f in picks.get("frames", ()) or ())
        }
        by_method = {
            m: [int(f) for f in fs] for m, fs in (picks.get("by_method") or {}).items() if fs
        }
        if by_method:
            info["selector_frames"] = by_method
        if entry.get("title"):
            info["title"] = entry["title"]
        info["frame_offset"] = int(entry.get("frame_offset", 0))
        baselines = {m: by_method[m][0] for m in SELECTOR_BASELINES if m in by_method}
        if baselines:
            info["baseline_frames"] = baselines
        else:
            warnings.warn(
                f"stimuli scene '{sid}': the manifest records no picks of the "
                f"{' and '.join(SELECTOR_BASELINES)} selectors (picks.by_method); "
                "those baselines are left out",
                stacklevel=2,
            )
        out[sid] = info
    return out


# ----------------------------------------------------------------- distances and hits


def predictor_frames(info: StudyScene) -> dict:
    """Name → predicted source frame for the deterministic predictors of a scene."""
    out = {
        "algorithm": info.algorithm_frame,
        "middle": info.frame_offset + (info.n_frames - 1) // 2,
    }
    for name in DETERMINISTIC_BASELINES[1:]:
        if name in info.baseline_frames:
            out[name] = int(info.baseline_frames[name])
    return out


def frame_distances(pose: pd.DataFrame, scenes: dict) -> pd.DataFrame:
    """Signed distance of every choice to every deterministic predictor, in seconds.

    Returns
    -------
    DataFrame
        ``scene``, ``participant_id``, ``chosen_frame``, ``predictor``,
        ``predicted_frame``, ``error_s`` (chosen − predicted, s), ``abs_error_s``.
    """
    parts = []
    for scene, info in scenes.items():
        g = pose[pose["scene"] == scene]
        c = g["chosen_frame"].to_numpy(dtype=float)
        for name, f in predictor_frames(info).items():
            e = (c - f) / info.fps
            parts.append(
                pd.DataFrame(
                    {
                        "scene": scene,
                        "participant_id": g["participant_id"].values,
                        "chosen_frame": c.astype(int),
                        "predictor": name,
                        "predicted_frame": int(f),
                        "error_s": e,
                        "abs_error_s": np.abs(e),
                    }
                )
            )
    if not parts:
        return pd.DataFrame(
            columns=[
                "scene",
                "participant_id",
                "chosen_frame",
                "predictor",
                "predicted_frame",
                "error_s",
                "abs_error_s",
            ]
        )
    return pd.concat(parts, ignore_index=True)


def _uniform_distance_matrix(c: np.ndarray, info: StudyScene) -> np.ndarray:
    """|c_i − f| / fps for every choice i and every clip frame f, shape (n, n_frames)."""
    return np.abs(c[:, None] - info.source_frames[None, :]) / info.fps


def hit_rates(
    pose: pd.DataFrame,
    scenes: dict,
    *,
    tolerances: Sequence[float] = TOLERANCES_S,
    confidence: float = 0.95,
) -> pd.DataFrame:
    """Hit rates and mean distances of every predictor, per scene.

    Returns
    -------
    DataFrame
        ``scene``, ``predictor``, ``predicted_frame`` (NaN for ``uniform_random``),
        ``n`` (choices), ``mean_abs_error_s``, ``median_abs_error_s`` (NaN for
        uniform_random), then for each tolerance ``t``: ``hit_<t>s`` (fraction of
        choices within ±t s), ``hit_<t>s_low`` / ``hit_<t>s_high`` (Wilson interval;
        NaN for uniform_random, whose rate is an exact expectation, not an estimate).
    """
    rows = []
    for scene, info in scenes.items():
        c = pose.loc[pose["scene"] == scene, "chosen_frame"].to_numpy(dtype=float)
        n = c.size
        if n == 0:
            continue
        for name, f in predictor_frames(info).items():
            d = np.abs(c - f) / info.fps
            row = {
                "scene": scene,
                "predictor": name,
                "predicted_frame": float(f),
                "n": n,
                "mean_abs_error_s": d.mean(),
                "median_abs_error_s": float(np.median(d)),
            }
            for t in tolerances:
                k = int((d <= t + 1e-9).sum())
                lo, hi = wilson_interval(k, n, confidence=confidence)
                row[f"hit_{t:g}s"] = k / n
                row[f"hit_{t:g}s_low"], row[f"hit_{t:g}s_high"] = float(lo), float(hi)
            rows.append(row)
        dm = _uniform_distance_matrix(c, info)  # expectation over a uniform frame
        row = {
            "scene": scene,
            "predictor": "uniform_random",
            "predicted_frame": np.nan,
            "n": n,
            "mean_abs_error_s": dm.mean(),
            "median_abs_error_s": np.nan,
        }
        for t in tolerances:
            row[f"hit_{t:g}s"] = float((dm <= t + 1e-9).mean())
            row[f"hit_{t:g}s_low"] = row[f"hit_{t:g}s_high"] = np.nan
        rows.append(row)
    return pd.DataFrame(rows)


def selector_agreement(
    pose: pd.DataFrame, scenes: dict, *, tolerance_s: float = 0.5
) -> pd.DataFrame:
    """How well every pose selector's top pick agrees with the people's chosen frames.

    Parameters
    ----------
    pose : DataFrame
        Pose-task rows (``scene``, ``chosen_frame``).
    scenes : dict
        scene → :class:`~study_app.design.scenes.StudyScene` with ``selector_frames``.
    tolerance_s : float
        A choice agrees with a pick within ±``tolerance_s`` seconds.

    Returns
    -------
    DataFrame
        ``scene``, ``selector``, ``frame`` (its top pick), ``n`` (choices), ``hit``
        (fraction of choices within the tolerance), ``hit_low``/``hit_high`` (Wilson 95%),
        ``median_abs_error_s``; then rows with ``scene == "ALL"``: the hit rate and the
        median distance over every choice, per selector, ``frame`` empty (no one frame),
        ``n`` the choices and ``participants`` the people, the interval a percentile
        bootstrap over participants (:func:`cluster_bootstrap_ci`; one person's choices
        in several scenes are not independent). Empty when no scene has selector picks.
    """
    rows: list[dict] = []
    pooled: dict[str, list] = {}
    for scene, info in scenes.items():
        if not info.selector_frames:
            continue
        c, who = _per_participant(pose, scene)
        if c.size == 0:
            continue
        for name, fs in info.selector_frames.items():
            d = np.abs(c - fs[0]) / info.fps
            k = int((d <= tolerance_s + 1e-9).sum())
            lo, hi = wilson_interval(k, c.size)
            rows.append(
                {
                    "scene": scene,
                    "selector": name,
                    "frame": int(fs[0]),
                    "n": int(c.size),
                    "participants": len(set(who)),
                    "hit": k / c.size,
                    "hit_low": float(lo),
                    "hit_high": float(hi),
                    "median_abs_error_s": float(np.median(d)),
                }
            )
            pooled.setdefault(name, []).append((d, who))
    for name, parts in pooled.items():
        d = np.concatenate([p[0] for p in parts])
        who = np.concatenate([p[1] for p in parts])
        hit = (d <= tolerance_s + 1e-9).astype(float)
        low, high = cluster_bootstrap_ci(hit, who)
        rows.append(
            {
                "scene": "ALL",
                "selector": name,
                "frame": pd.NA,
                "n": int(d.size),
                "participants": len(set(who)),
                "hit": float(hit.mean()),
                "hit_low": low,
                "hit_high": high,
                "median_abs_error_s": float(np.median(d)),
            }
        )
    out = pd.DataFrame(
        rows,
        columns=[
            "scene",
            "selector",
            "frame",
            "n",
            "participants",
            "hit",
            "hit_low",
            "hit_high",
            "median_abs_error_s",
        ],
    )
    out["frame"] = out["frame"].astype("Int64")
    return out


def selector_timeline_document(pose: pd.DataFrame, scenes: dict) -> dict | None:
    """The scenes with selector picks in the layout of a key-moment evaluation document
    (no intervals), for :func:`snapcore.render.keymoments_plot.plot_keymoment_timelines`."""
    sc = [(s, i) for s, i in scenes.items() if i.selector_frames]
    if not sc:
        return None
    methods = list(dict.fromkeys(m for _, i in sc for m in i.selector_frames))
    return {
        "widen_s": 0.0,
        "methods": methods,
        "scenes": [
            {
                "scene": s,
                "fps": i.fps,
                "first_frame": i.frame_offset,
                "last_frame": i.frame_offset + i.n_frames - 1,
                "intervals": [],
            }
            for s, i in sc
        ],
        "rows": [
            {"scene": s, "method": m, "frames": fs}
            for s, i in sc
            for m, fs in i.selector_frames.items()
        ],
    }


def _per_participant(pose: pd.DataFrame, scene: str) -> tuple[np.ndarray, np.ndarray]:
    """One scene's chosen frames and the participant of each, shape (n,) both."""
    g = pose[pose["scene"] == scene]
    who = g["participant_id"].to_numpy() if "participant_id" in g else np.arange(len(g))
    return g["chosen_frame"].to_numpy(dtype=float), who


def cluster_bootstrap_ci(
    values: ArrayLike,
    clusters: ArrayLike,
    *,
    stat: Callable[[np.ndarray], float] = np.mean,
    n_boot: int = N_BOOT,
    seed: int = 0,
    confidence: float = 0.95,
) -> tuple[float, float]:
    """Percentile bootstrap interval of ``stat(values)``, resampling whole clusters.

    Parameters
    ----------
    values : array-like, shape (n,)
        One number per observation (e.g. 1/0 for a hit, a distance in s).
    clusters : array-like, shape (n,)
        The cluster of each observation (the participant): a resample draws
        participants with replacement and keeps all their observations, so that the
        interval counts people, not choices.
    stat : callable
        Statistic of the pooled values of a resample (``np.mean``: computed for all
        resamples at once from per-cluster sums).

    Returns
    -------
    (low, high) : tuple of float
        NaN when there are no values.

    Notes
    -----
    Clusters are drawn from a list sorted by their values, not by their labels, so the
    interval does not depend on how participants are named (raw ids, pseudonyms) or on
    the order of the rows.
    """
    values = np.asarray(values, dtype=float)
    clusters = np.asarray(clusters)
    if values.size == 0 or n_boot <= 0:
        return float("nan"), float("nan")
    _, inverse = np.unique(clusters, return_inverse=True)
    inverse = inverse.reshape(-1)
    by_value = np.lexsort((values, inverse))  # each cluster's values together, sorted
    sizes = np.bincount(inverse)
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    sums = np.add.reduceat(values[by_value], starts)
    rng = np.random.default_rng(seed)
    picks = rng.integers(0, sizes.size, size=(n_boot, sizes.size))
    if stat is np.mean:
        # Clusters of equal size and sum add the same to every resample's mean: ordered
        # by (size, sum) they are in a canonical order for it.
        order = np.lexsort((sums, sizes))
        boots = sums[order][picks].sum(axis=1) / sizes[order][picks].sum(axis=1)
    else:  # the same order, ties broken by the values themselves
        members = np.split(values[by_value], starts[1:])
        ranked = sorted(
            range(sizes.size),
            key=lambda k: (sizes[k], sums[k], tuple(np.nan_to_num(members[k], nan=np.inf))),
        )
        boots = np.array([stat(np.concatenate([members[ranked[k]] for k in row])) for row in picks])
    q = (1 - confidence) / 2
    lo, hi = np.quantile(boots, [q, 1 - q])
    return float(lo), float(hi)


#: The comparisons of :func:`closeness_tests`, in table order: agreement with the
#: algorithm's frame, then "closer to the algorithm than to X" per deterministic baseline.
COMPARISONS = ("agreement", *DETERMINISTIC_BASELINES)
#: What each comparison asks, for the table and the report.
QUESTIONS = {
    "agreement": "do picks gather at the algorithm's frame more than position habits explain?",
    **{
        b: f"are picks closer to the algorithm's frame than to the {b} frame, "
        "more than position habits explain?"
        for b in DETERMINISTIC_BASELINES
    },
}
METHOD = "within-participant permutation over scenes (one-sided, Monte Carlo)"


def _comparisons(info: StudyScene) -> list[tuple[str, int | None]]:
    preds = predictor_frames(info)
    preds.pop("algorithm")
    return [("agreement", None), *preds.items()]


def closeness_tests(
    pose: pd.DataFrame,
    scenes: dict,
    *,
    n_boot: int = N_BOOT,
    seed: int = 0,
    alpha: float = 0.05,
    confidence: float = 0.95,
    n_permutations: int = N_PERMUTATIONS,
) -> pd.DataFrame:
    """Do people's picks follow the algorithm's frame of each scene? Permutation tests.

    Per scene, an *agreement* test (are the picks closer to the algorithm's frame than
    the same people's clip-position habits predict?) and, per deterministic baseline X,
    a *closer than X* test (is "distance to X minus distance to the algorithm" larger
    than the habits predict?). Both are one-sided within-participant permutation tests
    over scenes (:mod:`analysis.scene_permutation`): valid whenever a participant's clip
    position does not depend on the scene — random clickers, clickers who prefer the
    middle of the clip, participant-specific habits — so they do not reward centrality.
    Holm's adjustment runs over every test of the table; a baseline on the algorithm's
    frame gives ``d = 0`` for everyone and is reported, not tested, and so is a scene
    whose participants chose in no other scene (nothing to permute). A *closer than X*
    test is ``significant`` only when Holm rejects *and* the people are on average closer
    to the algorithm than to X (``difference_s > 0``): a pull toward the algorithm that
    still leaves them nearer X is not "closer than X" (requiring both can only lower the
    false-positive rate).

    Parameters
    ----------
    n_boot : int
        Resamples of the bootstrap (over participants) of the effects' intervals (0:
        no intervals; the tests do not depend on it).
    seed : int
        Seed of the permutations (and, plus the scene's index, of the bootstrap).
    n_permutations : int
        Monte-Carlo permutations B; p-values are ``(1 + #{T* ≥ T}) / (1 + B)``.

    Returns
    -------
    DataFrame
        ``scene``, ``comparison`` (:data:`COMPARISONS`), ``question``, ``n``
        (participants), ``algorithm_mean_abs_s`` (mean distance to the algorithm's
        frame), ``baseline_mean_abs_s`` (to X; NaN for agreement), ``difference_s``
        (mean of |c − X| − |c − algorithm|: > 0 = closer to the algorithm; NaN for
        agreement), ``habit_s`` (the statistic the participants' own positions in all
        their scenes predict), ``beyond_habit_s`` (statistic − habit prediction: > 0 =
        closer to the algorithm than habits explain) with ``beyond_habit_low`` /
        ``beyond_habit_high`` (percentile bootstrap over participants), ``p_value``,
        ``method``, ``p_holm`` (NaN for rows not tested), ``significant``, ``note``.
    """
    groups, u, design = sp.design_from_rows(pose, scenes, _comparisons)
    tested = [t for t in design if t["baseline"] != t["algorithm"] and t["informative"]]
    _, _, p = sp.permutation_pvalues(groups, u, tested, n_permutations=n_permutations, seed=seed)
    p_of = {(t["scene"], t["comparison"]): float(v) for t, v in zip(tested, p, strict=True)}
    index = {s: k for k, s in enumerate(scenes)}
    rows = []
    for t in design:
        obs, habit = sp.habit_effects(groups, u, t)
        x = t["first"] + u[t["rows"]] * t["span"]  # the chosen frames
        da = sp.per_participant(np.abs(x - t["algorithm"]) / t["fps"], t)
        db = (
            sp.per_participant(np.abs(x - t["baseline"]) / t["fps"], t)
            if t["baseline"] is not None
            else np.full(da.size, np.nan)
        )
        lo, hi = cluster_bootstrap_ci(
            obs - habit,
            np.arange(obs.size),
            n_boot=n_boot,
            seed=seed + index[t["scene"]],
            confidence=confidence,
        )
        key = (t["scene"], t["comparison"])
        rows.append(
            {
                "scene": t["scene"],
                "comparison": t["comparison"],
                "question": QUESTIONS[t["comparison"]],
                "n": int(obs.size),
                "algorithm_mean_abs_s": float(da.mean()),
                "baseline_mean_abs_s": float(db.mean()),
                "difference_s": float((db - da).mean()),
                "habit_s": float(habit.mean()),
                "beyond_habit_s": float((obs - habit).mean()),
                "beyond_habit_low": lo,
                "beyond_habit_high": hi,
                "p_value": p_of.get(key, float("nan")),
                "method": f"{METHOD}, B = {n_permutations}",
                "note": ""
                if key in p_of
                else "same frame as the algorithm: not tested"
                if t["baseline"] == t["algorithm"]
                else "no participant chose in another scene: not tested",
            }
        )
    out = pd.DataFrame(rows)
    if out.empty:
        return out
    tested_rows = out["p_value"].notna()
    out["p_holm"] = np.nan
    out.loc[tested_rows, "p_holm"] = holm_adjust(out.loc[tested_rows, "p_value"])
    closer = (out["comparison"] == "agreement") | (out["difference_s"] > 0)
    out["significant"] = (out["p_holm"] < alpha) & closer  # NaN (not tested) is False
    pulled = (out["p_holm"] < alpha) & ~closer
    out.loc[pulled, "note"] = (
        "closer to the algorithm than habits explain, yet on average nearer this baseline"
    )
    return out


def frame_histogram(
    pose: pd.DataFrame, info: StudyScene, *, bins: int | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Histogram of one scene's chosen frames over the whole clip.

    Parameters
    ----------
    bins : int, optional
        Number of bins (default: one per ~0.25 s, between 10 and 60).

    Returns
    -------
    counts : ndarray of int, shape (B,)
    edges : ndarray of float, shape (B + 1,)
        In source frames.
    """
    c = pose.loc[pose["scene"] == info.scene, "chosen_frame"].to_numpy(dtype=float)
    if bins is None:
        bins = int(np.clip(round(info.n_frames / (0.25 * info.fps)), 10, 60))
    edges = np.linspace(info.frame_offset - 0.5, info.frame_offset + info.n_frames - 0.5, bins + 1)
    counts, edges = np.histogram(c, bins=edges)
    return counts, edges
