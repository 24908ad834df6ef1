"""Signal helpers the pose selectors share: trajectory smoothing, min-max scaling and
the (half-)Gaussian that spreads an event's information over time.

:func:`hysteresis` and :func:`enforce_min_durations` debounce the story selector's
contact signals (:mod:`snapcore.select.story`).

Joint trajectories are smoothed with a Savitzky-Golay filter before anything
differentiates them (mocap jitter at 60-120 fps would otherwise dominate speeds and
curvatures); every selector (``paper``, ``story``, the stance model and the baselines)
uses :func:`smooth_positions`, and scores are put on one scale with :func:`minmax`
(the paper's eq. 9).

The filter is written as a cached matrix applied to sliding windows rather than
calling ``scipy.signal.savgol_filter``: the result is the same (a test compares them),
and the ``paper`` method's regression cases are recorded against this arithmetic.
"""

from __future__ import annotations

import math
import warnings
from functools import lru_cache

import numpy as np

__all__ = [
    "SMOOTH_S",
    "SAVGOL_POLYORDER",
    "window_frames",
    "savgol_matrix",
    "smooth_positions",
    "minmax",
    "half_gaussian",
    "find_peaks",
    "hysteresis",
    "hysteresis_rows",
    "true_runs",
    "nonzero_rows",
    "enforce_min_durations",
    "merge_adjacent",
]

#: Savitzky-Golay window (s) for smoothing joint trajectories before the curvature:
#: mocap jitter at 60-120 fps would otherwise turn every resting joint into a
#: high-curvature one. A tenth of a second keeps turns of a dancer's hand.
SMOOTH_S = 0.1
#: Polynomial order of that filter (quadratic keeps peaks and turning points).
SAVGOL_POLYORDER = 2


def window_frames(smooth_s: float, fps: float, n_frames: int, polyorder: int) -> int:
    """Odd Savitzky-Golay window for ``smooth_s`` seconds; 0 means no smoothing."""
    w = int(round(smooth_s * fps))
    w += 1 - w % 2  # odd
    w = min(w, n_frames - 1 + n_frames % 2)  # at most the clip, still odd
    return w if w > polyorder else 0


def savgol_matrix(window: int, polyorder: int) -> np.ndarray:
    """Savitzky-Golay smoothing as a matrix, shape (window, window).

    Row ``r`` evaluates, at sample ``r``, the least-squares polynomial of degree
    ``polyorder`` through the ``window`` samples. The middle row is the filter's
    interior kernel; the first and last ``window // 2`` rows smooth the ends of a
    signal from its first and last window (SciPy's ``savgol_filter(mode="interp")``).
    The result is read-only (computed once per window and order).
    """
    return _savgol_matrix(int(window), int(polyorder))


@lru_cache(maxsize=32)
def _savgol_matrix(window: int, polyorder: int) -> np.ndarray:
    half = window // 2
    t = (np.arange(window, dtype=float) - half) / max(half, 1)  # centred, scaled: well posed
    vander = np.vander(t, polyorder + 1, increasing=True)
    mat = vander @ np.linalg.pinv(vander)
    mat.flags.writeable = False
    return mat


def smooth_positions(
    positions: np.ndarray,
    *,
    fps: float,
    smooth_s: float = SMOOTH_S,
    polyorder: int = SAVGOL_POLYORDER,
) -> np.ndarray:
    """Savitzky-Golay smoothed trajectories.

    Parameters
    ----------
    positions : ndarray of shape (F, ...)
        Metres; smoothed along the first axis.
    fps : float
    smooth_s : float
        Window in seconds (rounded to an odd number of frames at ``fps``, at most the
        clip); windows of at most ``polyorder`` frames (or ``smooth_s=0``) leave the
        input unchanged.
    polyorder : int

    Returns
    -------
    ndarray of the input's shape
        A new array. The ends are fitted, not padded (:func:`savgol_matrix`); equal
        to ``scipy.signal.savgol_filter(x, w, polyorder, axis=0, mode="interp")``.
    """
    x = np.asarray(positions, dtype=float)
    n_f = x.shape[0]
    w = window_frames(smooth_s, fps, n_f, polyorder) if smooth_s > 0 else 0
    if w == 0:
        return x.copy()
    from numpy.lib.stride_tricks import sliding_window_view

    h = w // 2
    mat = savgol_matrix(w, polyorder)
    flat = x.reshape(n_f, -1)
    out = np.empty_like(flat)
    out[h : n_f - h] = sliding_window_view(flat, w, axis=0) @ mat[h]
    out[:h] = mat[:h] @ flat[:w]
    out[n_f - h :] = mat[h + 1 :] @ flat[n_f - w :]
    return out.reshape(x.shape)


