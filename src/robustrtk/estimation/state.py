"""Estimator states with a named layout, and the result of a measurement update.

A :class:`StateLayout` maps names to slices (``"pos"``, ``"vel"``, ``"clk"``) and keeps an
ordered list of ambiguity keys (``("PL4", "L1")`` or ``("G05", "1C")``) appended after the
fixed block, so ambiguity states can be added and dropped by key.

The :class:`State` protocol lists what the engine and the ambiguity code need from a state:
a Gaussian summary (``x``, ``P``), the layout and time, block access (``get``, ``cov``) and
the state operations — add/drop ambiguities, a linear transform (re-referencing DD
ambiguities), the conditional update on fixed values (integer fixing) and a hard-ish
constraint by pseudo-observations (fix-and-hold). :class:`GaussianState` implements them
exactly; a non-Gaussian state (particles) implements the same methods its own way.

States are immutable: every operation returns a new state.
"""

from __future__ import annotations

from collections.abc import Hashable, Sequence
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Protocol, Self, runtime_checkable

import numpy as np
import numpy.typing as npt

from robustrtk.core import FloatArray
from robustrtk.estimation.gaussian import condition_on, linear_transform, pseudo_observation_update


@dataclass(frozen=True)
class StateLayout:
    """Names of the state components.

    Attributes
    ----------
    blocks : tuple of (name, size)
        Fixed blocks in order, e.g. ``(("pos", 3), ("vel", 3))``.
    amb_keys : tuple of hashable
        Keys of the ambiguity states, stored after the fixed blocks in this order.
    """

    blocks: tuple[tuple[str, int], ...] = (("pos", 3),)
    amb_keys: tuple[Hashable, ...] = ()

    @cached_property
    def n_fixed(self) -> int:
        """Size of the fixed blocks (the first ambiguity's index)."""
        return sum(n for _, n in self.blocks)

    @property
    def size(self) -> int:
        return self.n_fixed + len(self.amb_keys)

    def slice(self, name: str) -> slice:
        """Slice of the fixed block ``name`` (``KeyError`` when absent)."""
        start = 0
        for b, n in self.blocks:
            if b == name:
                return slice(start, start + n)
            start += n
        raise KeyError(name)

    def has(self, name: str) -> bool:
        return any(b == name for b, _ in self.blocks)

    @cached_property
    def _amb_pos(self) -> dict[Hashable, int]:
        """Position of each ambiguity key in ``amb_keys`` (the first, for a repeated key)."""
        return {k: i for i, k in reversed(list(enumerate(self.amb_keys)))}

    def amb_index(self, key: Hashable) -> int:
        """State index of the ambiguity ``key`` (``ValueError`` when absent)."""
        i = self._amb_pos.get(key)
        if i is None:
            raise ValueError(f"{key!r} is not an ambiguity of the layout")
        return self.n_fixed + i

    def amb_indices(self, keys: Sequence[Hashable] | None = None) -> np.ndarray:
        """State indices of ``keys`` (all ambiguities by default): :meth:`amb_index` of each
        (``ValueError`` for the first one absent), without a call per key (an RTK epoch asks
        for a few dozen keys several times)."""
        pos = self._amb_pos
        n = self.n_fixed
        if keys is None:
            keys = self.amb_keys
            if len(pos) == len(keys):  # distinct keys: each one's index is its own place
                return np.arange(n, n + len(keys), dtype=int)
        found = [pos.get(k) for k in keys]
        if None in found:
            self.amb_index(keys[found.index(None)])  # raises the ValueError of the first absent key
        return np.array([n + i for i in found], dtype=int)  # type: ignore[operator]


