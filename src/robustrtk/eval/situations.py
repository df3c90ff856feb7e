r"""The observation situations of Li et al. (2019), Table 1 and Fig. 6.

Each DD at each epoch falls in one of three situations from its discriminant statistic
:math:`\Delta\bar v` and the IGG-III constants :math:`k_0 < k_1` (paper: 2 and 8):

* #1 :math:`|\Delta\bar v| \le k_0` — normal, weight kept;
* #2 :math:`k_0 < |\Delta\bar v| \le k_1` — small gross error, weight reduced;
* #3 :math:`|\Delta\bar v| > k_1` — large gross error, observation rejected.

An **epoch** ("All DD PLs" row of Table 1) is #1 when every DD at that epoch is #1, #3 when
any DD is #3, and #2 otherwise (the paper counts as #1 only the epochs where all DD code
observations are "simultaneously normal"; the published counts satisfy this rule, e.g.
the per-DD #3 counts add up to the all-DD #3 count). DDs of unknown situation (0) are
ignored; an epoch with none known is 0.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import numpy.typing as npt

from robustrtk.core import FloatArray, IntArray
from robustrtk.io.solution import DiagTable

ALL_LABEL = "All DDs"


def classify_dv(dv: npt.ArrayLike, k0: float = 2.0, k1: float = 8.0) -> IntArray:
    """Situation 1/2/3 of each ``dv`` (0 where NaN), see the module docstring."""
    a = np.abs(np.asarray(dv, dtype=float))
    out = np.where(a <= k0, 1, np.where(a <= k1, 2, 3)).astype(np.int64)
    return np.where(np.isnan(a), 0, out)


def _situations(diag: DiagTable, from_dv: bool, k0: float, k1: float) -> IntArray:
    s = classify_dv(diag.dv, k0, k1) if from_dv else np.asarray(diag.situation, np.int64)
    return np.where(_measured(diag), s, 0)


def _measured(diag: DiagTable) -> np.ndarray:
    """Rows of DDs, not engine events (integrity, adaptive factor, restarts): an event row
    has neither a situation nor a Δv̄."""
    return (np.asarray(diag.situation) != 0) | np.isfinite(np.asarray(diag.dv, float))


def epoch_situations(
    diag: DiagTable, *, from_dv: bool = False, k0: float = 2.0, k1: float = 8.0
) -> tuple[FloatArray, IntArray]:
    """Situation of each epoch over all its DDs.

    Parameters
    ----------
    diag : DiagTable
    from_dv : bool
        Recompute each DD's situation from ``dv`` with ``k0, k1`` instead of using the
        recorded ``situation`` column.

    Returns
    -------
    epoch_t_s : ndarray, shape (E,)
    situation : ndarray of int, shape (E,)
    """
    s = _situations(diag, from_dv, k0, k1)
    epochs, ei = np.unique(diag.t_s, return_inverse=True)
    known = s > 0
    n_known = np.bincount(ei, weights=known, minlength=epochs.size)
    n_one = np.bincount(ei, weights=s == 1, minlength=epochs.size)
    n_three = np.bincount(ei, weights=s == 3, minlength=epochs.size)
    out = np.where(n_three > 0, 3, np.where(n_one == n_known, 1, 2)).astype(np.int64)
    return epochs, np.where(n_known > 0, out, 0)


def situation_counts(
    diag: DiagTable, *, from_dv: bool = False, k0: float = 2.0, k1: float = 8.0
) -> dict[str, tuple[int, int, int]]:
    """Table 1: epochs in situation #1, #2, #3 per DD label and for all DDs.

    Returns
    -------
    dict
        ``{label: (n1, n2, n3)}`` in order of first appearance, then
        :data:`ALL_LABEL` for the epoch-level classification.
    """
    s = _situations(diag, from_dv, k0, k1)
    out: dict[str, tuple[int, int, int]] = {}
    labels = diag.dd
    for lab in dict.fromkeys(labels[_measured(diag)].tolist()):
        sel = s[labels == lab]
        out[lab] = (int((sel == 1).sum()), int((sel == 2).sum()), int((sel == 3).sum()))
    _, es = epoch_situations(diag, from_dv=from_dv, k0=k0, k1=k1)
    out[ALL_LABEL] = (int((es == 1).sum()), int((es == 2).sum()), int((es == 3).sum()))
    return out


def situation_mean_abs_errors(
    epoch_t_s: npt.ArrayLike,
    epoch_situation: npt.ArrayLike,
    errors: Mapping[str, tuple[npt.ArrayLike, npt.ArrayLike]],
    *,
    situations: tuple[int, ...] = (1, 2, 3),
    tol_s: float = 1e-3,
) -> dict[str, dict[int, FloatArray]]:
    """Fig. 6: mean |error| per axis in each situation, for each solution.

    Parameters
    ----------
    epoch_t_s, epoch_situation : array_like, shape (E,)
        From :func:`epoch_situations` (of the solution whose diagnostics define the
        situations, as in the paper where both filters are judged on the same epochs).
    errors : mapping name -> (t_s (T,), err_m (T, 3))
        Position errors of each solution (e.g. ``{"SUKF": ..., "RUKF": ...}``).
    situations : tuple of int
    tol_s : float
        Time tolerance to match solution epochs to diagnostic epochs.

    Returns
    -------
    dict
        ``{name: {situation: mean |err| (3,)}}``; NaN where no epoch matches.
    """
    et = np.asarray(epoch_t_s, dtype=float)
    es = np.asarray(epoch_situation, dtype=np.int64)
    order = np.argsort(et)
    et, es = et[order], es[order]
    out: dict[str, dict[int, FloatArray]] = {}
    for name, (t, err) in errors.items():
        tt = np.asarray(t, dtype=float)
        e = np.asarray(err, dtype=float).reshape(-1, 3)
        if et.size:
            j = np.clip(np.searchsorted(et, tt), 0, et.size - 1)
            jl = np.clip(j - 1, 0, et.size - 1)
            pick = np.where(np.abs(et[jl] - tt) < np.abs(et[j] - tt), jl, j)
            sit = np.where(np.abs(et[pick] - tt) <= tol_s, es[pick], 0)
        else:
            sit = np.zeros(tt.size, dtype=np.int64)
        ok = np.all(np.isfinite(e), axis=1)
        out[name] = {}
        for k in situations:
            sel = ok & (sit == k)
            out[name][k] = np.abs(e[sel]).mean(axis=0) if sel.any() else np.full(3, np.nan)
    return out
