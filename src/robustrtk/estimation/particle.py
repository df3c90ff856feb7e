"""Particle filter (sequential importance resampling), Zhou et al. eqs. 20–23, algorithms.md §21.5.

The cloud ``{x_i, w_i}, i = 1..N`` is stored as ``particles (N, n)`` and normalised
log-weights ``log_w (N,)`` (eq. 22); its Gaussian summary is the weighted mean and
covariance (eq. 23 reduced to two moments), which is what a node outputs and broadcasts.

* **Prediction** (eq. 20): ``x_i ← F x_i + w_i``, ``w_i ~ N(0, Q)`` drawn with a seeded
  :class:`numpy.random.Generator`.
* **Correction** (eq. 21): ``log w_i += log N(z; h(x_i), R)`` (one Cholesky of ``R`` for
  the whole cloud), then normalisation by log-sum-exp.
* **Linear sub-state** (optional, ``linear_idx``): states that enter every row linearly
  with a constant coefficient matrix ``A`` (receiver clocks: ``h(x) = g(x_rest) + A x_lin``)
  get their process noise ``Q_lin`` in the correction instead, through the optimal
  proposal of a linear-Gaussian sub-state::

      S = R + A Q_lin Aᵀ,  log w_i += log N(z − h(x_i); 0, S),
      x_lin,i ← x_lin,i + K (z − h(x_i)) + η_i,   K = Q_lin Aᵀ S⁻¹,
      η_i ~ N(0, Q_lin − K A Q_lin)

  which is exact and keeps the cloud from collapsing when the clock random walk is far
  wider than the code noise.
* **Resampling**: systematic (one uniform draw) when the effective sample size
  ``ESS = 1 / Σ w_i²`` falls below ``ess_threshold · N``; afterwards every weight is ``1/N``
  and the cloud is **roughened**: ``x_ij += N(0, (k E_j N^(−1/d))²)`` with ``E_j`` the
  range of component ``j`` over the cloud and ``d`` the number of components roughened
  (Gordon, Salmond & Smith 1993).
"""

from __future__ import annotations

from collections.abc import Hashable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
import numpy.typing as npt

from robustrtk.core import FloatArray
from robustrtk.estimation.models import MeasurementModel, ProcessModel
from robustrtk.estimation.state import GaussianState, StateLayout


def normalize_log_weights(log_w: npt.ArrayLike) -> FloatArray:
    """``log w_i − log Σ_j exp(log w_j)`` (log-sum-exp, stable for very negative values).

    Parameters
    ----------
    log_w : array_like, shape (N,)
        Unnormalised log-weights; ``−inf`` allowed (zero weight), not all of them.

    Returns
    -------
    ndarray, shape (N,)
        Normalised log-weights (``Σ exp = 1``).
    """
    lw = np.asarray(log_w, float)
    mx = float(np.max(lw))
    if not np.isfinite(mx):
        raise ValueError("every particle has zero weight")
    out: FloatArray = lw - (mx + np.log(np.sum(np.exp(lw - mx))))
    return out


def effective_sample_size(log_w: npt.ArrayLike) -> float:
    """``ESS = 1 / Σ w_i²`` of normalised weights ``w = exp(log_w)``; ``1 ≤ ESS ≤ N``."""
    w = np.exp(normalize_log_weights(log_w))
    return float(1.0 / np.sum(w * w))


def systematic_resample(weights: npt.ArrayLike, rng: np.random.Generator) -> npt.NDArray[np.int64]:
    """Systematic resampling: indices ``i_k`` with ``C(i_k − 1) < (k + u)/N ≤ C(i_k)``.

    ``u ~ U[0, 1)`` is the only random draw and ``C`` the cumulative weights, so particle
    ``i`` is copied ``⌊N w_i⌋`` or ``⌈N w_i⌉`` times (unbiased: ``E[copies] = N w_i``).

    Parameters
    ----------
    weights : array_like, shape (N,)
        Non-negative, summing to 1 (normalised here against round-off).
    rng : numpy.random.Generator

    Returns
    -------
    ndarray of int, shape (N,)
        Indices into the cloud, non-decreasing.
    """
    w = np.asarray(weights, float)
    n = w.shape[0]
    c = np.cumsum(w)
    c /= c[-1]
    pos = (rng.random() + np.arange(n)) / n
    idx = np.searchsorted(c, pos, side="left")
    out: npt.NDArray[np.int64] = np.minimum(idx, n - 1).astype(np.int64)
    return out


