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

Layout changes
--------------
Between epochs the filter may drop ambiguity states, predict, and add new ones (and
re-reference DD ambiguities, a linear map ``T``). The transition from the previous
posterior's layout to the next prior's layout is then the linear map built by
:func:`layout_transition` from the two :class:`~robustrtk.estimation.state.StateLayout`
objects and the fixed-block part of the process model's ``F`` (ambiguities are matched by
key: kept ones map with 1, new ones get a zero row, dropped ones have no row); compose it
with ``T`` on the left when re-referencing (``F = T · layout_transition(prev, before_T)``).
:meth:`FilterStep.from_states` records a step from the states themselves.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from robustrtk.core import FloatArray
from robustrtk.estimation.state import GaussianState, StateLayout


def layout_transition(
    prev_layout: StateLayout, next_layout: StateLayout, F_fixed: npt.ArrayLike | None = None
) -> FloatArray:
    """Linear map from a posterior with ``prev_layout`` to the next prior with ``next_layout``.

    Parameters
    ----------
    prev_layout : StateLayout
        Layout of the previous posterior (``n0 = prev_layout.size`` states).
    next_layout : StateLayout
        Layout of the next prior (``n1 = next_layout.size`` states).
    F_fixed : array_like, shape (next_layout.n_fixed, prev_layout.n_fixed), optional
        Transition of the fixed blocks (``F[:nf, :nf]`` of the process model); the
        identity by default (then both layouts need the same fixed blocks).

    Returns
    -------
    F : ndarray, shape (n1, n0)
        ``F[:nf1, :nf0] = F_fixed``; ``F[i1(key), i0(key)] = 1`` for every ambiguity key in
        both layouts (ambiguities are constant); a zero row for each key new in
        ``next_layout`` (a diffuse state with no predecessor: its initial value and
        variance are in the prior, not in ``F``); no row for a key only in
        ``prev_layout`` (dropped: its column is zero).

    Raises
    ------
    ValueError
        ``F_fixed`` has the wrong shape, or is omitted while the fixed blocks differ.
    """
    nf0, nf1 = prev_layout.n_fixed, next_layout.n_fixed
    if F_fixed is None:
        if prev_layout.blocks != next_layout.blocks:
            raise ValueError(
                f"fixed blocks differ ({prev_layout.blocks} → {next_layout.blocks}); pass F_fixed"
            )
        Ff = np.eye(nf1)
    else:
        Ff = np.asarray(F_fixed, dtype=np.float64)
        if Ff.shape != (nf1, nf0):
            raise ValueError(f"F_fixed has shape {Ff.shape}, expected ({nf1}, {nf0})")
    F = np.zeros((next_layout.size, prev_layout.size))
    F[:nf1, :nf0] = Ff
    prev_index = {k: nf0 + j for j, k in enumerate(prev_layout.amb_keys)}
    for j, key in enumerate(next_layout.amb_keys):
        i0 = prev_index.get(key)
        if i0 is not None:
            F[nf1 + j, i0] = 1.0
    return F


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
    layout : StateLayout or None
        Layout of this epoch's prior and posterior (optional, for the caller).
    """

    F: FloatArray | None
    x_prior: FloatArray
    P_prior: FloatArray
    x_post: FloatArray
    P_post: FloatArray
    layout: StateLayout | None = None

    @classmethod
    def from_states(
        cls,
        prior: GaussianState,
        post: GaussianState,
        prev_post: GaussianState | None = None,
        F_fixed: npt.ArrayLike | None = None,
        F: npt.ArrayLike | None = None,
    ) -> FilterStep:
        """Record an epoch from its prior and posterior states.

        Parameters
        ----------
        prior, post : GaussianState
            This epoch's prior and posterior (same layout, ``n_k`` states).
        prev_post : GaussianState, optional
            The previous posterior (``n_{k-1}`` states); None starts a new segment
            (``F = None``).
        F_fixed : array_like, optional
            Fixed-block transition, see :func:`layout_transition`.
        F : array_like, shape (n_k, n_{k-1}), optional
            The whole transition when it is more than a layout change, e.g.
            ``T · layout_transition(prev_post.layout, layout_before_T, F_fixed)`` when
            the prior was re-referenced by ``T``; default
            ``layout_transition(prev_post.layout, prior.layout, F_fixed)``.
        """
        if prior.layout != post.layout:
            raise ValueError("prior and posterior of one epoch must share the layout")
        Fk: FloatArray | None = None
        if prev_post is not None:
            if F is None:
                Fk = layout_transition(prev_post.layout, prior.layout, F_fixed)
            else:
                Fk = np.asarray(F, dtype=np.float64)
                if Fk.shape != (prior.n, prev_post.n):
                    raise ValueError(f"F has shape {Fk.shape}, expected ({prior.n}, {prev_post.n})")
        return cls(Fk, prior.x, prior.P, post.x, post.P, prior.layout)


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
            if F.shape != (following.x_prior.shape[0], s.x_post.shape[0]):
                raise ValueError(
                    f"steps[{k + 1}].F has shape {F.shape}, expected "
                    f"({following.x_prior.shape[0]}, {s.x_post.shape[0]})"
                )
            C = _gain(s.P_post, F, following.P_prior)
            x = s.x_post + C @ (nxt[0] - following.x_prior)
            P = s.P_post + C @ (nxt[1] - following.P_prior) @ C.T
            cur = (x, 0.5 * (P + P.T))
        out[k] = cur
        nxt = cur
    return out


__all__ = ["FilterStep", "layout_transition", "rts_smooth"]