@runtime_checkable
class State(Protocol):
    """What the engine needs from an estimator state (every operation returns a new one).

    Attributes
    ----------
    x : ndarray, shape (n,)
        Mean (the Gaussian summary of a non-Gaussian state).
    P : ndarray, shape (n, n)
        Covariance (ditto).
    t_s : float
        Time of validity (s).
    layout : StateLayout
        Names of the components; ``layout.size == n``.
    """

    @property
    def x(self) -> FloatArray: ...

    @property
    def P(self) -> FloatArray: ...

    @property
    def t_s(self) -> float: ...

    @property
    def layout(self) -> StateLayout: ...

    @property
    def n(self) -> int:
        """Number of state components."""
        ...

    def get(self, name: str) -> FloatArray:
        """Mean of the fixed block ``name``."""
        ...

    def cov(self, name: str) -> FloatArray:
        """Covariance of the fixed block ``name``."""
        ...

    def with_(self, **kw: object) -> Self:
        """Copy with fields replaced."""
        ...

    def add_ambiguities(self, keys: Sequence[Hashable], values: FloatArray, var: float | FloatArray) -> Self:
        """Append uncorrelated ambiguity states."""
        ...

    def drop_ambiguities(self, keys: Sequence[Hashable]) -> Self:
        """Marginalise ambiguity states out."""
        ...

    def transform(self, T: npt.ArrayLike, layout: StateLayout | None = None) -> Self:
        """Linear map of the state, ``x ← T x``."""
        ...

    def conditional_update(self, idx: npt.ArrayLike, values: npt.ArrayLike) -> Self:
        """Condition on ``x[idx] = values`` exactly."""
        ...

    def constrain(self, idx: npt.ArrayLike, values: npt.ArrayLike, sigma: float | npt.ArrayLike) -> Self:
        """Update with the pseudo-observations ``x[idx] = values ± sigma``."""
        ...


#: The fields of :class:`GaussianState` (:meth:`GaussianState.with_` replaces these).
_STATE_FIELDS = frozenset({"x", "P", "t_s", "layout"})


@dataclass(frozen=True)
class GaussianState:
    """Mean and covariance with a layout.

    Attributes
    ----------
    x : ndarray, shape (n,)
    P : ndarray, shape (n, n)
    t_s : float
        Time of validity (s).
    layout : StateLayout
    """

    x: FloatArray
    P: FloatArray
    t_s: float = 0.0
    layout: StateLayout = field(default_factory=StateLayout)

    @property
    def n(self) -> int:
        return int(self.x.shape[0])

    def get(self, name: str) -> FloatArray:
        return self.x[self.layout.slice(name)]

    def cov(self, name: str) -> FloatArray:
        s = self.layout.slice(name)
        return self.P[s, s]

    def with_(self, **kw: object) -> GaussianState:
        # dataclasses.replace's result, without its generic field walk (several calls per epoch)
        if not kw.keys() <= _STATE_FIELDS:
            raise TypeError(f"with_: unknown fields {sorted(kw.keys() - _STATE_FIELDS)}")
        return type(self)(
            kw.get("x", self.x),  # type: ignore[arg-type]
            kw.get("P", self.P),  # type: ignore[arg-type]
            kw.get("t_s", self.t_s),  # type: ignore[arg-type]
            kw.get("layout", self.layout),  # type: ignore[arg-type]
        )

    def add_ambiguities(
        self, keys: Sequence[Hashable], values: FloatArray, var: float | FloatArray
    ) -> GaussianState:
        """Append ambiguity states ``keys`` with means ``values`` and variances ``var``
        (uncorrelated with the rest)."""
        keys = [k for k in keys]
        if not keys:
            return self
        m = len(keys)
        n = self.n
        x = np.concatenate([self.x, np.asarray(values, float).reshape(m)])
        P = np.zeros((n + m, n + m))
        P[:n, :n] = self.P
        P[n:, n:] = np.diag(np.broadcast_to(np.asarray(var, float), (m,)))
        layout = replace(self.layout, amb_keys=self.layout.amb_keys + tuple(keys))
        return self.with_(x=x, P=P, layout=layout)

    def drop_ambiguities(self, keys: Sequence[Hashable]) -> GaussianState:
        """Remove the ambiguity states ``keys`` (marginalisation: drop rows/columns)."""
        drop = set(keys)
        if not drop:
            return self
        keep_keys = tuple(k for k in self.layout.amb_keys if k not in drop)
        nf = self.layout.n_fixed
        idx = np.concatenate([np.arange(nf), [self.layout.amb_index(k) for k in keep_keys]]).astype(int)
        layout = replace(self.layout, amb_keys=keep_keys)
        return self.with_(x=self.x[idx], P=self.P[np.ix_(idx, idx)], layout=layout)

    def transform(self, T: npt.ArrayLike, layout: StateLayout | None = None) -> GaussianState:
        """Linear map of the state (e.g. re-referencing DD ambiguities).

        Parameters
        ----------
        T : array_like, shape (k, n)
            The map; ``k = layout.size``.
        layout : StateLayout, optional
            Layout of the result (default: this state's, then ``k`` must equal ``n``).

        Returns
        -------
        GaussianState
            ``x ← T x``, ``P ← (T P Tᵀ + (T P Tᵀ)ᵀ)/2``, same ``t_s``.
        """
        lay = self.layout if layout is None else layout
        x, P = linear_transform(T, self.x, self.P)
        if x.shape[0] != lay.size:
            raise ValueError(f"T maps to {x.shape[0]} states but the layout has {lay.size}")
        return self.with_(x=x, P=P, layout=lay)

    def conditional_update(self, idx: npt.ArrayLike, values: npt.ArrayLike) -> GaussianState:
        """Condition on ``x[idx] = values`` exactly (integer ambiguity fixing).

        Parameters
        ----------
        idx : array_like of int, shape (m,)
            State indices (distinct) of the fixed components.
        values : array_like, shape (m,)
            Their values.

        Returns
        -------
        GaussianState
            ``x ← x − P[:, f] P[f, f]⁻¹ (x[f] − values)``,
            ``P ← P − P[:, f] P[f, f]⁻¹ P[f, :]`` (rows/columns ``f`` zero), see
            :func:`robustrtk.estimation.gaussian.condition_on`.
        """
        x, P = condition_on(self.x, self.P, idx, values)
        return self.with_(x=x, P=P)

    def constrain(
        self, idx: npt.ArrayLike, values: npt.ArrayLike, sigma: float | npt.ArrayLike
    ) -> GaussianState:
        """Fix-and-hold: linear Kalman update with pseudo-observations ``x[idx] = values``.

        Parameters
        ----------
        idx : array_like of int, shape (m,)
            Constrained state indices.
        values : array_like, shape (m,)
            Observed values.
        sigma : float or array_like, shape (m,)
            Their standard deviation (state units, e.g. cycles).

        Returns
        -------
        GaussianState
            Joseph-form update with ``H = I[idx]``, ``R = σ² I``, bit-identical to
            ``EKF().update(state, LinearMeasurement(H, values, R)).state`` (see
            :func:`robustrtk.estimation.gaussian.pseudo_observation_update`).
        """
        x, P = pseudo_observation_update(self.x, self.P, idx, values, sigma)
        return self.with_(x=x, P=P)


