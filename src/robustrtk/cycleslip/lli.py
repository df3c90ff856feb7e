"""Loss-of-lock indicator (LLI) flags as slip masks.

RINEX LLI bits: bit 0 (value 1) = lost lock between the previous and this observation,
a cycle slip is possible; bit 1 (value 2) = half-cycle ambiguity / slip possible;
bit 2 (value 4, RINEX 2 only) = observing under anti-spoofing.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from robustrtk.core import BoolArray


def lli_slips(lli: npt.ArrayLike) -> BoolArray:
    """Cells whose loss-of-lock bit (bit 0) is set.

    Parameters
    ----------
    lli : array_like of int, any shape (e.g. ``(T, N, K)``)
        RINEX loss-of-lock indicators; 0 where absent.

    Returns
    -------
    slip : ndarray of bool, same shape
        ``(lli & 1) != 0``.
    """
    arr = np.asarray(lli).astype(np.int64)
    return (arr & 1) != 0


def half_cycle_flags(lli: npt.ArrayLike) -> BoolArray:
    """Cells whose half-cycle-ambiguity bit (bit 1) is set.

    Parameters
    ----------
    lli : array_like of int, any shape

    Returns
    -------
    half : ndarray of bool, same shape
        ``(lli & 2) != 0``: the phase may be off by half a cycle until the receiver
        resolves the navigation-bit polarity; such cells should not be used for integer
        ambiguity fixing.
    """
    arr = np.asarray(lli).astype(np.int64)
    return (arr & 2) != 0


def half_cycle_transitions(phase_cyc: npt.ArrayLike, lli: npt.ArrayLike) -> BoolArray:
    """Cells where the half-cycle bit (bit 1) differs from the series' previous phase.

    A receiver that resolves a half-cycle ambiguity corrects its phase by half a cycle and
    clears the bit (Android ``ADR_STATE_HALF_CYCLE_RESOLVED``); a bit that appears on a
    running arc means the tracking loop lost the polarity again. Either way the carrier
    phase jumps by 0.5 cycle with no loss-of-lock bit, so a filter that keeps the
    ambiguity would carry a half-cycle bias: the cell is a slip.

    Parameters
    ----------
    phase_cyc : array_like, shape (T, N)
        Carrier phase series (NaN where absent).
    lli : array_like of int, shape (T, N)

    Returns
    -------
    ndarray of bool, shape (T, N)
        True where a phase is present, an earlier phase of the same series exists and the
        bit differs from that of the most recent earlier phase.
    """
    ph = np.asarray(phase_cyc, float)
    half = half_cycle_flags(lli)
    out = np.zeros(ph.shape, dtype=bool)
    last = np.full(ph.shape[1:], -1, dtype=np.int8)  # -1: no phase yet
    for i in range(ph.shape[0]):
        ok = np.isfinite(ph[i])
        h = half[i].astype(np.int8)
        out[i] = ok & (last >= 0) & (last != h)
        last = np.where(ok, h, last)
    return out
