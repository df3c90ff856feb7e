r"""Accuracy metrics: position errors against truth, summary statistics, fix rate, time to
first fix, and the "extra error" of contaminated epochs.

Statistics ignore NaN rows (epochs without truth or solution). Percentiles use numpy's
linear interpolation. Horizontal/vertical statistics rotate ECEF errors into the local
East-North-Up frame of a reference point: :math:`e_{enu} = R(\varphi_0, \lambda_0)\,e`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

import numpy as np
import numpy.typing as npt

from robustrtk.core import BoolArray, FloatArray, InputError
from robustrtk.geometry.frames import ecef2enu_rotation, ecef2geodetic


class _HasTimesPositions(Protocol):
    @property
    def t_s(self) -> FloatArray: ...
    @property
    def pos_m(self) -> FloatArray: ...


def position_errors(
    sol: _HasTimesPositions,
    truth_t_s: npt.ArrayLike | None,
    truth_pos_m: npt.ArrayLike,
    tol_s: float = 0.005,
) -> FloatArray:
    """Solution minus truth at each solution epoch.

    Parameters
    ----------
    sol : SolutionTable (or anything with ``t_s (T,)`` and ``pos_m (T, 3)``)
    truth_t_s : array_like, shape (M,), or None
        Truth epochs (s); None (or a scalar with a single point) for a static truth.
    truth_pos_m : array_like, shape (3,) or (M, 3)
        Truth positions in the solution's frame (m).
    tol_s : float
        Largest |t_sol - t_truth| for a match (nearest truth epoch).

    Returns
    -------
    err_m : ndarray, shape (T, 3)
        ``pos - truth``; NaN rows where no truth epoch lies within ``tol_s``.
    """
    t = np.asarray(sol.t_s, dtype=float)
    pos = np.asarray(sol.pos_m, dtype=float).reshape(-1, 3)
    truth = np.asarray(truth_pos_m, dtype=float)
    if truth.shape == (3,):
        return pos - truth
    if truth.ndim != 2 or truth.shape[1] != 3:
        raise InputError(f"truth_pos_m must have shape (3,) or (M, 3), got {truth.shape}")
    if truth_t_s is None:
        raise InputError("truth_t_s is required with a truth trajectory")
    tt = np.asarray(truth_t_s, dtype=float).reshape(-1)
    if tt.shape[0] != truth.shape[0]:
        raise InputError(f"truth_t_s has {tt.shape[0]} epochs, truth_pos_m {truth.shape[0]}")
    order = np.argsort(tt)
    tt, truth = tt[order], truth[order]
    j = np.clip(np.searchsorted(tt, t), 1, max(len(tt) - 1, 1))
    left = np.clip(j - 1, 0, len(tt) - 1)
    right = np.clip(j, 0, len(tt) - 1)
    pick = np.where(np.abs(tt[left] - t) <= np.abs(tt[right] - t), left, right)
    ok = np.abs(tt[pick] - t) <= tol_s
    return np.where(ok[:, None], pos - truth[pick], np.nan)


def enu_errors(err_ecef_m: npt.ArrayLike, ref_pos_ecef_m: npt.ArrayLike) -> FloatArray:
    """ECEF error vectors ``(T, 3)`` rotated to ENU at ``ref_pos_ecef_m`` (3,)."""
    lat, lon, _ = ecef2geodetic(np.asarray(ref_pos_ecef_m, dtype=float).reshape(3))
    rot = ecef2enu_rotation(float(lat), float(lon))
    return np.asarray(err_ecef_m, dtype=float).reshape(-1, 3) @ rot.T


def _pct(x: FloatArray, q: float) -> float:
    return float(np.percentile(x, q, method="linear")) if x.size else float("nan")


def _rms(x: FloatArray) -> float:
    return float(np.sqrt(np.mean(x**2))) if x.size else float("nan")


def hv_error_stats(enu_m: npt.ArrayLike) -> dict[str, float]:
    """Horizontal and vertical statistics of ENU errors.

    With :math:`h_i = \\sqrt{e_i^2 + n_i^2}` and :math:`v_i = |u_i|`: RMS
    (:math:`\\sqrt{\\tfrac1n \\sum h_i^2}`), 95th percentile (:func:`numpy.percentile`,
    linear interpolation) and maximum of each.

    Parameters
    ----------
    enu_m : array_like, shape (n, 3)
        ENU errors (m); NaN rows are ignored.

    Returns
    -------
    dict
        ``H_rms_m, H_95_m, V_rms_m, V_95_m, H_max_m, V_max_m`` (m; NaN when no row is left).
    """
    e = np.asarray(enu_m, dtype=float).reshape(-1, 3)
    e = e[np.all(np.isfinite(e), axis=1)]
    h = np.hypot(e[:, 0], e[:, 1])
    v = np.abs(e[:, 2])
    return {
        "H_rms_m": _rms(h),
        "H_95_m": _pct(h, 95.0),
        "V_rms_m": _rms(v),
        "V_95_m": _pct(v, 95.0),
        "H_max_m": float(h.max()) if h.size else float("nan"),
        "V_max_m": float(v.max()) if v.size else float("nan"),
    }


def error_stats(err_m: npt.ArrayLike, ref_pos_ecef_m: npt.ArrayLike | None = None) -> dict[str, float]:
    """Summary statistics of position errors.

    Parameters
    ----------
    err_m : array_like, shape (T, 3)
        Errors (m); NaN rows are ignored.
    ref_pos_ecef_m : array_like, shape (3,), optional
        ECEF reference point; when given, errors are rotated to ENU and horizontal
        (``sqrt(e^2 + n^2)``) and vertical (``|u|``) statistics are added.

    Returns
    -------
    dict
        ``n``; ``mean_abs_x_m, mean_abs_y_m, mean_abs_z_m`` (mean |error| per axis, the
        paper's Fig. 6 measure); ``rms_3d_m``; ``p50_3d_m``, ``p95_3d_m``, ``max_3d_m``;
        with a reference also the :func:`hv_error_stats` of the ENU errors (``H_rms_m,
        H_95_m, V_rms_m, V_95_m, H_max_m, V_max_m``).
    """
    e = np.asarray(err_m, dtype=float).reshape(-1, 3)
    e = e[np.all(np.isfinite(e), axis=1)]
    d3 = np.linalg.norm(e, axis=1)
    mean_abs = np.mean(np.abs(e), axis=0) if len(e) else np.full(3, np.nan)
    out = {
        "n": float(len(e)),
        "mean_abs_x_m": float(mean_abs[0]),
        "mean_abs_y_m": float(mean_abs[1]),
        "mean_abs_z_m": float(mean_abs[2]),
        "rms_3d_m": _rms(d3),
        "p50_3d_m": _pct(d3, 50.0),
        "p95_3d_m": _pct(d3, 95.0),
        "max_3d_m": float(d3.max()) if len(e) else float("nan"),
    }
    if ref_pos_ecef_m is not None:
        out.update(hv_error_stats(enu_errors(e, ref_pos_ecef_m)))
    return out


def sigma_coverage(err_m: npt.ArrayLike, std_m: npt.ArrayLike, k: float = 3.0) -> dict[str, float]:
    """How often the reported σ covers the error: the fraction of epochs with
    ``|errᵢ| ≤ k σᵢ`` on each axis, and on all three at once.

    Parameters
    ----------
    err_m, std_m : array_like, shape (T, 3)
        Errors and reported standard deviations in the same frame (m); epochs with a NaN
        in either are left out.
    k : float
        Multiple of σ.

    Returns
    -------
    dict
        ``n`` epochs counted, ``axis0``, ``axis1``, ``axis2`` and ``all`` (fractions in
        [0, 1]; NaN without epochs).
    """
    e = np.asarray(err_m, float).reshape(-1, 3)
    s = np.asarray(std_m, float).reshape(-1, 3)
    ok = np.all(np.isfinite(e), axis=1) & np.all(np.isfinite(s), axis=1)
    inside = np.abs(e[ok]) <= k * s[ok]
    n = int(ok.sum())
    nan = float("nan")
    out = {"n": float(n)}
    for a in range(3):
        out[f"axis{a}"] = float(inside[:, a].mean()) if n else nan
    out["all"] = float(np.all(inside, axis=1).mean()) if n else nan
    return out


def fix_rate(status: npt.ArrayLike, fixed: Sequence[str] = ("fixed",), n_total: int | None = None) -> float:
    """Fraction of epochs whose status is in ``fixed``.

    Parameters
    ----------
    status : array_like of str, shape (T,)
    fixed : sequence of str
        Statuses counted as fixed (add ``"partial"`` to count partial fixes).
    n_total : int, optional
        Denominator; default: epochs with a solution (status other than ``"none"``).

    Returns
    -------
    float in [0, 1] (NaN when the denominator is 0).
    """
    s = np.asarray(status).astype(str)
    num = int(np.isin(s, list(fixed)).sum())
    den = int((s != "none").sum()) if n_total is None else int(n_total)
    return num / den if den > 0 else float("nan")


def time_to_first_fix(
    t_s: npt.ArrayLike,
    status: npt.ArrayLike,
    t0_s: float | None = None,
    fixed: Sequence[str] = ("fixed",),
) -> float:
    """Seconds from ``t0_s`` (default: the first epoch) to the first fixed epoch.

    Returns NaN when no epoch is fixed.
    """
    t = np.asarray(t_s, dtype=float)
    s = np.asarray(status).astype(str)
    idx = np.flatnonzero(np.isin(s, list(fixed)))
    if idx.size == 0 or t.size == 0:
        return float("nan")
    start = float(t[0]) if t0_s is None else float(t0_s)
    return float(t[idx[0]] - start)


def extra_error(err3d_m: npt.ArrayLike, contaminated_mask: npt.ArrayLike) -> FloatArray:
    """Error added by contamination, per epoch.

    ``extra[i] = err3d[i] - err3d[j]`` for each contaminated epoch ``i``, with ``j`` the
    last clean (not contaminated, finite error) epoch before ``i``.

    Parameters
    ----------
    err3d_m : array_like, shape (T,)
        3D error norm per epoch (m).
    contaminated_mask : array_like of bool, shape (T,)

    Returns
    -------
    extra_m : ndarray, shape (T,)
        NaN at clean epochs, and at contaminated ones with no clean epoch before them.
    """
    e = np.asarray(err3d_m, dtype=float).reshape(-1)
    m = np.asarray(contaminated_mask, dtype=bool).reshape(-1)
    if e.shape != m.shape:
        raise InputError(f"err3d_m {e.shape} and contaminated_mask {m.shape} differ")
    clean = ~m & np.isfinite(e)
    idx = np.where(clean, np.arange(e.size), -1)
    last = np.maximum.accumulate(idx) if e.size else idx
    ok = m & (last >= 0)
    return np.where(ok, e - e[np.maximum(last, 0)], np.nan)


def mean_extra_error(err3d_m: npt.ArrayLike, contaminated_mask: npt.ArrayLike) -> float:
    """Mean of :func:`extra_error` over the contaminated epochs where it is defined."""
    x = extra_error(err3d_m, contaminated_mask)
    x = x[np.isfinite(x)]
    return float(x.mean()) if x.size else float("nan")


def removed_fraction(
    err3d_ref_m: npt.ArrayLike, err3d_new_m: npt.ArrayLike, contaminated_mask: BoolArray
) -> float:
    """Share of the reference solution's mean extra error removed by the new one:
    ``1 - mean_extra(new) / mean_extra(ref)``."""
    ref = mean_extra_error(err3d_ref_m, contaminated_mask)
    new = mean_extra_error(err3d_new_m, contaminated_mask)
    return 1.0 - new / ref if ref != 0 else float("nan")
