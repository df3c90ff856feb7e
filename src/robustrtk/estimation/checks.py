"""Input checks at the filters' entry points: covariances and time steps a filter refuses.

A negative or asymmetric measurement covariance ``R``, an asymmetric or indefinite prior
``P`` or a time step that is not a finite non-negative number would give a posterior that
is not a covariance (or a NaN state) without a word; :func:`check_covariance` and
:func:`check_dt` refuse them with a :class:`ValueError` naming the matrix. Non-finite
matrices are left to the filter, which marks such an update rejected as a whole.

The checks are cheap (an exact symmetry test and one Cholesky factorisation; the
tolerances are applied only when those fail): they run on every update.
"""

from __future__ import annotations

import math

import numpy as np

from robustrtk.core import FloatArray

#: Relative tolerance of the symmetry test, ``|A − Aᵀ| ≤ tol · max|A|``.
SYMMETRY_RTOL = 1e-8
#: Negative eigenvalues down to ``−tol · max diag`` are accepted (rounding in ``F P Fᵀ``).
PSD_RTOL = 1e-9


def check_covariance(A: FloatArray, name: str) -> None:
    """:class:`ValueError` unless ``A`` is square, symmetric and positive semi-definite
    within tolerance (a finite ``A`` only; non-finite ones are not judged here).

    Parameters
    ----------
    A : ndarray, shape (k, k)
        Covariance matrix.
    name : str
        Its name in the message (``"R"``, ``"prior P"``).
    """
    if A.ndim != 2 or A.shape[0] != A.shape[1]:
        raise ValueError(f"{name}: expected a square covariance matrix, got shape {A.shape}")
    k = A.shape[0]
    if k == 0:
        return
    if not (A == A.T).all():  # the filters' own P is symmetric to the bit: no tolerance needed
        scale = float(np.max(np.abs(A)))
        if not math.isfinite(scale):
            return
        if float(np.max(np.abs(A - A.T))) > SYMMETRY_RTOL * scale:
            raise ValueError(f"{name}: covariance matrix is not symmetric")
    diag = np.diagonal(A)
    dmin = float(diag.min())
    if not math.isfinite(dmin):
        return
    if dmin < 0.0:
        raise ValueError(f"{name}: negative variance on the diagonal ({dmin:.3g})")
    if dmin > 0.0 and _factorises(A):
        return  # positive definite: the usual case, one factorisation
    load = PSD_RTOL * max(float(np.max(diag)), np.finfo(float).tiny)
    if not _factorises(A + load * np.eye(k)):
        raise ValueError(f"{name}: covariance matrix is not positive semi-definite")


def _factorises(A: FloatArray) -> bool:
    try:
        np.linalg.cholesky(A)
    except np.linalg.LinAlgError:
        return False
    return True


def check_dt(dt_s: float) -> None:
    """:class:`ValueError` unless the prediction step ``dt_s`` is finite and ``>= 0``."""
    if not math.isfinite(dt_s) or dt_s < 0.0:
        raise ValueError(f"predict: time step must be finite and >= 0 s, got {dt_s!r}")


__all__ = ["PSD_RTOL", "SYMMETRY_RTOL", "check_covariance", "check_dt"]
