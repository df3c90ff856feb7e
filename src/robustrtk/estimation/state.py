"""Gaussian state with a named layout, and the result of a measurement update.

A :class:`StateLayout` maps names to slices (``"pos"``, ``"vel"``, ``"clk"``) and keeps an
ordered list of ambiguity keys (``("PL4", "L1")`` or ``("G05", "1C")``) appended after the
fixed block, so ambiguity states can be added and dropped by key. States are immutable:
every operation returns a new :class:`GaussianState`.
"""

from __future__ import annotations

from collections.abc import Hashable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from robustrtk.core import FloatArray


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

    @property
    def n_fixed(self) -> int:
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

    def amb_index(self, key: Hashable) -> int:
        """State index of the ambiguity ``key``."""
        return self.n_fixed + self.amb_keys.index(key)

    def amb_indices(self, keys: Sequence[Hashable] | None = None) -> np.ndarray:
        """State indices of ``keys`` (all ambiguities by default)."""
        keys = self.amb_keys if keys is None else keys
        return np.array([self.amb_index(k) for k in keys], dtype=int)


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
        return replace(self, **kw)  # type: ignore[arg-type]

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
        return replace(self, x=x, P=P, layout=layout)

    def drop_ambiguities(self, keys: Sequence[Hashable]) -> GaussianState:
        """Remove the ambiguity states ``keys`` (marginalisation: drop rows/columns)."""
        drop = set(keys)
        if not drop:
            return self
        keep_keys = tuple(k for k in self.layout.amb_keys if k not in drop)
        nf = self.layout.n_fixed
        idx = np.concatenate([np.arange(nf), [self.layout.amb_index(k) for k in keep_keys]]).astype(int)
        layout = replace(self.layout, amb_keys=keep_keys)
        return replace(self, x=self.x[idx], P=self.P[np.ix_(idx, idx)], layout=layout)


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
