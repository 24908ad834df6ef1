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
±0.25, ±0.5 and ±1 s (``TOLERANCES_S``). Permutation tests ask whether the algorithm
is closer to people than each baseline (one-sided):

- deterministic baseline ``b``: paired sign-flip test on
  ``d_i = |c_i − b| − |c_i − a|`` (statistic: mean ``d``; under "equally close" each
  ``d_i`` is symmetric about 0); exact enumeration for up to ``EXACT_MAX_N`` choices,
  else ``N_PERMUTATIONS`` random flips, ``p = (1 + #{T* >= T}) / (1 + B)``;
- ``uniform_random``: the exact randomisation p-value, the fraction of the clip's frames
  whose mean distance to the choices is at most the algorithm's.

Frames are in source numbering; a clip covers frames ``frame_offset ..
frame_offset + n_frames − 1`` (``frame_offset`` 0 unless the stimuli manifest says).
"""

from __future__ import annotations

import itertools
import warnings

import numpy as np
import pandas as pd

from study_app.design.scenes import StudyScene

from .load import ordered_scenes
from .votes import holm_adjust, wilson_interval

__all__ = [
    "TOLERANCES_S",
    "N_PERMUTATIONS",
    "EXACT_MAX_N",
    "DETERMINISTIC_BASELINES",
    "scene_frames_from_rows",
    "motion_baselines",
    "baselines_from_stimuli",
    "SELECTOR_BASELINES",
    "predictor_frames",
    "frame_distances",
    "hit_rates",
    "closeness_tests",
    "frame_histogram",
]

#: Hit-rate windows, seconds either side of the predicted frame.
TOLERANCES_S = (0.25, 0.5, 1.0)
#: Random sign flips of the permutation test when exact enumeration is too large.
N_PERMUTATIONS = 10_000
#: Up to this many choices the sign-flip test enumerates all 2^n flips exactly.
EXACT_MAX_N = 16
#: Baselines that predict one frame (tested by paired sign flips).
DETERMINISTIC_BASELINES = ("middle", "fastest", "stretch")
#: The pose selectors (:data:`snapcore.select.pose_methods.POSE_METHODS`) whose top pick
#: is a baseline here.
SELECTOR_BASELINES = ("fastest", "stretch")


def _mode(values, name, scene):
    v = pd.Series(values).dropna()
    if v.empty:
        return None
    counts = v.value_counts()
    if len(counts) > 1:
        warnings.warn(f"scene '{scene}': rows disagree on {name} ({sorted(counts.index)}); "
                      f"using the most common, {counts.index[0]}", stacklevel=3)
    return counts.index[0]


def scene_frames_from_rows(pose: pd.DataFrame, *, extra: dict | None = None,
                           order=None) -> dict:
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
            warnings.warn(f"scene '{scene}': rows lack fps, n_frames or algorithm_frame; "
                          "left out of the frame analysis", stacklevel=2)
            continue
        kw = dict(extra.get(scene, {}))
        out[scene] = StudyScene(scene=scene, fps=float(fps), n_frames=int(n),
                                 algorithm_frame=int(a), **kw)
    return out


# ----------------------------------------------------------------- motion baselines


def motion_baselines(scene, *, window=None) -> dict:
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
        raise ValueError(f"scene '{scene.name}': window {tuple(window)} holds no frame of the "
                         f"motion (source frames {source[0]}..{source[-1]})")
    frames = source[keep]
    if frames.size == 1:
        warnings.warn(f"scene '{scene.name}': one frame; the baselines are that frame",
                      stacklevel=2)
    return {"fastest": int(frames[int(np.argmax(speed_score(scene)[keep]))]),
            "stretch": int(frames[int(np.argmax(stretch_score(scene)[keep]))])}


def baselines_from_stimuli(manifest) -> dict:
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
        info = {"algorithm_frames": tuple(int(f) for f in picks.get("frames", ()) or ())}
        by_method = {m: [int(f) for f in fs] for m, fs in (picks.get("by_method") or {}).items()
                     if fs}
        if by_method:
            info["selector_frames"] = by_method
        if entry.get("title"):
            info["title"] = entry["title"]
        info["frame_offset"] = int(entry.get("frame_offset", 0))
        baselines = {m: by_method[m][0] for m in SELECTOR_BASELINES if m in by_method}
        if baselines:
            info["baseline_frames"] = baselines
        else:
            warnings.warn(f"stimuli scene '{sid}': the manifest records no picks of the "
                          f"{' and '.join(SELECTOR_BASELINES)} selectors (picks.by_method); "
                          "those baselines are left out", stacklevel=2)
        out[sid] = info
    return out


# ----------------------------------------------------------------- distances and hits


def predictor_frames(info: StudyScene) -> dict:
    """Name → predicted source frame for the deterministic predictors of a scene."""
    out = {"algorithm": info.algorithm_frame,
           "middle": info.frame_offset + (info.n_frames - 1) // 2}
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
            parts.append(pd.DataFrame({"scene": scene, "participant_id": g["participant_id"].values,
                                       "chosen_frame": c.astype(int), "predictor": name,
                                       "predicted_frame": int(f), "error_s": e,
                                       "abs_error_s": np.abs(e)}))
    if not parts:
        return pd.DataFrame(columns=["scene", "participant_id", "chosen_frame", "predictor",
                                     "predicted_frame", "error_s", "abs_error_s"])
    return pd.concat(parts, ignore_index=True)


def _uniform_distance_matrix(c, info):
    """|c_i − f| / fps for every choice i and every clip frame f, shape (n, n_frames)."""
    return np.abs(c[:, None] - info.source_frames[None, :]) / info.fps


def hit_rates(pose: pd.DataFrame, scenes: dict, *, tolerances=TOLERANCES_S,
              confidence: float = 0.95) -> pd.DataFrame:
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
            row = {"scene": scene, "predictor": name, "predicted_frame": float(f), "n": n,
                   "mean_abs_error_s": d.mean(), "median_abs_error_s": float(np.median(d))}
            for t in tolerances:
                k = int((d <= t + 1e-9).sum())
                lo, hi = wilson_interval(k, n, confidence=confidence)
                row[f"hit_{t:g}s"] = k / n
                row[f"hit_{t:g}s_low"], row[f"hit_{t:g}s_high"] = float(lo), float(hi)
            rows.append(row)
        dm = _uniform_distance_matrix(c, info)  # expectation over a uniform frame
        row = {"scene": scene, "predictor": "uniform_random", "predicted_frame": np.nan, "n": n,
               "mean_abs_error_s": dm.mean(), "median_abs_error_s": np.nan}
        for t in tolerances:
            row[f"hit_{t:g}s"] = float((dm <= t + 1e-9).mean())
            row[f"hit_{t:g}s_low"] = row[f"hit_{t:g}s_high"] = np.nan
        rows.append(row)
    return pd.DataFrame(rows)


def selector_agreement(pose: pd.DataFrame, scenes: dict, *, tolerance_s: float = 0.5
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
        ``median_abs_error_s``; then rows with ``scene == "ALL"``: the mean hit rate and
        the median distance over every choice, per selector. Empty when no scene has
        selector picks.
    """
    rows, pooled = [], {}
    for scene, info in scenes.items():
        if not info.selector_frames:
            continue
        c = pose.loc[pose["scene"] == scene, "chosen_frame"].to_numpy(dtype=float)
        if c.size == 0:
            continue
        for name, fs in info.selector_frames.items():
            d = np.abs(c - fs[0]) / info.fps
            k = int((d <= tolerance_s + 1e-9).sum())
            lo, hi = wilson_interval(k, c.size)
            rows.append({"scene": scene, "selector": name, "frame": int(fs[0]), "n": int(c.size),
                         "hit": k / c.size, "hit_low": float(lo), "hit_high": float(hi),
                         "median_abs_error_s": float(np.median(d))})
            pooled.setdefault(name, []).append(d)
    for name, ds in pooled.items():
        d = np.concatenate(ds)
        k = int((d <= tolerance_s + 1e-9).sum())
        lo, hi = wilson_interval(k, d.size)
        rows.append({"scene": "ALL", "selector": name, "frame": -1, "n": int(d.size),
                     "hit": k / d.size, "hit_low": float(lo), "hit_high": float(hi),
                     "median_abs_error_s": float(np.median(d))})
    return pd.DataFrame(rows, columns=["scene", "selector", "frame", "n", "hit", "hit_low",
                                       "hit_high", "median_abs_error_s"])


def selector_timeline_document(pose: pd.DataFrame, scenes: dict) -> dict | None:
    """The scenes with selector picks in the layout of a key-moment evaluation document
    (no intervals), for :func:`snapcore.render.keymoments_plot.plot_keymoment_timelines`."""
    sc = [(s, i) for s, i in scenes.items() if i.selector_frames]
    if not sc:
        return None
    methods = list(dict.fromkeys(m for _, i in sc for m in i.selector_frames))
    return {"widen_s": 0.0, "methods": methods,
            "scenes": [{"scene": s, "fps": i.fps, "first_frame": i.frame_offset,
                        "last_frame": i.frame_offset + i.n_frames - 1, "intervals": []}
                       for s, i in sc],
            "rows": [{"scene": s, "method": m, "frames": fs} for s, i in sc
                     for m, fs in i.selector_frames.items()]}


def _sign_flip_p(d, *, n_permutations, rng):
    """One-sided p of mean(d) > 0 under sign symmetry; exact for small n."""
    d = np.asarray(d, dtype=float)
    t_obs = d.mean()
    if np.allclose(d, 0):
        return 1.0, True
    n = d.size
    if n <= EXACT_MAX_N:
        signs = np.array(list(itertools.product((1.0, -1.0), repeat=n)))
        t = (signs * d).mean(axis=1)
        return float(np.mean(t >= t_obs - 1e-12)), True
    signs = rng.choice((-1.0, 1.0), size=(n_permutations, n))
    t = (signs * d).mean(axis=1)
    return float((1 + np.sum(t >= t_obs - 1e-12)) / (1 + n_permutations)), False


def closeness_tests(pose: pd.DataFrame, scenes: dict, *, n_permutations: int = N_PERMUTATIONS,
                    seed: int = 0, alpha: float = 0.05) -> pd.DataFrame:
    """Is the algorithm closer to people than each baseline? One-sided permutation tests.

    Returns
    -------
    DataFrame
        ``scene``, ``baseline``, ``n``, ``algorithm_mean_abs_s``,
        ``baseline_mean_abs_s``, ``difference_s`` (baseline − algorithm; > 0 = the
        algorithm is closer), ``p_value``, ``method`` (``"sign-flip exact"``,
        ``"sign-flip Monte Carlo"``, ``"uniform frame exact"``), ``p_holm`` (over all
        rows), ``significant`` (p_holm < alpha), ``note``.
    """
    rng = np.random.default_rng(seed)
    rows = []
    for scene, info in scenes.items():
        c = pose.loc[pose["scene"] == scene, "chosen_frame"].to_numpy(dtype=float)
        if c.size == 0:
            continue
        preds = predictor_frames(info)
        a = preds.pop("algorithm")
        da = np.abs(c - a) / info.fps
        for name, b in preds.items():
            db = np.abs(c - b) / info.fps
            p, exact = _sign_flip_p(db - da, n_permutations=n_permutations, rng=rng)
            rows.append({"scene": scene, "baseline": name, "n": c.size,
                         "algorithm_mean_abs_s": da.mean(), "baseline_mean_abs_s": db.mean(),
                         "difference_s": db.mean() - da.mean(), "p_value": p,
                         "method": "sign-flip exact" if exact else "sign-flip Monte Carlo",
                         "note": "same frame as the algorithm" if b == a else ""})
        mean_per_frame = _uniform_distance_matrix(c, info).mean(axis=0)
        p = float(np.mean(mean_per_frame <= da.mean() + 1e-12))
        rows.append({"scene": scene, "baseline": "uniform_random", "n": c.size,
                     "algorithm_mean_abs_s": da.mean(),
                     "baseline_mean_abs_s": mean_per_frame.mean(),
                     "difference_s": mean_per_frame.mean() - da.mean(), "p_value": p,
                     "method": "uniform frame exact", "note": ""})
    out = pd.DataFrame(rows)
    if out.empty:
        return out
    out["p_holm"] = holm_adjust(out["p_value"])
    out["significant"] = out["p_holm"] < alpha
    return out


def frame_histogram(pose: pd.DataFrame, info: StudyScene, *, bins: int | None = None):
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
    edges = np.linspace(info.frame_offset - 0.5, info.frame_offset + info.n_frames - 0.5,
                        bins + 1)
    counts, edges = np.histogram(c, bins=edges)
    return counts, edges
