"""The information of the contact events, the story selector's event term.

Each onset and each release of a contactor's debounced contact
(:mod:`snapcore.select.limb_contacts`) is an event; an event of a kind (contactor,
onset or release) that happens ``n`` times in ``F`` frames carries ``-log2(n / F)`` bits
(:func:`event_surprisal`), credited to the frames where the limb is free: a release to
the frames after it, an onset to the frames before it. :func:`contact_state_entropy` is
the paper's ``-p log2 p`` on the same contacts, for ablation.
"""

from __future__ import annotations

import numpy as np

from snapcore.select.signals import half_gaussian, nonzero_rows

__all__ = ["event_surprisal", "event_marks", "spread_events", "contact_state_entropy"]


def event_surprisal(
    state: np.ndarray, *, fps: float, support_s: float = 0.2, sided: bool = True
) -> np.ndarray:
    """Information (bits) of the contact events, with temporal support, shape (F,).

    Parameters
    ----------
    state : ndarray of bool, shape (L, F)
        Debounced contacts per contactor.
    fps : float
    support_s : float
        Width (s) of the spreading kernel; 0: only the event frame.
    sided : bool
        Release events credit the frames after them, onsets the frames before them
        (where the limb is free); False: both sides.

    Notes
    -----
    Onset of contactor l at frame t: ``state[l, t]`` and not ``state[l, t-1]``; release
    at t: the first free frame. A contact running at a clip edge has no onset or release
    there (the clip cut it). For each (contactor, kind) with ``n`` events in ``F``
    frames, ``P = n / F`` is the probability that a frame carries such an event and
    each one carries ``-log2 P`` bits. Events of one frame add; the spread signal is
    ``sum_e I_e K(i - t_e)`` with ``K`` a (half-)Gaussian of peak 1.
    """
    onset, release = event_marks(state)
    return spread_events(onset, release, fps=fps, support_s=support_s, sided=sided)


def event_marks(state: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The onsets' and releases' bits at their own frames, shape (F,) each.

    :func:`event_surprisal` before the spreading: it is :func:`spread_events` of these.
    Spreading is linear, so the story adds its characters' marks and spreads them once.
    """
    st = np.asarray(state, dtype=bool)
    n_l, n_f = st.shape
    onset = np.zeros(n_f)
    release = np.zeros(n_f)
    if n_f < 2 or n_l == 0:
        return onset, release
    d = np.diff(st.astype(np.int8), axis=1)  # (L, F-1): +1 onset at t+1, -1 release at t+1
    for kind, out in ((1, onset), (-1, release)):
        # the events (a few dozen), contactor by contactor: per frame their bits add in
        # contactor order, as the column sums of a dense (L, F-1) array of bits would
        limb, frame = nonzero_rows(d == kind)
        n = np.bincount(limb, minlength=n_l)  # events per contactor
        bits = np.where(n > 0, -np.log2(np.maximum(n, 1) / n_f), 0.0)
        out[1:] += np.bincount(frame, weights=bits.take(limb), minlength=n_f - 1)
    return onset, release


def spread_events(onset, release, *, fps: float, support_s: float, sided: bool) -> np.ndarray:
    """:func:`event_marks` spread over time, shape (F,): onsets credited to the frames
    before them, releases to the frames after them (both sides unless ``sided``), over a
    half-Gaussian of ``support_s`` seconds and peak 1 (see :func:`event_surprisal`)."""
    n_f = onset.size
    kernel, r = half_gaussian(support_s * fps, sided)
    if r == 0:
        return onset + release
    # np.convolve(x, k)[i + r] = sum_t x[t] k[i - t + r]: kernel index r + (i - t), so the
    # "after" kernel (offsets >= 0) credits frames i >= t, its mirror frames i <= t
    after = np.convolve(release, kernel)[r : r + n_f]
    before = np.convolve(onset, kernel[::-1])[r : r + n_f]
    return after + before


def contact_state_entropy(state: np.ndarray) -> np.ndarray:
    """The paper's event entropy on debounced contacts, for ablation, shape (F,).

    ``-p_l log2 p_l`` (``p_l``: fraction of frames contactor l touches, eq. 6) at each
    onset and release frame of l (eq. 7, transitions mode).
    """
    st = np.asarray(state, dtype=bool)
    n_l, n_f = st.shape
    out = np.zeros(n_f)
    if n_f < 2 or n_l == 0:
        return out
    p = st.mean(axis=1)
    h = np.where(p > 0, -p * np.log2(np.where(p > 0, p, 1.0)), 0.0)
    mark = np.diff(st.astype(np.int8), axis=1) != 0
    out[1:] = (mark * h[:, None]).sum(axis=0)
    return out
