"""Shared helpers for epoch-difference slip tests over ``(T, N)`` series."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from robustrtk.core import FloatArray, InputError, IntArray


def as_series(t_s: npt.ArrayLike, *arrays: npt.ArrayLike) -> tuple[FloatArray, list[FloatArray]]:
    """Validate ``t_s (T,)`` and arrays ``(T, N)`` or ``(T,)``; return them as 2-D floats."""
    t = np.asarray(t_s, dtype=float)
    if t.ndim != 1:
        raise InputError(f"t_s must have shape (T,), got {t.shape}")
    if t.shape[0] > 1 and not np.all(np.diff(t) > 0):
        raise InputError("t_s must be strictly increasing")
    out = []
    for a in arrays:
        arr = np.asarray(a, dtype=float)
        if arr.ndim == 1:
            arr = arr[:, None]
        if arr.ndim != 2 or arr.shape[0] != t.shape[0]:
            raise InputError(f"expected an array of shape (T={t.shape[0]}, N), got {arr.shape}")
        out.append(arr)
    shapes = {a.shape for a in out}
    if len(shapes) > 1:
        raise InputError(f"series shapes differ: {sorted(shapes)}")
    return t, out


def previous_valid_index(valid: npt.NDArray[np.bool_]) -> IntArray:
    """Index of the last valid row strictly before each row, per column (-1 if none).

    Parameters
    ----------
    valid : ndarray of bool, shape (T, N)

    Returns
    -------
    prev : ndarray of int64, shape (T, N)
    """
    T = valid.shape[0]
    idx = np.where(valid, np.arange(T)[:, None], -1)
    run = np.maximum.accumulate(idx, axis=0)
    prev = np.empty_like(run)
    prev[0] = -1
    prev[1:] = run[:-1]
    return prev.astype(np.int64)
