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