def minmax(values: np.ndarray, *, name: str = "values") -> np.ndarray:
    """Min-max normalise to [0, 1] (eq. 9); a constant array becomes 0 with a warning."""
    v = np.asarray(values, dtype=float)
    if v.size == 0:
        return v.copy()
    lo, hi = float(v.min()), float(v.max())
    if not hi > lo:
        warnings.warn(f"{name} is constant over the clip ({lo:g}); it contributes 0", stacklevel=3)
        return np.zeros_like(v)
    return (v - lo) / (hi - lo)


def half_gaussian(sigma_frames: float, sided: bool) -> tuple[np.ndarray, int]:
    """A Gaussian kernel of peak 1 over offsets ``-r..r`` and its radius ``r``.

    ``sided``: zero at negative offsets (convolved with a signal of events, it credits
    the frames after each event; reversed, the frames before). ``sigma_frames <= 0``
    gives the one-frame kernel ``[1]`` and ``r = 0``. The kernel is read-only (made
    once per width and side).
    """
    return _half_gaussian(float(sigma_frames), bool(sided))


@lru_cache(maxsize=32)
def _half_gaussian(sigma_frames: float, sided: bool) -> tuple[np.ndarray, int]:
    if sigma_frames <= 0:
        k, r = np.ones(1), 0
    else:
        r = int(math.ceil(3 * sigma_frames))
        off = np.arange(-r, r + 1)
        k = np.exp(-0.5 * (off / sigma_frames) ** 2)
        if sided:
            k = np.where(off >= 0, k, 0.0)
    k.flags.writeable = False
    return k, r


def find_peaks(x: np.ndarray, *, height: float, prominence: float) -> np.ndarray:
    """Indices of the peaks of ``x`` at least ``height`` high and ``prominence``
    prominent: ``scipy.signal.find_peaks(x, height=..., prominence=...)[0]``, the same
    indices (a test compares them on many arrays with plateaus and NaN).

    Written here because importing ``scipy.signal`` costs 1-3 s, more than all of a
    ``snapshot select`` run's work. SciPy's definitions: a peak is a sample (the middle
    of a plateau, rounded down) higher than both neighbours, never the first or last;
    its prominence is its height over the higher of the lowest points on either side
    before the signal rises above it (or ends, or reaches a NaN).

    Parameters
    ----------
    x : ndarray of shape (N,)
    height, prominence : float
        Lower bounds, inclusive.

    Returns
    -------
    ndarray of int
    """
    x = np.asarray(x, dtype=np.float64)
    n = x.shape[0]
    if n < 3:
        return np.zeros(0, dtype=np.intp)
    # runs of equal values (NaN never equals, so each NaN is its own run)
    change = np.empty(n, dtype=bool)  # (np.r_'s index machinery took longer than this)
    change[0] = True
    np.not_equal(x[1:], x[:-1], out=change[1:])
    start = np.flatnonzero(change)
    end = np.empty_like(start)
    end[:-1] = start[1:] - 1
    end[-1] = n - 1
    v = x[start]
    inner = np.arange(1, len(start) - 1)
    up = v[inner - 1] < v[inner]
    down = v[inner + 1] < v[inner]
    runs = inner[up & down]
    peaks = (start[runs] + end[runs]) // 2
    peaks = peaks[height <= x[peaks]]
    keep = np.zeros(len(peaks), dtype=bool)
    for i, p in enumerate(peaks):
        top = x[p]
        # the scan stops before the first sample that is not <= the peak (higher, NaN)
        stop_l = np.flatnonzero(~(x[:p] <= top))
        lo = stop_l[-1] + 1 if len(stop_l) else 0
        stop_r = np.flatnonzero(~(x[p + 1 :] <= top))
        hi = p + 1 + stop_r[0] if len(stop_r) else n
        keep[i] = prominence <= top - max(x[lo : p + 1].min(), x[p:hi].min())
    return peaks[keep].astype(np.intp)


