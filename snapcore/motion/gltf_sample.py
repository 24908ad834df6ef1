"""Sampling glTF animation curves at chosen times: STEP, LINEAR, CUBICSPLINE.

Pure array functions (glTF 2.0 specification, Appendix C "Animation sampler
interpolation modes"), vectorised over the sample times: one ``searchsorted`` finds
every sample's key interval, the interpolation is then elementwise.

- ``STEP``: the value of the last key at or before ``t``.
- ``LINEAR``: ``(1 - s) v_k + s v_{k+1}`` with ``s = (t - t_k) / (t_{k+1} - t_k)``; for
  rotations the spherical linear interpolation of unit quaternions along the shorter
  arc (``slerp``), falling back to normalised lerp where the two keys are nearly equal.
- ``CUBICSPLINE``: the output holds ``(in-tangent a_k, value v_k, out-tangent b_k)`` per
  key; ``p(s) = (2s³ - 3s² + 1) v_k + (s³ - 2s² + s) Δ b_k + (-2s³ + 3s²) v_{k+1}
  + (s³ - s²) Δ a_{k+1}`` with ``Δ = t_{k+1} - t_k``; rotations are normalised after.

Before the first key the first value holds, after the last key the last value.
"""

from __future__ import annotations

import numpy as np

__all__ = ["INTERPOLATIONS", "sample_curve", "slerp", "quat_normalize"]

INTERPOLATIONS = ("STEP", "LINEAR", "CUBICSPLINE")
#: Below this angle (cos > 1 - 1e-9) slerp is replaced by normalised lerp (no division
#: by a vanishing sine).
_SLERP_COS = 1.0 - 1e-9


def quat_normalize(q: np.ndarray) -> np.ndarray:
    """Unit quaternions ``(..., 4)``; zero quaternions become the identity ``(0, 0, 0, 1)``."""
    q = np.asarray(q, dtype=np.float64)
    n = np.linalg.norm(q, axis=-1, keepdims=True)
    ident = np.zeros_like(q)
    ident[..., 3] = 1.0
    return np.where(n > 1e-12, q / np.where(n > 1e-12, n, 1.0), ident)


def slerp(q0: np.ndarray, q1: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Spherical linear interpolation of unit quaternions along the shorter arc.

    Parameters
    ----------
    q0, q1 : ndarray of shape (N, 4)
        Quaternions in any consistent component order (glTF: ``x, y, z, w``).
    s : ndarray of shape (N,)
        Fractions in [0, 1].

    Returns
    -------
    ndarray of shape (N, 4)
        Unit quaternions.
    """
    q0 = quat_normalize(q0)
    q1 = quat_normalize(q1)
    d = np.sum(q0 * q1, axis=-1)
    q1 = np.where(d[:, None] < 0, -q1, q1)  # q and -q are one rotation: take the short way
    d = np.abs(d)
    s = np.asarray(s, dtype=np.float64)[:, None]
    near = d[:, None] > _SLERP_COS
    theta = np.arccos(np.clip(d, -1.0, 1.0))[:, None]
    sin = np.sin(theta)
    safe = np.where(near, 1.0, sin)
    w0 = np.where(near, 1.0 - s, np.sin((1.0 - s) * theta) / safe)
    w1 = np.where(near, s, np.sin(s * theta) / safe)
    return quat_normalize(w0 * q0 + w1 * q1)


def sample_curve(
    times: np.ndarray,
    values: np.ndarray,
    interpolation: str,
    t: np.ndarray,
    *,
    rotation: bool = False,
) -> np.ndarray:
    """Values of one animation sampler at times ``t``.

    Parameters
    ----------
    times : ndarray of shape (K,)
        Key times in seconds, strictly increasing.
    values : ndarray of shape (K, n), or (3K, n) for ``CUBICSPLINE``
        Key values (``n`` = 3 for translation/scale, 4 for rotation quaternions).
    interpolation : {"STEP", "LINEAR", "CUBICSPLINE"}
    t : ndarray of shape (T,)
        Sample times in seconds.
    rotation : bool
        The values are unit quaternions (slerp for LINEAR, normalised results).

    Returns
    -------
    ndarray of shape (T, n)

    Raises
    ------
    ValueError
        Unknown interpolation, or values that do not match the keys.
    """
    times = np.asarray(times, dtype=np.float64)
    values = np.asarray(values, dtype=np.float64)
    if values.ndim == 1:
        values = values[:, None]
    t = np.asarray(t, dtype=np.float64)
    k = times.size
    if interpolation not in INTERPOLATIONS:
        raise ValueError(
            f"unknown interpolation {interpolation!r} (expected one of {', '.join(INTERPOLATIONS)})"
        )
    per_key = 3 if interpolation == "CUBICSPLINE" else 1
    if k == 0 or values.shape[0] != per_key * k:
        raise ValueError(
            f"{values.shape[0]} output values for {k} keys of a "
            f"{interpolation} sampler (expected {per_key * k})"
        )
    if k > 1 and np.any(np.diff(times) <= 0):
        raise ValueError("key times must increase strictly")
    if per_key == 3:
        tangent_in, value, tangent_out = values[0::3], values[1::3], values[2::3]
    else:
        value = values
    if k == 1:
        out = np.repeat(value[:1], t.size, axis=0)
        return quat_normalize(out) if rotation else out
    # key interval of each sample: times[i] <= t < times[i + 1], clamped to the ends
    i = np.clip(np.searchsorted(times, t, side="right") - 1, 0, k - 2)
    dt = times[i + 1] - times[i]
    s = np.clip((t - times[i]) / dt, 0.0, 1.0)
    if interpolation == "STEP":
        j = np.where(t >= times[i + 1], i + 1, i)  # the last key at or before t
        out = value[j]
    elif interpolation == "LINEAR":
        if rotation:
            out = slerp(value[i], value[i + 1], s)
        else:
            out = (1.0 - s)[:, None] * value[i] + s[:, None] * value[i + 1]
    else:
        s2, s3 = s * s, s * s * s
        h00 = 2 * s3 - 3 * s2 + 1
        h10 = s3 - 2 * s2 + s
        h01 = -2 * s3 + 3 * s2
        h11 = s3 - s2
        out = (
            h00[:, None] * value[i]
            + (h10 * dt)[:, None] * tangent_out[i]
            + h01[:, None] * value[i + 1]
            + (h11 * dt)[:, None] * tangent_in[i + 1]
        )
    return quat_normalize(out) if rotation else out