def roughen(
    particles: FloatArray, rng: np.random.Generator, k: float = 0.2, idx: npt.ArrayLike | None = None
) -> FloatArray:
    """Roughening jitter ``x_ij += N(0, (k E_j N^(−1/d))²)`` on the components ``idx``.

    Parameters
    ----------
    particles : ndarray, shape (N, n)
    rng : numpy.random.Generator
    k : float
        Tuning constant (0.2 in Gordon et al.); 0 returns the cloud unchanged.
    idx : array_like of int, optional
        Components roughened (default all); ``d = len(idx)``.

    Returns
    -------
    ndarray, shape (N, n)
        A new array.
    """
    X = np.array(particles, float, copy=True)
    if k <= 0.0:
        return X
    cols = np.arange(X.shape[1]) if idx is None else np.asarray(idx, dtype=np.int64)
    if cols.size == 0:
        return X
    n = X.shape[0]
    E = np.ptp(X[:, cols], axis=0)
    sd = k * E * n ** (-1.0 / cols.size)
    X[:, cols] += rng.standard_normal((n, cols.size)) * sd
    return X


def _t(A: FloatArray) -> FloatArray:
    """``Aᵀ`` as a C-contiguous array: OpenBLAS multiplies a tall (N, m) block by a small
    transposed view hundreds of times slower than by a contiguous copy."""
    return np.ascontiguousarray(np.asarray(A).T)


def _sqrt_psd(Q: FloatArray) -> FloatArray:
    """``B`` with ``B Bᵀ = Q`` for a positive semi-definite ``Q`` (zero rows allowed)."""
    w, V = np.linalg.eigh(0.5 * (Q + Q.T))
    out: FloatArray = V * np.sqrt(np.clip(w, 0.0, None))
    return out


@dataclass(frozen=True)
class ParticleState:
    """A weighted particle cloud with a layout (immutable; operations return new states).

    Attributes
    ----------
    particles : ndarray, shape (N, n)
    log_w : ndarray, shape (N,)
        Normalised log-weights.
    t_s : float
        Time of validity (s).
    layout : StateLayout
    pending_var : ndarray, shape (n,)
        Process-noise variance of the linear sub-state predicted but not yet drawn (it is
        drawn in the next correction, see the module notes); zero elsewhere.
    """

    particles: FloatArray
    log_w: FloatArray
    t_s: float = 0.0
    layout: StateLayout = field(default_factory=StateLayout)
    pending_var: FloatArray | None = None

    @property
    def n(self) -> int:
        return int(self.particles.shape[1])

    @property
    def n_particles(self) -> int:
        return int(self.particles.shape[0])

    @property
    def weights(self) -> FloatArray:
        """``exp(log_w)`` (N,)."""
        out: FloatArray = np.exp(self.log_w)
        return out

    @property
    def x(self) -> FloatArray:
        """Weighted mean ``Σ w_i x_i`` (n,)."""
        out: FloatArray = self.weights @ self.particles
        return out

    @property
    def P(self) -> FloatArray:
        """Weighted covariance ``Σ w_i (x_i − x̄)(x_i − x̄)ᵀ`` plus ``diag(pending_var)`` (n, n)."""
        w = self.weights
        d = self.particles - w @ self.particles
        P = (d * w[:, None]).T @ d
        if self.pending_var is not None:
            P = P + np.diag(self.pending_var)
        out: FloatArray = 0.5 * (P + P.T)
        return out

    @property
    def ess(self) -> float:
        """Effective sample size ``1 / Σ w_i²``."""
        return effective_sample_size(self.log_w)

    def get(self, name: str) -> FloatArray:
        return self.x[self.layout.slice(name)]

    def cov(self, name: str) -> FloatArray:
        s = self.layout.slice(name)
        return self.P[s, s]

    def with_(self, **kw: object) -> ParticleState:
        return replace(self, **kw)  # type: ignore[arg-type]

    def summary(self) -> GaussianState:
        """The Gaussian summary ``N(x, P)`` with the same time and layout."""
        return GaussianState(self.x, self.P, self.t_s, self.layout)

    def add_ambiguities(
        self,
        keys: Sequence[Hashable],
        values: FloatArray,
        var: float | FloatArray,
        rng: np.random.Generator | None = None,
    ) -> ParticleState:
        """Append ambiguity components ``keys`` drawn independently of the rest.

        Each particle gets ``a_ij = values_j + √var_j ε_ij``, ``ε_ij ~ N(0, 1)``; the
        weights are kept, so the new components are uncorrelated with the others and their
        weighted moments tend to ``values`` and ``diag(var)`` (the particle counterpart of
        :meth:`GaussianState.add_ambiguities`).

        Parameters
        ----------
        keys : sequence of hashable, length m
            Keys appended to ``layout.amb_keys``.
        values : ndarray, shape (m,)
            Means (the ambiguity's unit, e.g. cycles).
        var : float or ndarray, shape (m,)
            Variances (unit²), ≥ 0.
        rng : numpy.random.Generator, optional
            Source of the draws. Default: a generator seeded from the cloud's size, its
            dimension, ``m`` and ``t_s``, so that a run repeats exactly.

        Returns
        -------
        ParticleState
            ``particles (N, n + m)``, the same ``log_w`` and ``t_s``.
        """
        keys = list(keys)
        if not keys:
            return self
        m = len(keys)
        mean = np.asarray(values, float).reshape(m)
        v = np.broadcast_to(np.asarray(var, float), (m,))
        if not (np.all(np.isfinite(mean)) and np.all(np.isfinite(v)) and np.all(v >= 0.0)):
            raise ValueError("ambiguity means must be finite and variances finite and ≥ 0")
        if rng is None:
            t_us = int(round(self.t_s * 1e6)) if np.isfinite(self.t_s) else 0
            rng = np.random.default_rng([self.n_particles, self.n, m, abs(t_us)])
        draws = mean + rng.standard_normal((self.n_particles, m)) * np.sqrt(v)
        pending = None if self.pending_var is None else np.concatenate([self.pending_var, np.zeros(m)])
        layout = replace(self.layout, amb_keys=self.layout.amb_keys + tuple(keys))
        return replace(self, particles=np.hstack([self.particles, draws]), layout=layout, pending_var=pending)

    def drop_ambiguities(self, keys: Sequence[Hashable]) -> ParticleState:
        """Remove the ambiguity components ``keys`` (marginalisation: the columns go, the
        weights stay, so the other components' weighted moments are unchanged).

        Parameters
        ----------
        keys : sequence of hashable
            Keys of ``layout.amb_keys``; keys the state does not hold are ignored.
        """
        drop = set(keys)
        if not drop:
            return self
        keep_keys = tuple(k for k in self.layout.amb_keys if k not in drop)
        nf = self.layout.n_fixed
        idx = np.concatenate([np.arange(nf), [self.layout.amb_index(k) for k in keep_keys]]).astype(np.int64)
        pending = None if self.pending_var is None else self.pending_var[idx]
        layout = replace(self.layout, amb_keys=keep_keys)
        return replace(self, particles=self.particles[:, idx], layout=layout, pending_var=pending)

    @classmethod
    def from_gaussian(cls, state: GaussianState, n_particles: int, rng: np.random.Generator) -> ParticleState:
        """``n_particles`` equally weighted draws from ``N(state.x, state.P)``."""
        B = _sqrt_psd(np.asarray(state.P, float))
        X = state.x + rng.standard_normal((n_particles, state.n)) @ _t(B)
        return cls(X, np.full(n_particles, -np.log(n_particles)), state.t_s, state.layout)


