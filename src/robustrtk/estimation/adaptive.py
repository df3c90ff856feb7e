"""Adaptive factors: scale the predicted covariance when the dynamics disagree with the data.

Yang's two-segment adaptive factor (smartphone seed; ``docs/algorithms.md`` §5) from a
discrepancy statistic ``Δ``::

    α = 1                                      Δ ≤ c0
    α = (c0/Δ) · ((c1 − Δ)/(c1 − c0))²          c0 < Δ ≤ c1
    α = floor                                  Δ > c1

and the prior becomes ``P̄/α``. :class:`InnovationAdaptiveFactor` computes ``Δ`` from the
innovations of the nominal prior, robustly: the median absolute standardized innovation
``Δ = median |dᵢ| / √Sᵢᵢ / 0.6745`` is 1 on average when the prior is right, stays near 1
when a minority of rows carries gross errors (those are the robust policy's business), and
grows with a dynamics error, which moves every row. It implements the ``scale`` protocol
of the filters' prior-scaling hook and returns the factor ``1/α`` applied to ``P̄``.

:class:`StateDiscrepancyFactor` is the smartphone paper's factor (``estimator.adaptive =
"state"``, ``--adaptive``): per kinematic component ``Δx̃ᵢ = |x̂ᵢ − x̄ᵢ|/√P̄ᵢᵢ`` (c0 = 1.0,
c1 = 2.5), the row weights of ``x̂`` taken from a measurement-only robust fit, repeated on the
widened prior until it agrees with the data, and applied as the two-factor equivalent
covariance ``P̄ᵢⱼ/√(αᵢαⱼ)`` (algorithms.md §23). :func:`adaptive_update` is the one entry
point of the pipelines for both factors.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from robustrtk.core import FloatArray, median_of
from robustrtk.estimation.filters import Filter
from robustrtk.estimation.models import MeasurementModel
from robustrtk.estimation.prior_scale import apply_prior_scale
from robustrtk.estimation.robust import FixedFactors, RobustPolicy
from robustrtk.estimation.state import GaussianState, StateLayout, UpdateResult

#: Median of |N(0, 1)|: the median absolute standardized innovation is this when the prior is right.
MEDIAN_ABS_NORMAL = 0.6744897501960817


def yang_factor(delta: float, c0: float, c1: float, floor: float = 1e-3) -> float:
    """Yang's two-segment adaptive factor α(Δ) (see the module docstring)."""
    if not np.isfinite(delta) or delta > c1:
        return floor
    if delta <= c0:
        return 1.0
    return max(floor, (c0 / delta) * ((c1 - delta) / (c1 - c0)) ** 2)


def robust_innovation_ratio(innovation: FloatArray, innovation_cov: FloatArray) -> float:
    """``median |dᵢ| / √Sᵢᵢ / 0.6745``: about 1 when the prior and the noise model are right."""
    d = np.asarray(innovation, float)
    s = np.sqrt(np.maximum(np.diag(np.asarray(innovation_cov, float)), 1e-300))
    ok = np.isfinite(d)
    if not ok.any():
        return 1.0
    return float(median_of(np.abs(d[ok]) / s[ok]) / MEDIAN_ABS_NORMAL)


@dataclass(frozen=True)
class InnovationAdaptiveFactor:
    """Adaptive factor from the robust innovation ratio (prior-scaling hook).

    Parameters
    ----------
    c0, c1 : float
        Segment bounds on the ratio: no scaling up to ``c0``; the floor beyond ``c1``.
    floor : float
        Smallest α (largest inflation ``1/floor``).
    min_rows : int
        With fewer rows the ratio is not meaningful and α = 1.
    """

    c0: float = 2.0
    c1: float = 6.0
    floor: float = 1e-4
    min_rows: int = 4
    name: str = "innovation"

    def alpha(self, innovation: FloatArray, innovation_cov: FloatArray) -> float:
        """α for these innovations ``d`` (m,) and their covariance ``S`` (m, m)."""
        if np.count_nonzero(np.isfinite(innovation)) < self.min_rows:
            return 1.0
        return yang_factor(robust_innovation_ratio(innovation, innovation_cov), self.c0, self.c1, self.floor)

    def scale(
        self, state: object, innovation: FloatArray, innovation_cov: FloatArray, R: FloatArray
    ) -> float:
        """The factor ``1/α`` applied to the predicted covariance."""
        return 1.0 / self.alpha(innovation, innovation_cov)


