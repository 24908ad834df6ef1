"""Frame tests that hold under any position habit: a within-participant permutation over scenes.

The question behind every frame test of the report is whether people's picks *in a
scene* follow the algorithm's frame of that scene. Comparing a pick with a fixed frame
(the middle, the fastest pose) or with a uniformly random frame mixes that question with
another one: how central the pick is. A person who clicks at random is, on average,
closer to any frame away from the clip's ends than to a uniformly drawn one, so such a
test declares random clickers "closer than random" (issue 35).

The null hypothesis here is that a participant's *clip position* — the chosen frame as a
fraction ``u`` of the clip, ``u = (frame − first) / (n_frames − 1)`` in [0, 1] — does not
depend on the scene: their positions over the scenes they saw are exchangeable. It holds
for uniform clickers, for clickers who prefer the middle (any centre bias), and for
participant-specific habits ("I always pick near the end"). Under it, given the positions
a participant chose, each arrangement of them over their scenes is equally likely, so
the test permutes every participant's positions over their own scenes, independently
across participants (Ernst 2004, *Permutation methods: a basis for exact inference*,
Statistical Science 19(4):676–685; the randomisation is within the participant, as in a
stratified permutation test). A permuted position is placed in the scene at the same
fraction of its clip.

Per scene ``s`` and comparison the statistic is a mean over the scene's participants of
one number each (a participant with several choices of the scene gives their mean):

- *agreement* — ``−|x − a_s| / fps``: closeness to the algorithm's frame ``a_s``;
- *closer than X* — ``(|x − b_s| − |x − a_s|) / fps``: how much closer to the algorithm
  than to the baseline's frame ``b_s``.

Large values speak for the algorithm. The Monte-Carlo p-value is
``(1 + #{T* ≥ T}) / (1 + B)`` over ``B`` seeded permutations (valid at every ``B``:
Phipson & Smyth 2010, Stat. Appl. Genet. Mol. Biol. 9(1):39). The test asks "do the
picks in this scene gather at the algorithm's frame more than these people's position
habits elsewhere explain?" — agreement, not centrality.

Power: a permutation can only tell scene-specific behaviour from a habit when the
algorithm's frames sit at different clip positions in different scenes. If the
algorithm picked the same fraction of every clip, people who follow it would be
indistinguishable from people with a habit for that fraction (no test of this design
could tell them apart), and the test has no power; the more the scenes' picks differ in
clip position, the more it has. Habits in *seconds* (say "always 1 s after the start"
on clips of different lengths) are scene-dependent in clip position and are not covered
by the null.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

__all__ = [
    "N_PERMUTATIONS",
    "clip_positions",
    "permuted_within",
    "drawn_within",
    "scene_statistics",
    "permutation_pvalues",
    "design_from_rows",
    "habit_effects",
    "per_participant",
]

#: Permutations of the frame tests (p-values down to 1/10_000: Holm over ~20 tests at
#: α = 0.05 needs about 1/400).
N_PERMUTATIONS = 9_999
#: Permutations per block (memory: 2 × block × rows × 8 bytes).
_BLOCK = 512


def clip_positions(frames, first, n_frames) -> np.ndarray:
    """Chosen frames as fractions of their clips, ``(frame − first) / (n_frames − 1)``.

    Parameters
    ----------
    frames, first, n_frames : array-like, shape (N,)
        Chosen source frames, each clip's first source frame and its frame count.

    Returns
    -------
    ndarray of float, shape (N,)
        In [0, 1] (0 for a clip of one frame).
    """
    f, lo, n = (np.asarray(v, dtype=float) for v in (frames, first, n_frames))
    return np.where(n > 1, (f - lo) / np.maximum(n - 1, 1), 0.0)


def permuted_within(groups: np.ndarray, n_permutations: int, rng) -> np.ndarray:
    """Random permutations of positions ``0..N−1`` that move each index only within its group.

    Parameters
    ----------
    groups : ndarray of int, shape (N,)
        Group codes (participants), sorted: each group's rows are contiguous.
    n_permutations : int
    rng : numpy.random.Generator

    Returns
    -------
    ndarray of int, shape (n_permutations, N)
        Row ``b`` maps position ``j`` to the row whose value lands there: position ``j``
        receives a uniformly random member of its own group, all members used once.
    """
    groups = np.asarray(groups)
    if groups.size and np.any(np.diff(groups) < 0):
        raise ValueError("groups: expected sorted group codes")
    # A group code plus a uniform key in [0, 1) sorts the rows group by group (the
    # blocks stay where they are) and in a uniformly random order inside each block.
    keys = rng.random((n_permutations, groups.size)) + groups[None, :]
    return np.argsort(keys, axis=1, kind="stable")


def drawn_within(groups: np.ndarray, n_draws: int, rng) -> np.ndarray:
    """Row indices where position ``j`` receives a uniformly random member of its group.

    The draws of different positions are independent, so a row of indices is not a
    permutation; but a test that reads one row per participant (each participant chose
    once in the scene) sees exactly the distribution a permutation gives that row — a
    uniformly random one of the participant's positions — at a fraction of the cost of
    :func:`permuted_within` (no sort).

    Returns
    -------
    ndarray of int, shape (n_draws, N)
    """
    groups = np.asarray(groups)
    if groups.size and np.any(np.diff(groups) < 0):
        raise ValueError("groups: expected sorted group codes")
    start = np.searchsorted(groups, groups, side="left")
    size = np.searchsorted(groups, groups, side="right") - start
    return start + (rng.random((n_draws, groups.size)) * size).astype(np.int64)


def scene_statistics(u: np.ndarray, design: list[dict]) -> np.ndarray:
    """The tests' statistics for positions ``u`` (one study or many permuted copies).

    Parameters
    ----------
    u : ndarray, shape (..., N)
        Clip positions of the N rows (observed, or permuted over the last axis).
    design : list of dict
        One entry per test: ``rows`` (indices of the scene's rows), ``weights`` (shape
        (len(rows),): 1 / (participants × that participant's choices of the scene)),
        ``first``, ``span`` (n_frames − 1), ``fps``, ``algorithm`` (source frame) and
        ``baseline`` (source frame, or None for agreement).

    Returns
    -------
    ndarray, shape (..., len(design))
        Each test's statistic in seconds (large = closer to the algorithm).
    """
    out = np.empty(u.shape[:-1] + (len(design),))
    last = None
    for j, t in enumerate(design):
        if last is None or t["rows"] is not last["rows"]:
            # The tests of one scene share its rows: gather them and the distance to
            # the algorithm's frame once.
            x = t["first"] + u[..., t["rows"]] * t["span"]
            da = np.abs(x - t["algorithm"])
            last = t
        g = np.abs(x - t["baseline"]) - da if t["baseline"] is not None else -da
        out[..., j] = (g @ t["weights"]) / t["fps"]
    return out


def _closeness(u: np.ndarray, test: dict) -> np.ndarray:
    """A test's per-choice statistic (seconds) at clip positions ``u`` placed in its scene."""
    x = test["first"] + u * test["span"]
    g = -np.abs(x - test["algorithm"])
    if test["baseline"] is not None:
        g = g + np.abs(x - test["baseline"])
    return g / test["fps"]


def permutation_pvalues(
    groups: np.ndarray,
    u: np.ndarray,
    design: list[dict],
    *,
    n_permutations: int = N_PERMUTATIONS,
    seed: int = 0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One-sided Monte-Carlo p-values of the within-participant permutation tests.

    Parameters
    ----------
    groups : ndarray of int, shape (N,)
        Participant code of each row, sorted.
    u : ndarray of float, shape (N,)
        Clip position of each row (:func:`clip_positions`).
    design : list of dict
        The tests (:func:`scene_statistics`; ``repeated`` false in every test — nobody
        chose twice in a scene — lets the draws skip the sort, :func:`drawn_within`).
    n_permutations : int
        Monte-Carlo permutations B (drawn in blocks; the same seed gives the same
        p-values whatever the block size).
    seed : int
        Seed of the ``numpy.random.Generator`` drawing them.

    Returns
    -------
    observed : ndarray, shape (T,)
        The statistics of the data.
    null_mean : ndarray, shape (T,)
        Their mean over the permutations (the value the position habits predict).
    p_value : ndarray, shape (T,)
        ``(1 + #{T* ≥ T}) / (1 + B)``; a permuted value within 1e-9 s of the observed
        counts as a tie (≥), so equal distances computed along different float paths
        never make a test anti-conservative.
    """
    u = np.asarray(u, dtype=float)
    observed = scene_statistics(u, design)
    if not design:
        return observed, observed.copy(), observed.copy()
    rng = np.random.default_rng(seed)
    # Each test reads one scene's rows; when nobody chose twice in a scene, only the
    # marginal of each row matters and independent draws give it without sorting.
    draw = permuted_within if any(t.get("repeated", True) for t in design) else drawn_within
    exceed = np.zeros(len(design))
    total = np.zeros(len(design))
    done = 0
    while done < n_permutations:
        b = min(_BLOCK, n_permutations - done)
        stats = scene_statistics(u[draw(groups, b, rng)], design)
        exceed += (stats >= observed - 1e-9).sum(axis=0)
        total += stats.sum(axis=0)
        done += b
    return observed, total / max(n_permutations, 1), (1 + exceed) / (1 + n_permutations)


def design_from_rows(pose: pd.DataFrame, scenes: dict, comparisons) -> tuple:
    """Rows of the pose task → (participant codes, positions, test design, row order).

    Parameters
    ----------
    pose : DataFrame
        ``scene``, ``participant_id``, ``chosen_frame``.
    scenes : dict
        scene → :class:`~study_app.design.scenes.StudyScene`.
    comparisons : callable
        ``comparisons(info) → list of (name, baseline frame or None)`` for a scene.

    Returns
    -------
    groups : ndarray of int, shape (N,)
    u : ndarray of float, shape (N,)
    design : list of dict
        As :func:`scene_statistics`, plus ``scene``, ``comparison``, ``members`` (the
        participant codes of the scene, sorted), ``inverse`` (for each of ``rows``, its
        participant's index in ``members``), ``participants`` (their ids) and
        ``informative`` (how many of them chose in another scene too: the others'
        positions cannot move) and ``repeated`` (someone chose twice in the scene).
    """
    keep = pose[pose["scene"].isin(list(scenes))]
    who = keep["participant_id"].astype(str).to_numpy()
    ids, groups = _canonical_participants(who, keep)
    order = np.lexsort(
        (keep["chosen_frame"].to_numpy(dtype=float), keep["scene"].astype(str).to_numpy(), groups)
    )
    keep = keep.iloc[order].reset_index(drop=True)
    groups = groups[order]
    first = keep["scene"].map({s: float(i.frame_offset) for s, i in scenes.items()})
    n_frames = keep["scene"].map({s: float(i.n_frames) for s, i in scenes.items()})
    u = clip_positions(keep["chosen_frame"].to_numpy(dtype=float), first, n_frames)
    labels = keep["scene"].to_numpy()
    _, scene_code = np.unique(labels, return_inverse=True)
    # Scenes each participant chose in: one alone leaves nothing to permute.
    pairs = np.unique(np.stack([groups, scene_code]), axis=1)
    n_scenes = np.bincount(pairs[0], minlength=ids.size)
    design = []
    for scene, sc in scenes.items():
        rows = np.flatnonzero(labels == scene)
        if rows.size == 0:
            continue
        members, inverse, k = np.unique(groups[rows], return_inverse=True, return_counts=True)
        weights = 1.0 / (k[inverse] * members.size)
        for name, baseline in comparisons(sc):
            design.append(
                {
                    "scene": scene,
                    "comparison": name,
                    "rows": rows,
                    "weights": weights,
                    "first": float(sc.frame_offset),
                    "span": float(max(sc.n_frames - 1, 0)),
                    "fps": float(sc.fps),
                    "algorithm": float(sc.algorithm_frame),
                    "baseline": None if baseline is None else float(baseline),
                    "members": members,
                    "inverse": inverse,
                    "participants": ids[members],
                    "informative": int((n_scenes[members] > 1).sum()),
                    "repeated": bool((k > 1).any()),
                }
            )
    return groups, u, design


def _canonical_participants(who: np.ndarray, rows: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
    """Participants numbered in an order set by their answers, not by their ids.

    The Monte-Carlo draws are made participant by participant, so the order of the
    participants decides which draw each gets. Ordering them by their answers (the
    sorted ``(scene, chosen frame)`` pairs) makes the p-values the same whatever the
    ids and the row order are — the database's ids and an open file's pseudonyms give
    the same numbers. Participants with the same answers are interchangeable, so how
    their tie is broken changes nothing.

    Returns
    -------
    ids : ndarray of str, shape (P,)
        The participant id of each code, in canonical order.
    codes : ndarray of int, shape (N,)
        Each row's participant code.
    """
    answers = pd.DataFrame(
        {
            "who": who,
            "scene": rows["scene"].astype(str).to_numpy(),
            "frame": rows["chosen_frame"].to_numpy(dtype=float),
        }
    ).sort_values(["who", "scene", "frame"], kind="stable")
    signature = {
        w: tuple(zip(d["scene"], d["frame"], strict=True))
        for w, d in answers.groupby("who", sort=True)
    }
    ids = np.array(sorted(signature, key=lambda w: (signature[w], w)), dtype=object)
    code = {w: i for i, w in enumerate(ids)}
    return ids, np.array([code[w] for w in who], dtype=np.int64)


def per_participant(values: np.ndarray, test: dict) -> np.ndarray:
    """Mean of ``values`` (one per row of the test's scene) per participant of the scene."""
    k = np.bincount(test["inverse"], minlength=test["members"].size)
    return np.bincount(test["inverse"], weights=values, minlength=k.size) / k


def habit_effects(groups: np.ndarray, u: np.ndarray, test: dict) -> tuple[np.ndarray, np.ndarray]:
    """Per participant of a test's scene: their statistic, and what their habits predict.

    The prediction is the exact mean of the participant's statistic over the
    permutations: the statistic at each position they chose in any scene, averaged.

    Returns
    -------
    observed, expected : ndarray, shape (participants of the scene,)
        In seconds, large = closer to the algorithm; in the order of ``test["members"]``.
    """
    g = _closeness(u, test)
    observed = per_participant(g[test["rows"]], test)
    own = np.bincount(groups, weights=g) / np.bincount(groups)
    return observed, own[test["members"]]
