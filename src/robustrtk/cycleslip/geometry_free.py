r"""Geometry-free (two-frequency) cycle-slip detector.

The geometry-free phase combination (m)

.. math:: L_{GF}(t) = \lambda_1 \varphi_1(t) - \lambda_2 \varphi_2(t)

removes geometry, clocks and troposphere and keeps the ionosphere (slowly varying) plus
the constant :math:`\lambda_1 N_1 - \lambda_2 N_2`. A slip on either frequency changes it
by :math:`\lambda_1 \Delta N_1 - \lambda_2 \Delta N_2`, so a slip is declared when

.. math:: |L_{GF}(t) - L_{GF}(t_{prev})| > \text{threshold\_m}

with :math:`t_{prev}` the previous epoch where both phases exist. Blind spot: slip pairs
with :math:`\lambda_1 \Delta N_1 \approx \lambda_2 \Delta N_2` (e.g. 9 and 7 cycles on GPS
L1/L2, 0.6 cm); combine with a Melbourne-Wübbena or Doppler test where that matters.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from robustrtk.core import BoolArray, FloatArray
from robustrtk.cycleslip._series import as_series, previous_valid_index


def gf_jump_m(
    t_s: npt.ArrayLike,
    phase1_cyc: npt.ArrayLike,
    phase2_cyc: npt.ArrayLike,
    lam1_m: npt.ArrayLike,
    lam2_m: npt.ArrayLike,
) -> tuple[FloatArray, FloatArray]:
    """Epoch-to-epoch change of the geometry-free combination.

    Parameters
    ----------
    t_s : array_like, shape (T,)
        Strictly increasing epoch times (s).
    phase1_cyc, phase2_cyc : array_like, shape (T, N) or (T,)
        Phases on the two frequencies (cycles), NaN where absent.
    lam1_m, lam2_m : float or array_like broadcastable to (N,)
        Wavelengths (m), per transmitter where they differ (GLONASS FDMA).

    Returns
    -------
    dgf_m : ndarray, shape (T, N)
        :math:`L_{GF}(t) - L_{GF}(t_{prev})` (m); NaN at the first valid epoch of each
        series and where either phase is absent.
    dt_s : ndarray, shape (T, N)
        :math:`t - t_{prev}` (s); NaN where ``dgf_m`` is NaN.
    """
    t, (p1, p2) = as_series(t_s, phase1_cyc, phase2_cyc)
    gf = np.asarray(lam1_m, dtype=float) * p1 - np.asarray(lam2_m, dtype=float) * p2
    valid = np.isfinite(gf)
    prev = previous_valid_index(valid)
    has = valid & (prev >= 0)
    cols = np.broadcast_to(np.arange(gf.shape[1]), gf.shape)
    pi = np.where(has, prev, 0)
    dgf = np.where(has, gf - gf[pi, cols], np.nan)
    dt = np.where(has, t[:, None] - t[pi], np.nan)
    return dgf, dt


def gf_slips(
    t_s: npt.ArrayLike,
    phase1_cyc: npt.ArrayLike,
    phase2_cyc: npt.ArrayLike,
    lam1_m: npt.ArrayLike,
    lam2_m: npt.ArrayLike,
    threshold_m: float = 0.05,
    max_gap_s: float = np.inf,
) -> BoolArray:
    """Geometry-free slip mask.

    Parameters
    ----------
    t_s, phase1_cyc, phase2_cyc, lam1_m, lam2_m
        As in :func:`gf_jump_m`.
    threshold_m : float
        Largest accepted change of :math:`L_{GF}` between compared epochs (m). The default
        0.05 m tolerates the ionospheric rate at 1 Hz to a few tens of seconds.
    max_gap_s : float
        An epoch whose previous valid epoch is older than this is flagged as a slip
        (continuity unverifiable).

    Returns
    -------
    slip : ndarray of bool, shape (T, N)
        True where ``|dgf_m| > threshold_m`` or the gap exceeds ``max_gap_s``; False at
        the first epoch of each series and where either phase is absent.
    """
    dgf, dt = gf_jump_m(t_s, phase1_cyc, phase2_cyc, lam1_m, lam2_m)
    with np.errstate(invalid="ignore"):
        return (np.abs(dgf) > threshold_m) | (dt > max_gap_s)


def gf_drift_slips(
    t_s: npt.ArrayLike,
    phase1_cyc: npt.ArrayLike,
    phase2_cyc: npt.ArrayLike,
    lam1_m: npt.ArrayLike,
    lam2_m: npt.ArrayLike,
    lli1: npt.ArrayLike,
    lli2: npt.ArrayLike,
    window_s: float = 10.0,
    threshold_m: float = 0.08,
) -> BoolArray:
    r"""Slow phase inconsistency on one frequency: the geometry-free change over a window.

    A phase that drifts against the other frequency (an accumulated-delta-range fault of a
    phone: a few cm/s, no flag) moves :math:`L_{GF}` by less than the epoch-to-epoch
    threshold of :func:`gf_slips` at every epoch, but by the drift times the window over
    ``window_s``; the ionosphere moves it by millimetres in ten seconds. Within an arc
    (both phases present at every epoch, no loss-of-lock bit on either), an epoch is
    flagged when

    .. math:: |L_{GF}(t) - L_{GF}(t_0)| > \text{threshold\_m},\quad
              t_0 = \text{the first arc epoch at or after } t - \text{window\_s}

    (algorithms.md § 24). Flags continue while the drift lasts; the caller decides what a
    flag does (the RTK defers the reset to the robust filter's verdict).

    Parameters
    ----------
    t_s : array_like, shape (T,)
    phase1_cyc, phase2_cyc : array_like, shape (T, N)
    lam1_m, lam2_m : float or array_like broadcastable to (N,)
    lli1, lli2 : array_like of int, shape (T, N)
        Loss-of-lock indicators (bit 0 starts a new arc).
    window_s, threshold_m : float

    Returns
    -------
    ndarray of bool, shape (T, N)
    """
    t, (p1, p2) = as_series(t_s, phase1_cyc, phase2_cyc)
    gf = np.asarray(lam1_m, dtype=float) * p1 - np.asarray(lam2_m, dtype=float) * p2
    lost = ((np.asarray(lli1).astype(np.int64) | np.asarray(lli2).astype(np.int64)) & 1) != 0
    T, N = gf.shape
    out = np.zeros((T, N), dtype=bool)
    for n in range(N):
        start = -1  # first epoch of the current arc
        for i in range(T):
            if not np.isfinite(gf[i, n]):
                start = -1
                continue
            if start < 0 or lost[i, n]:
                start = i
                continue
            j = max(start, int(np.searchsorted(t, t[i] - window_s - 1e-6)))
            if j < i and abs(gf[i, n] - gf[j, n]) > threshold_m:
                out[i, n] = True
    return out