def state_discrepancy(prior: GaussianState, post_x: FloatArray, idx: np.ndarray) -> FloatArray:
    """Per-component discrepancy of the predicted state (algorithms.md §23).

    ``Δx̃ᵢ = |x̂ᵢ − x̄ᵢ| / √P̄ᵢᵢ`` for ``i ∈ idx``: the correction the measurements apply to
    component ``i`` in units of its predicted standard deviation.

    Parameters
    ----------
    prior : GaussianState
        The prediction ``(x̄, P̄)``, n states.
    post_x : ndarray, shape (n,)
        The updated state ``x̂``.
    idx : ndarray of int, shape (p,)
        Components tested.

    Returns
    -------
    ndarray, shape (p,)
        ``Δx̃`` (dimensionless, ≥ 0).
    """
    dx = np.abs(np.asarray(post_x, float)[idx] - prior.x[idx])
    sig = np.sqrt(np.maximum(np.diag(prior.P)[idx], 1e-300))
    return np.asarray(dx / sig, float)


def yang_factors(delta: FloatArray, c0: float, c1: float, floor: float = 1e-3) -> FloatArray:
    """:func:`yang_factor` of each entry of ``delta`` (shape kept)."""
    d = np.asarray(delta, float)
    return np.array([yang_factor(float(v), c0, c1, floor) for v in d.ravel()], float).reshape(d.shape)


def equivalent_covariance(P: FloatArray, alpha: FloatArray) -> FloatArray:
    """Two-factor equivalent covariance of the prediction (algorithms.md §2, §23).

    .. math:: \\bar P^{α}_{ij} = \\bar P_{ij} / \\sqrt{α_i α_j}

    so ``P̄ᵢᵢ/αᵢ`` on the diagonal and every correlation coefficient unchanged; in matrix form
    ``A^{-1/2} P̄ A^{-1/2}`` with ``A = diag(α)``, symmetric and positive definite when ``P̄`` is.

    Parameters
    ----------
    P : ndarray, shape (n, n)
        Predicted covariance ``P̄``.
    alpha : ndarray, shape (n,)
        Factors ``0 < αᵢ ≤ 1``.
    """
    a = np.asarray(alpha, float)
    return apply_prior_scale(np.asarray(P, float), 1.0 / a)


@dataclass(frozen=True)
class AdaptiveOutcome:
    """What the adaptive factor decided in one update.

    Attributes
    ----------
    alpha : ndarray, shape (n,)
        Per-component factor αᵢ (1 = prediction kept; the prior became ``P̄ᵢⱼ/√(αᵢαⱼ)``).
    delta : ndarray, shape (n,)
        The discrepancy ``Δx̃ᵢ`` of the first pass (NaN for components not tested; for the
        innovation factor the robust innovation ratio in every entry).
    iterations : int
        Passes of the discrepancy test.
    floor : float
        The factor's smallest α (0: none).
    """

    alpha: FloatArray
    delta: FloatArray
    iterations: int = 1
    floor: float = 0.0

    @property
    def at_floor(self) -> bool:
        """Some αᵢ reached the floor (that component's prediction all but dropped)."""
        return bool(self.floor > 0 and np.any(self.alpha <= self.floor * (1 + 1e-12)))

    @property
    def alpha_min(self) -> float:
        """The smallest αᵢ (1 when none was lowered)."""
        return float(np.min(self.alpha)) if self.alpha.size else 1.0

    @property
    def delta_max(self) -> float:
        """The largest tested ``Δx̃ᵢ`` (NaN when none was tested)."""
        ok = np.isfinite(self.delta)
        return float(np.max(self.delta[ok])) if ok.any() else float("nan")