@dataclass(frozen=True)
class UpdateResult:
    """Outcome of one measurement update, with the diagnostics the paper plots.

    Attributes
    ----------
    state : GaussianState
        Posterior state.
    innovation : ndarray, shape (m,)
        ``d = z - h(x̄)`` (pre-fit residuals).
    innovation_cov : ndarray, shape (m, m)
        ``S = H P̄ Hᵀ + R`` (or the unscented ``Pyy``) with the nominal R and the prior
        covariance after any prior scaling.
    residual : ndarray, shape (m,)
        Post-fit residuals ``v = z - h(x̂)`` of the final (possibly robust) update.
    residual_cov : ndarray, shape (m, m)
        ``Cvv = R - H P⁺ Hᵀ`` of the nominal (first, non-robust) update.
    std_residual : ndarray, shape (m,)
        Standardized residuals ``v̄ = v / sqrt(diag Cvv)`` used by the robust policy.
    dv : ndarray, shape (m,)
        Error-discriminant statistic Δv̄ (Li et al. eq. 13); NaN when not computed.
    factors : ndarray, shape (m,)
        Variance inflation factors γ finally applied (1 none, inf rejected).
    situation : ndarray of int, shape (m,)
        Per-row situation class: 1 none, 2 down-weighted, 3 rejected (Li et al. Table 1).
    n_used : int
        Rows with finite factor.
    iterations : int
        Number of measurement updates performed.
    prior_scale : float or ndarray or None
        Factor applied to the prior covariance (``s``, ``g`` (n,) or ``T`` (n, n)); None
        when the prior was not scaled.
    """

    state: GaussianState
    innovation: FloatArray
    innovation_cov: FloatArray
    residual: FloatArray
    residual_cov: FloatArray
    std_residual: FloatArray
    dv: FloatArray
    factors: FloatArray
    situation: np.ndarray
    n_used: int
    iterations: int = 1
    prior_scale: float | FloatArray | None = None
