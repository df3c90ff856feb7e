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