@dataclass(frozen=True)
class StateDiscrepancyFactor:
    """Yang's adaptive factor from the predicted-state discrepancy (smartphone paper sec. 3.2).

    One measurement update with this factor (:meth:`update`, algorithms.md §23):

    1. *measurement-only robust fit*: the robust update of the prior whose kinematic block is
       inflated to the floor (``P̄ᵢⱼ/√(αᵢαⱼ)`` with ``α = floor``), so the robust policy judges
       the rows against the measurements, not against a prediction that may be wrong; its
       row factors γ are kept;
    2. *discrepancy*: the update of the nominal prior with those γ gives ``x̂``;
       ``Δx̃ᵢ = |x̂ᵢ − x̄ᵢ|/√P̄ᵢᵢ`` on the kinematic components and ``αᵢ`` from Yang's
       three-segment function (c0, c1). While some ``αᵢ < 1`` (at most ``max_iter`` passes)
       the test is repeated on the adapted prior ``(x̄, P̄^α)``, the factors multiplying, so
       the prior is widened until the prediction agrees with the data within ``c0`` of its
       own spread (the first pass alone is the paper's factor);
    3. the robust update of ``(x̄, P̄^α)`` with the two-factor equivalent covariance.

    When no component exceeds ``c0`` the result is the plain robust update.

    Parameters
    ----------
    c0, c1 : float
        Segment bounds on ``Δx̃ᵢ`` (paper: 1.0 and 2.5).
    floor : float
        Smallest αᵢ (never 0).
    blocks : tuple of str
        State blocks that get a factor (the kinematic ones); other components keep α = 1.
    max_iter : int
        Passes of the discrepancy test (1 = the paper's single pass).
    """

    c0: float = 1.0
    c1: float = 2.5
    floor: float = 1e-3
    blocks: tuple[str, ...] = ("pos", "vel", "acc")
    max_iter: int = 10
    name: str = "state"

    def components(self, layout: StateLayout) -> np.ndarray:
        """Indices of the tested components (:attr:`blocks` present in ``layout``)."""
        idx = [np.arange(layout.slice(b).start, layout.slice(b).stop) for b in self.blocks if layout.has(b)]
        return np.concatenate(idx).astype(int) if idx else np.zeros(0, int)

    def alphas(self, prior: GaussianState, post_x: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``(α (n,), Δx̃ (n,))`` of one pass; α = 1 and Δx̃ = NaN outside :attr:`blocks`."""
        idx = self.components(prior.layout)
        a = np.ones(prior.n)
        dlt = np.full(prior.n, np.nan)
        if idx.size:
            dlt[idx] = state_discrepancy(prior, post_x, idx)
            a[idx] = yang_factors(dlt[idx], self.c0, self.c1, self.floor)
        return a, dlt

    def update(
        self, filt: Filter, state: GaussianState, meas: MeasurementModel, robust: RobustPolicy | None
    ) -> tuple[UpdateResult, AdaptiveOutcome]:
        """The adaptive robust update of ``state`` (steps 1–3 above).

        Returns
        -------
        UpdateResult
            Of the final update (``prior_scale`` = ``1/α`` when the prior was widened).
        AdaptiveOutcome
            α, the first pass's Δx̃ and the passes run.
        """
        n = state.n
        idx = self.components(state.layout)
        a = np.ones(n)
        if idx.size == 0:
            return filt.update(state, meas, robust), AdaptiveOutcome(a, np.full(n, np.nan), 0)
        wide = np.ones(n)
        wide[idx] = 1.0 / self.floor
        fit = filt.update(state, meas, robust, prior_scale=wide)
        rows = FixedFactors(tuple(float(g) for g in fit.factors))
        first: FloatArray | None = None
        passes = 0
        for _ in range(self.max_iter):
            scale = None if np.all(a == 1.0) else 1.0 / a
            prior = state if scale is None else state.with_(P=apply_prior_scale(state.P, scale))
            trial = filt.update(state, meas, rows, prior_scale=scale)
            step, dlt = self.alphas(prior, trial.state.x)
            passes += 1
            if first is None:
                first = dlt
            if np.all(step == 1.0):
                break
            a = np.maximum(a * step, self.floor)
            if np.all(a[idx] == self.floor):
                break
        assert first is not None
        out = AdaptiveOutcome(a, first, passes, self.floor)
        if np.all(a == 1.0):
            return filt.update(state, meas, robust), out
        return filt.update(state, meas, robust, prior_scale=1.0 / a), out


AdaptiveFactor = InnovationAdaptiveFactor | StateDiscrepancyFactor


#: Names of the adaptive factors (``estimator.adaptive``), ``"off"`` for none.
ADAPTIVE_NAMES = ("off", "innovation", "state")


def make_adaptive_factor(
    name: str, c0: float | None = None, c1: float | None = None, max_iter: int | None = None
) -> AdaptiveFactor | None:
    """Adaptive factor by name: ``off`` (None), ``innovation`` (c0 = 2, c1 = 6 by default) or
    ``state`` (the paper's c0 = 1.0, c1 = 2.5 by default); ``c0``/``c1`` override, and
    ``max_iter`` the passes of the state factor (default 10)."""
    if name == "off":
        return None
    if name == "innovation":
        d = InnovationAdaptiveFactor()
        return replace(d, c0=d.c0 if c0 is None else c0, c1=d.c1 if c1 is None else c1)
    if name == "state":
        e = StateDiscrepancyFactor()
        return replace(
            e,
            c0=e.c0 if c0 is None else c0,
            c1=e.c1 if c1 is None else c1,
            max_iter=e.max_iter if max_iter is None else max_iter,
        )
    raise ValueError(f"unknown adaptive factor {name!r}; expected one of {', '.join(ADAPTIVE_NAMES)}")


def adaptive_update(
    filt: Filter,
    state: GaussianState,
    meas: MeasurementModel,
    robust: RobustPolicy | None,
    adaptive: AdaptiveFactor | None,
) -> tuple[UpdateResult, AdaptiveOutcome | None]:
    """One measurement update with the configured adaptive factor (None: the plain update).

    The pipelines call this one function (Kalman SPP, DGNSS/DPL code, RTK), so every mode
    gets the same factor. :class:`InnovationAdaptiveFactor` goes through the prior-scaling
    hook (one scalar α for the whole state); :class:`StateDiscrepancyFactor` runs its own
    passes (:meth:`StateDiscrepancyFactor.update`).
    """
    if adaptive is None:
        return filt.update(state, meas, robust), None
    if isinstance(adaptive, StateDiscrepancyFactor):
        return adaptive.update(filt, state, meas, robust)
    res = filt.update(state, meas, robust, prior_scale=adaptive)
    s = 1.0 if res.prior_scale is None else float(np.max(np.atleast_1d(res.prior_scale)))
    d = robust_innovation_ratio(res.innovation, res.innovation_cov) if res.innovation.size else np.nan
    return res, AdaptiveOutcome(np.full(state.n, 1.0 / s), np.full(state.n, d), 1, adaptive.floor)


@dataclass(frozen=True)
class StationaryModel:
    """The "not moving" hypothesis on a position–velocity layout.

    ``pos ← pos`` with the tiny noise ``q_m2_s · dt``, ``vel ← 0`` with variance
    ``sigma_vel0_m_s²``, no coupling: the position block evolves exactly as under a static
    model, so a receiver that never moves gets the static solution, while the state keeps
    the velocity block a constant-velocity hypothesis needs when it starts moving. Used by
    :class:`MotionSelector`.
    """

    q_m2_s: float = 1e-8
    sigma_vel0_m_s: float = 0.1
    name: str = "stationary"

    def blocks(self) -> tuple[tuple[str, int], ...]:
        return (("pos", 3), ("vel", 3))

    def transition(self, layout: StateLayout, dt_s: float) -> tuple[FloatArray, FloatArray]:
        n = layout.size
        F = np.eye(n)
        Q = np.zeros((n, n))
        p, v = layout.slice("pos"), layout.slice("vel")
        F[v, v] = 0.0
        Q[p, p] = np.eye(3) * self.q_m2_s * abs(dt_s)
        Q[v, v] = np.eye(3) * self.sigma_vel0_m_s**2
        return F, Q


def robust_log_likelihood(innovation: FloatArray, innovation_cov: FloatArray, k: float = 3.0) -> float:
    """Truncated Gaussian log-likelihood of innovations, row by row (diagonal of ``S``).

    ``ℓ = Σᵢ −½ min(uᵢ², k²) − ln σᵢ`` with ``σᵢ = √Sᵢᵢ`` and ``uᵢ = dᵢ/σᵢ``: each row's
    contribution is capped at ``k`` standard deviations, so a gross error costs as much as a
    large one and a few faulty rows do not decide which prediction explains the data.
    """
    d = np.asarray(innovation, float)
    sig = np.sqrt(np.maximum(np.diag(np.asarray(innovation_cov, float)), 1e-300))
    ok = np.isfinite(d)
    u2 = np.minimum((d[ok] / sig[ok]) ** 2, k * k)
    return float(np.sum(-0.5 * u2 - np.log(sig[ok])))


@dataclass(frozen=True)
class MotionSelector:
    """Chooses per epoch between a stationary and a moving prediction (``dynamics = auto``).

    Both predictions are confronted with the epoch's innovations; the moving one (constant
    velocity) is used when its truncated log-likelihood (:func:`robust_log_likelihood`)
    is higher. A parked receiver's data agree with the tight stationary prior (the broad
    moving prior pays ``ln σ`` per row); a moving receiver's do not. So a receiver that stands
    still is averaged like a static one and a car is followed like a kinematic one; capping
    each row at ``k`` σ keeps a minority of faulty rows from deciding.
    """

    k: float = 3.0
    min_rows: int = 4

    def moving(
        self,
        stationary: tuple[FloatArray, FloatArray],
        moving: tuple[FloatArray, FloatArray],
    ) -> bool:
        """True when the moving prediction's ``(d, S)`` explain the rows better."""
        if np.count_nonzero(np.isfinite(stationary[0])) < self.min_rows:
            return False
        gain = robust_log_likelihood(*moving, k=self.k) - robust_log_likelihood(*stationary, k=self.k)
        return gain > 0.0


__all__ = [
    "ADAPTIVE_NAMES", "MEDIAN_ABS_NORMAL", "AdaptiveFactor", "AdaptiveOutcome", "InnovationAdaptiveFactor",
    "MotionSelector", "StateDiscrepancyFactor", "StationaryModel", "adaptive_update",
    "equivalent_covariance", "make_adaptive_factor", "robust_log_likelihood", "robust_innovation_ratio",
    "state_discrepancy", "yang_factor", "yang_factors",
]  # fmt: skip
