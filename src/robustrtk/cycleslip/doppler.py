r"""Doppler-minus-phase cycle-slip detector.

Sign convention (RINEX 3, section "Basic definitions"): the carrier phase "changes in the
same sense as the range (negative doppler)" and the Doppler shift is "positive for
approaching satellites". Hence the phase rate is the negated Doppler,

.. math:: \dot\varphi = -D,

and the phase change between two epochs is predicted with the trapezoidal rule

.. math::

    \Delta\hat\varphi = s \, \frac{D(t_{prev}) + D(t)}{2} (t - t_{prev}), \qquad s = -1,

a slip being declared when :math:`|\Delta\varphi - \Delta\hat\varphi| >` ``threshold_cyc``.
Receiver clock drift enters phase and Doppler alike and cancels. The test is per receiver
and per signal (no differencing needed); its sensitivity is limited by Doppler noise and
by acceleration over the interval (the trapezoid is exact for constant acceleration).
For data in another convention (phase counting with the Doppler) pass ``sign=+1``.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from robustrtk.core import BoolArray, FloatArray
from robustrtk.cycleslip._series import as_series, previous_valid_index


def doppler_phase_residual_cyc(
    t_s: npt.ArrayLike,
    phase_cyc: npt.ArrayLike,
    doppler_hz: npt.ArrayLike,
    sign: float = -1.0,
) -> FloatArray:
    """Observed minus Doppler-predicted phase change since the previous valid epoch.

    Parameters
    ----------
    t_s : array_like, shape (T,)
        Strictly increasing epoch times (s).
    phase_cyc : array_like, shape (T, N) or (T,)
        Carrier phase (cycles), NaN where absent.
    doppler_hz : array_like, same shape
        Doppler (Hz), NaN where absent. Where only one of the two epochs has a Doppler
        value, that one is used alone (rectangle rule).
    sign : float
        Phase rate = ``sign * Doppler``; -1 for RINEX.

    Returns
    -------
    resid_cyc : ndarray, shape (T, N)
        NaN at the first valid phase of each series, where the phase is absent, or where
        neither epoch has a Doppler.
    """
    t, (ph, dop) = as_series(t_s, phase_cyc, doppler_hz)
    valid = np.isfinite(ph)
    prev = previous_valid_index(valid)
    has = valid & (prev >= 0)
    cols = np.broadcast_to(np.arange(ph.shape[1]), ph.shape)
    pi = np.where(has, prev, 0)
    dt = t[:, None] - t[pi]
    d0 = dop[pi, cols]
    d1 = dop
    dmean = np.where(
        np.isfinite(d0) & np.isfinite(d1),
        0.5 * (d0 + d1),
        np.where(np.isfinite(d0), d0, d1),
    )
    pred = sign * dmean * dt
    return np.where(has, (ph - ph[pi, cols]) - pred, np.nan)


def doppler_phase_slips(
    t_s: npt.ArrayLike,
    phase_cyc: npt.ArrayLike,
    doppler_hz: npt.ArrayLike,
    threshold_cyc: float = 0.5,
    sign: float = -1.0,
) -> BoolArray:
    """Doppler-minus-phase slip mask.

    Parameters
    ----------
    t_s, phase_cyc, doppler_hz, sign
        As in :func:`doppler_phase_residual_cyc`.
    threshold_cyc : float
        Largest accepted |observed - predicted| phase change (cycles). It must stay
        below 1 cycle minus the residual's spread for 1-cycle slips to be seen: 0.5 suits
        geodetic receivers at 1 Hz with moderate dynamics; noisy (smartphone) Doppler or
        high jerk need more, at the price of missing small slips.

    Returns
    -------
    slip : ndarray of bool, shape (T, N)
        False where the residual is NaN.
    """
    r = doppler_phase_residual_cyc(t_s, phase_cyc, doppler_hz, sign)
    with np.errstate(invalid="ignore"):
        return np.abs(r) > threshold_cyc