@dataclass(frozen=True)
class ParticleUpdate:
    """Outcome of one particle-filter correction.

    Attributes
    ----------
    state : ParticleState
        Posterior cloud (after any resampling and roughening).
    ess : float
        Effective sample size of the weights after the correction, before resampling.
    resampled : bool
    log_likelihood : float
        ``log p(z | z_1:t−1)`` estimated by ``log Σ w_i p(z | x_i)`` (the evidence).
    innovation : ndarray, shape (m,)
        ``z − E[h(x)]`` over the prior cloud.
    residual : ndarray, shape (m,)
        ``z − h(x̂)`` at the posterior mean.
    """

    state: ParticleState
    ess: float
    resampled: bool
    log_likelihood: float
    innovation: FloatArray
    residual: FloatArray


@dataclass
class ParticleFilter:
    """Bootstrap particle filter with an optional linear-Gaussian sub-state.

    Parameters
    ----------
    n_particles : int
        Cloud size ``N`` for :meth:`init`.
    ess_threshold : float
        Resample when ``ESS < ess_threshold · N`` (0 never, 1 every correction).
    roughening : float
        Roughening constant ``k`` after a resampling (0 off).
    seed : int
        Seed of the :class:`numpy.random.Generator` (one stream per filter object).
    linear_idx : tuple of int
        State indices of the linear sub-state (clocks); their process noise is drawn
        through the optimal proposal in :meth:`update` (module notes). Each measurement
        model's Jacobian columns for them must be constant.
    """

    n_particles: int = 2000
    ess_threshold: float = 0.5
    roughening: float = 0.2
    seed: int = 0
    linear_idx: tuple[int, ...] = ()
    name: str = "pf"
    rng: np.random.Generator = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if self.n_particles < 2:
            raise ValueError("n_particles must be at least 2")
        if not 0.0 <= self.ess_threshold <= 1.0:
            raise ValueError("ess_threshold must be in [0, 1]")
        self.rng = np.random.default_rng(self.seed)

    def init(self, state: GaussianState) -> ParticleState:
        """A cloud of :attr:`n_particles` draws from the Gaussian ``state``."""
        return ParticleState.from_gaussian(state, self.n_particles, self.rng)

    def predict(self, state: ParticleState, process: ProcessModel, t_s: float) -> ParticleState:
        """Eq. 20: ``x_i ← F x_i + w_i``, ``w_i ~ N(0, Q)`` (the linear sub-state's noise is
        deferred to the correction, accumulated in ``pending_var``)."""
        dt = t_s - state.t_s
        F, Q = process.transition(state.layout, dt)
        Q = np.array(Q, float, copy=True)
        pending = np.zeros(state.n) if state.pending_var is None else state.pending_var.copy()
        lin = np.asarray(self.linear_idx, dtype=np.int64)
        if lin.size:
            F_lin = F[np.ix_(lin, lin)]
            pending[lin] = np.diag(F_lin) ** 2 * pending[lin] + np.diag(Q)[lin]
            Q[lin, :] = 0.0
            Q[:, lin] = 0.0
        X = state.particles if np.array_equal(F, np.eye(F.shape[0])) else state.particles @ _t(F)
        nz = np.flatnonzero(np.diag(Q) > 0.0)  # draw only the components with noise
        if nz.size:
            B = _sqrt_psd(Q[np.ix_(nz, nz)])
            X = X.copy() if X is state.particles else X
            X[:, nz] += self.rng.standard_normal((X.shape[0], nz.size)) @ _t(B)
        return replace(state, particles=X, t_s=t_s, pending_var=pending if lin.size else None)

    def update(self, state: ParticleState, meas: MeasurementModel) -> ParticleUpdate:
        """Eq. 21–23: re-weight by the likelihood, resample under the ESS threshold, roughen.

        Parameters
        ----------
        state : ParticleState
            Prior cloud.
        meas : MeasurementModel
            ``z`` (m,), ``R`` (m, m), ``h`` evaluated on the whole cloud at once.

        Returns
        -------
        ParticleUpdate
        """
        z = np.asarray(meas.z, float)
        R = np.asarray(meas.R, float)
        X = state.particles
        w_prior = state.weights
        Y = meas.h(X)  # (N, m)
        innov = z - w_prior @ Y
        lin = np.asarray(self.linear_idx, dtype=np.int64)
        q_lin = None if state.pending_var is None or lin.size == 0 else state.pending_var[lin]
        S = R
        A = None
        if q_lin is not None and np.any(q_lin > 0):
            A = np.asarray(meas.jacobian(state.x), float)[:, lin]
            S = R + (A * q_lin) @ A.T
        L = np.linalg.cholesky(0.5 * (S + S.T))
        resid = z - Y  # (N, m)
        Linv = np.linalg.inv(L)  # small (m, m); LAPACK's batched triangular solve is slower here
        white = resid @ _t(Linv)  # (N, m): L⁻¹ rᵢ per particle
        ll = -0.5 * np.einsum("ij,ij->i", white, white) - np.sum(np.log(np.diag(L)))
        ll -= 0.5 * z.shape[0] * np.log(2.0 * np.pi)
        lw_un = state.log_w + ll
        mx = float(np.max(lw_un))
        evidence = mx + float(np.log(np.sum(np.exp(lw_un - mx))))
        log_w = lw_un - evidence
        Xn = X
        pending = state.pending_var
        if A is not None and q_lin is not None:
            Qa = np.diag(q_lin)
            K = (Linv.T @ (Linv @ (A @ Qa))).T  # Q Aᵀ S⁻¹, (n_lin, m)
            Pc = Qa - K @ A @ Qa
            Bc = _sqrt_psd(Pc)
            Xn = X.copy()
            Xn[:, lin] += resid @ _t(K) + self.rng.standard_normal((X.shape[0], lin.size)) @ _t(Bc)
            pending = np.zeros(state.n)
        w = np.exp(log_w)
        ess = float(1.0 / np.dot(w, w))
        resampled = False
        N = X.shape[0]
        if ess < self.ess_threshold * N:
            idx = systematic_resample(w, self.rng)
            Xn = roughen(Xn[idx], self.rng, self.roughening)
            log_w = np.full(N, -np.log(N))
            resampled = True
        post = replace(state, particles=Xn, log_w=log_w, pending_var=pending)
        resid_post = z - meas.h(post.x)
        return ParticleUpdate(post, ess, resampled, evidence, innov, resid_post)


__all__ = [
    "ParticleFilter",
    "ParticleState",
    "ParticleUpdate",
    "effective_sample_size",
    "normalize_log_weights",
    "roughen",
    "systematic_resample",
]