def hysteresis(score: np.ndarray, on: float, off: float) -> np.ndarray:
    """Two-threshold switch along the first axis.

    Parameters
    ----------
    score : ndarray of shape (F, ...)
        Low means "in contact".
    on, off : float
        The state switches on where ``score <= on`` and off where ``score > off``
        (``off >= on``); in between it keeps its previous value. It starts off.

    Returns
    -------
    ndarray of bool, the shape of ``score``

    Notes
    -----
    Vectorised: the state at frame i is the one set by the last frame ``<= i`` where
    the score was outside the band (see :func:`hysteresis_rows`).
    """
    s = np.asarray(score, dtype=float)
    # frames last and contiguous: along a strided first axis (a (F, L) score) every
    # step below took several times as long
    rows = np.ascontiguousarray(np.moveaxis(s, 0, -1))
    return np.moveaxis(hysteresis_rows(rows, on, off), -1, 0)


def hysteresis_rows(score: np.ndarray, on: float, off: float) -> np.ndarray:
    """:func:`hysteresis` along the *last* axis: ``score`` of shape (..., F), one signal
    per row of frames (the story's contactors, (L, F)); bool of the same shape."""
    s = np.asarray(score, dtype=float)
    n = s.shape[-1]
    low = s <= on
    if low.size == 0:
        return low
    decided = low | (s > off)
    # the rows end to end, each row's first frame decided (an undecided first frame is
    # off, and ``low`` is False there): the state is ``low`` at the last decided frame,
    # so it changes only at decided frames whose ``low`` differs from the previous
    # one's -- a few dozen switches, each run written by one repeat (a running maximum
    # of frame indices carrying the state took twice as long: an accumulate is a
    # sequential loop over every frame)
    decided.reshape(-1, n)[:, 0] = True
    flat = low.reshape(-1)
    at = np.flatnonzero(decided)
    state_at = flat[at]
    switch = at[np.flatnonzero(state_at[1:] != state_at[:-1]) + 1]
    bounds = np.empty(switch.size + 2, dtype=np.intp)
    bounds[0], bounds[-1] = 0, flat.size
    bounds[1:-1] = switch
    return np.repeat(flat[bounds[:-1]], np.diff(bounds)).reshape(low.shape)


