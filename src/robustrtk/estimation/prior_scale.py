"""Scaling of the predicted covariance before a measurement update (the adaptive-factor hook).

A filter update accepts ``prior_scale``, applied to the prior covariance ``P̄`` before the
measurement model is linearised (so the UKF draws its sigma points and ``Pxy`` from the
scaled covariance, and the robust policy runs on the scaled prior):

* ``None`` — no scaling (the update is bit-identical to the plain one);
* a float ``s > 0`` — ``P̄ ← s P̄``;
* a vector ``g`` of shape (n,), ``gᵢ > 0`` — ``P̄ ← G P̄ G`` with ``G = diag(√g)``, which keeps
  the correlation coefficients (algorithms.md §2 applied to the state);
* a matrix ``T`` of shape (n, n) — ``P̄ ← T P̄ Tᵀ`` (symmetrised);
* an object implementing :class:`PriorScale` — its :meth:`PriorScale.scale` is called with
  the nominal prior's innovation ``d = z − h(x̄)`` and covariance ``S`` and returns one of
  the three forms above.

Yang's adaptive factor α (algorithms.md §5) inflates the prior as ``P̄ ← P̄/α``, i.e. an
implementation returns ``1/α`` (a float, or a vector of per-component ``1/αᵢ``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from robustrtk.core import FloatArray
from robustrtk.estimation.state import GaussianState

#: A factor as applied: a positive float, an (n,) vector or an (n, n) matrix.
ScaleFactor = float | FloatArray


@runtime_checkable
class PriorScale(Protocol):
    """Decides the factor applied to the prior covariance of one measurement update."""

    def scale(
        self, state: GaussianState, innovation: FloatArray, innovation_cov: FloatArray, R: FloatArray
    ) -> ScaleFactor:
        """Factor for this update.

        Parameters
        ----------
        state : GaussianState
            The nominal (unscaled) prior ``(x̄, P̄)``, n states.
        innovation : ndarray, shape (m,)
            ``d = z − h(x̄)`` of the nominal prior (UKF: ``z − ŷ``).
        innovation_cov : ndarray, shape (m, m)
            ``S = H P̄ Hᵀ + R`` of the nominal prior (UKF: ``Pyy``).
        R : ndarray, shape (m, m)
            Nominal measurement covariance.

        Returns
        -------
        float or ndarray
            ``s`` (``P̄ ← s P̄``), ``g`` of shape (n,) (``P̄ ← G P̄ G``, ``G = diag(√g)``) or
            ``T`` of shape (n, n) (``P̄ ← T P̄ Tᵀ``).
        """
        ...


PriorScaleLike = float | FloatArray | PriorScale


@dataclass(frozen=True)
class FixedPriorScale:
    """Reference :class:`PriorScale`: always the same factor, whatever the innovation.

    Parameters
    ----------
    factor : float or ndarray
        ``s``, ``g`` (n,) or ``T`` (n, n), see :func:`apply_prior_scale`. For Yang's
        α this is ``1/α``.
    """

    factor: float | FloatArray = 1.0

    def scale(
        self, state: GaussianState, innovation: FloatArray, innovation_cov: FloatArray, R: FloatArray
    ) -> ScaleFactor:
        """Return :attr:`factor` (the arguments are not used)."""
        return self.factor


def normalize_factor(factor: ScaleFactor | list[float] | tuple[float, ...], n: int) -> ScaleFactor:
    """Check a factor against the state size and return it as float or float64 array.

    Parameters
    ----------
    factor : float, array_like (n,) or (n, n)
    n : int
        State size.

    Returns
    -------
    float or ndarray
        A 0-d input becomes a float.

    Raises
    ------
    ValueError
        Wrong shape, non-finite, or not positive (float/vector).
    """
    a = np.asarray(factor, dtype=np.float64)
    if a.ndim == 0:
        s = float(a)
        if not (np.isfinite(s) and s > 0.0):
            raise ValueError(f"prior scale must be a finite positive number, got {s}")
        return s
    if a.ndim == 1:
        if a.shape != (n,):
            raise ValueError(f"prior scale vector has shape {a.shape}, expected ({n},)")
        if not (np.all(np.isfinite(a)) and np.all(a > 0.0)):
            raise ValueError("prior scale vector must be finite and positive")
        return a
    if a.shape != (n, n):
        raise ValueError(f"prior scale matrix has shape {a.shape}, expected ({n}, {n})")
    if not np.all(np.isfinite(a)):
        raise ValueError("prior scale matrix must be finite")
    return a


def apply_prior_scale(P: FloatArray, factor: ScaleFactor) -> FloatArray:
    """Scaled prior covariance.

    Parameters
    ----------
    P : ndarray, shape (n, n)
        Prior covariance ``P̄``.
    factor : float or ndarray
        Normalised factor (see :func:`normalize_factor`).

    Returns
    -------
    ndarray, shape (n, n)
        ``s P̄`` (float), ``G P̄ G`` with ``G = diag(√g)`` (vector, elementwise
        ``P̄ᵢⱼ √(gᵢ gⱼ)``), or ``(T P̄ Tᵀ + (T P̄ Tᵀ)ᵀ)/2`` (matrix).
    """
    if isinstance(factor, float):
        return factor * P
    if factor.ndim == 1:
        r = np.sqrt(factor)
        return P * np.outer(r, r)
    M = factor @ P @ factor.T
    return 0.5 * (M + M.T)


__all__ = [
    "FixedPriorScale",
    "PriorScale",
    "PriorScaleLike",
    "ScaleFactor",
    "apply_prior_scale",
    "normalize_factor",
]
