"""Rauch–Tung–Striebel (RTS) fixed-interval smoother for a filter whose state may change size.

The forward filter records, for each epoch ``k``, the transition that produced its prior,
``x̄_k = F_k x̂_{k−1} + u_k``, ``P̄_k = F_k P̂_{k−1} F_kᵀ + Q_k`` (``F_k`` of shape
``(n_k, n_{k−1})``: states added at ``k`` have a zero row and their initial value in
``u_k``; states dropped at ``k`` have no row), the prior ``(x̄_k, P̄_k)`` and the posterior
``(x̂_k, P̂_k)``. The backward pass (Rauch, Tung and Striebel 1965)::

    C_k = P̂_k F_{k+1}ᵀ P̄_{k+1}⁻¹
    x̃_k = x̂_k + C_k (x̃_{k+1} − x̄_{k+1})
    P̃_k = P̂_k + C_k (P̃_{k+1} − P̄_{k+1}) C_kᵀ

starts from ``x̃_K = x̂_K`` and holds for rectangular ``F`` because the derivation only
needs the joint Gaussian of ``(x_k, x_{k+1})`` given the data up to ``k``. A state added
at ``k+1`` (zero row of ``F``) receives nothing from the past and gives nothing back
through the zero row; a state dropped at ``k+1`` is smoothed by its correlation with the
states that survive.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from robustrtk.core import FloatArray


@dataclass(frozen=True)
class FilterStep:
    """What the forward filter stores for one epoch.

    Attributes
    ----------
    F : ndarray, shape (n_k, n_{k-1}) or None
        Transition from the previous posterior to this prior; None at the first epoch of
        a segment (the smoother does not cross it).
    x_prior, P_prior : ndarray, shapes (n_k,), (n_k, n_k)
    x_post, P_post : ndarray, shapes (n_k,), (n_k, n_k)
    """

    F: FloatArray | None
    x_prior: FloatArray
    P_prior: FloatArray
    x_post: FloatArray
    P_post: FloatArray


def _gain(P_post: FloatArray, F: FloatArray, P_prior_next: FloatArray) -> FloatArray:
    """``C = P̂ Fᵀ P̄⁻¹`` by a symmetric solve (least squares if ``P̄`` is singular)."""
    A = F @ P_post  # (n1, n0) = (P̂ Fᵀ)ᵀ
    try:
        return np.linalg.solve(P_prior_next, A).T
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(P_prior_next, A, rcond=None)[0].T


def rts_smooth(steps: Sequence[FilterStep]) -> list[tuple[FloatArray, FloatArray]]:
    """Smoothed means and covariances of a chain of filter steps.

    Parameters
    ----------
    steps : sequence of FilterStep, length K
        Forward-filter records in time order. ``steps[k].F`` links ``k−1`` to ``k``; where it
        is None a new segment starts and nothing is propagated across.

    Returns
    -------
    list of (x, P), length K
        Smoothed mean (n_k,) and covariance (n_k, n_k) per epoch.
    """
    K = len(steps)
    out: list[tuple[FloatArray, FloatArray]] = [(np.empty(0), np.empty((0, 0)))] * K
    nxt: tuple[FloatArray, FloatArray] | None = None
    for k in range(K - 1, -1, -1):
        s = steps[k]
        following = steps[k + 1] if k + 1 < K else None
        if nxt is None or following is None or following.F is None:
            cur = (s.x_post.copy(), s.P_post.copy())
        else:
            F = following.F
            C = _gain(s.P_post, F, following.P_prior)
            x = s.x_post + C @ (nxt[0] - following.x_prior)
            P = s.P_post + C @ (nxt[1] - following.P_prior) @ C.T
            cur = (x, 0.5 * (P + P.T))
        out[k] = cur
        nxt = cur
    return out


__all__ = ["FilterStep", "rts_smooth"]