def nonzero_rows(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.nonzero`` of a 2-D array, (rows, columns), in the same (row-major) order.

    From the flat indices: ``np.nonzero`` of a 2-D array walks it element by element
    (37 us for a (10, 2,000) mask with a few dozen hits) where ``np.flatnonzero`` scans
    it in one pass (4 us), and the few hits are split into rows and columns after.
    """
    m = np.asarray(mask)
    flat = np.flatnonzero(m)
    return np.divmod(flat, m.shape[1]) if m.shape[1] else (flat, flat.copy())


def true_runs(b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Starts and stops (exclusive) of the True runs of a 1-D bool array."""
    padded = np.zeros(b.size + 2, dtype=np.int8)  # False at both ends: every run closes
    padded[1:-1] = b
    d = padded[1:] - padded[:-1]
    return np.flatnonzero(d == 1), np.flatnonzero(d == -1)


def _runs_mask(size: int, starts: np.ndarray, stops: np.ndarray) -> np.ndarray:
    """A bool array of ``size``, True on ``[s, e)`` for every run: runs sorted and
    disjoint. Without a Python loop over them."""
    # the stretches between the runs and the runs, alternately, each written by one
    # repeat (a running sum of +1 at each start and -1 at each stop, a sequential loop
    # over every frame, took longer)
    bounds = np.empty(2 * starts.size + 2, dtype=np.intp)
    bounds[0], bounds[-1] = 0, size
    bounds[1:-1:2], bounds[2:-1:2] = starts, stops
    inside = np.zeros(bounds.size - 1, dtype=bool)
    inside[1::2] = True
    return np.repeat(inside, np.diff(bounds))


def enforce_min_durations(state: np.ndarray, min_on: int, min_off: int) -> np.ndarray:
    """Close short gaps, then drop short contacts, of contact signals.

    Parameters
    ----------
    state : ndarray of bool, shape (F,) or (L, F)
        One signal, or one per row (each row on its own).
    min_on, min_off : int
        Minimum contact and gap lengths (frames).

    Returns
    -------
    ndarray of bool, the shape of ``state``
        Gaps inside the clip shorter than ``min_off`` are filled (a gap touching a clip
        edge is left: what lies beyond is unknown); then contacts shorter than
        ``min_on`` are removed. Afterwards no contact is shorter than ``min_on`` and no
        interior gap shorter than ``min_off`` unless removing a short contact opened
        it next to a clip edge.

    Notes
    -----
    All rows at once: they are laid end to end with one free frame after each, so that
    no contact runs from one row into the next, and a gap that reaches that frame
    touches its row's end.

    Worked on the contacts' ends alone: the interior gaps are those between two
    consecutive contacts of one row, so closing the short ones joins those contacts
    (each contact that follows a closed gap continues the one before it), and the
    contacts that stay too short are left out when the result is written.
    """
    st = np.asarray(state, dtype=bool)
    rows = st.reshape(-1, st.shape[-1]) if st.ndim else st.reshape(1, 1)
    n = rows.shape[1]
    width = n + 1
    padded = np.zeros((rows.shape[0], width), dtype=bool)
    padded[:, :n] = rows
    s, e = true_runs(padded.reshape(-1))  # contacts, the rows end to end
    # a gap shorter than min_off between two contacts of one row is closed
    closed = (s[1:] - e[:-1] < min_off) & (s[1:] // width == s[:-1] // width)
    first = np.ones(s.size, dtype=bool)  # contacts that do not continue the one before
    first[1:] = ~closed
    last = np.ones(s.size, dtype=bool)  # contacts not continued by the next
    last[:-1] = ~closed
    s, e = s[first], e[last]
    long = e - s >= min_on
    out = _runs_mask(padded.size, s[long], e[long])
    return out.reshape(padded.shape)[:, :n].reshape(st.shape).copy()


def merge_adjacent(
    joints: np.ndarray, starts: np.ndarray, ends: np.ndarray
) -> tuple[np.ndarray, ...]:
    """Join interactions of one joint that follow each other without a free frame.

    When an interaction ends because the relative position drifted beyond the
    tolerance and a new one starts on the very next frame, the joint never left the
    object: the contact slid and re-anchored (a landing foot settling, a pivot). The
    interaction *state* is continuous, so its onset and release are those of the
    union. Inputs sorted by joint, then start (as :func:`snapcore.select.contacts.scan_interactions` returns).

    Returns
    -------
    joints, starts, ends, first : ndarray of int
        The merged interactions and, for each, the index of its first input piece.
    """
    if joints.size == 0:
        return joints, starts, ends, np.zeros(0, dtype=np.int64)
    new = np.r_[True, (joints[1:] != joints[:-1]) | (starts[1:] != ends[:-1] + 1)]
    first = np.flatnonzero(new)
    last = np.r_[first[1:] - 1, joints.size - 1]
    return joints[first], starts[first], ends[last], first
