"""The filters of a cooperative node behind one interface (:class:`NodeFilter`; Zhou et al.
2018; algorithms.md §21).

* :class:`KalmanNode` ``ekf`` (eqs. 12–13) and ``ukf`` (eqs. 14–19): the project's one
  Kalman predict and update, :class:`robustrtk.estimation.filters.EKF` /
  :class:`~robustrtk.estimation.filters.UKF` (κ = 0, so ``λ = (α² − 1) n``). The paper's
  augmented UKF time update (sigma points of ``blockdiag(P, Q̃)``, each propagated as
  ``F χ_x + W χ_w``) equals ``F P Fᵀ + W Q̃ Wᵀ`` exactly for the linear eq. 8, which is the
  shared prediction (the test compares both);
* :class:`ParticleNode` (eqs. 20–23): :class:`robustrtk.estimation.particle.ParticleFilter`;
* :class:`LeastSquaresNode` (the paper's baseline): per-epoch Gauss–Newton,
  :func:`gauss_newton`.

Typical use for one node and epoch::

    filt = make_node_filter("pf", n_particles=10_000, linear_idx=(3,), seed=1)
    belief = filt.init(GaussianState(x0, P0, t0, layout))
    belief = filt.predict(belief, LocationTimeModel(), t1)
    rows = StackedModel((pseudoranges, peer_range_model(...)))
    step = filt.update(belief, rows)          # NodeStep: belief, summary, ESS, ...
    broadcast = PeerBroadcast.of("node2", step.summary)
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Literal, Protocol, get_args

import numpy as np
import numpy.typing as npt

from robustrtk.core import FloatArray, MeasurementModel
from robustrtk.estimation.filters import EKF, UKF
from robustrtk.estimation.models import ProcessModel
from robustrtk.estimation.particle import ParticleFilter, ParticleState
from robustrtk.estimation.robust import RobustOutcome, SolveFn
from robustrtk.estimation.state import GaussianState, StateLayout

FilterKind = Literal["ekf", "ukf", "pf", "ls"]
#: Filter names of :func:`make_node_filter`.
FILTER_KINDS: tuple[str, ...] = get_args(FilterKind)

Belief = GaussianState | ParticleState


@dataclass(frozen=True)
class LsqResult:
    """A Gauss–Newton solution: ``state`` (x, covariance ``(Hᵀ R⁻¹ H)⁻¹``), its post-fit
    residuals, and whether it converged with a non-singular normal matrix."""

    state: GaussianState
    residual: FloatArray
    ok: bool


def gauss_newton(
    meas: MeasurementModel,
    x0: FloatArray,
    *,
    cols: npt.ArrayLike | None = None,
    max_iter: int = 10,
    tol_m: float = 1e-4,
    t_s: float = 0.0,
    layout: StateLayout | None = None,
) -> LsqResult:
    """Weighted least squares ``min (z − h(x))ᵀ R⁻¹ (z − h(x))`` by Gauss–Newton from ``x0``.

    Parameters
    ----------
    meas : MeasurementModel
    x0 : ndarray, shape (n,)
        Start; components outside ``cols`` stay fixed at their start values.
    cols : array_like of int, optional
        Estimated components (default all). Needs ``len(z) ≥ len(cols)``.
    max_iter : int
    tol_m : float
        Stop when ``|Δx| < tol_m``.
    t_s : float
    layout : StateLayout, optional

    Returns
    -------
    LsqResult
        Components outside ``cols`` get a zero covariance row; ``ok`` False when the
        problem is under-determined, singular (condition > 1e12) or did not converge.
    """
    x = np.array(x0, float, copy=True)
    n = x.shape[0]
    c = np.arange(n) if cols is None else np.asarray(cols, dtype=np.int64)
    lay = layout if layout is not None else StateLayout(blocks=(("x", n),))
    z = np.asarray(meas.z, float)
    R = np.asarray(meas.R, float)
    P = np.full((n, n), np.nan)
    if z.shape[0] < c.size:
        return LsqResult(GaussianState(x, P, t_s, lay), z - meas.h(x), False)
    Li = np.linalg.inv(np.linalg.cholesky(R))
    ok = False
    for _ in range(max_iter):
        H = np.asarray(meas.jacobian(x), float)[:, c]
        v = z - meas.h(x)
        Hw, vw = Li @ H, Li @ v
        N = Hw.T @ Hw
        if not np.all(np.isfinite(N)) or np.linalg.cond(N) > 1e12:
            return LsqResult(GaussianState(x, P, t_s, lay), v, False)
        dx = np.linalg.solve(N, Hw.T @ vw)
        x[c] += dx
        if float(np.linalg.norm(dx)) < tol_m:
            ok = True
            break
    H = np.asarray(meas.jacobian(x), float)[:, c]
    Hw = Li @ H
    P = np.zeros((n, n))
    P[np.ix_(c, c)] = np.linalg.inv(Hw.T @ Hw)
    return LsqResult(GaussianState(x, P, t_s, lay), z - meas.h(x), ok)


# ---------------------------------------------------------------------- filters
@dataclass(frozen=True)
class NodeStep:
    """One correction of a node's filter.

    Attributes
    ----------
    belief : GaussianState or ParticleState
        The filter's posterior (what it carries to the next epoch).
    summary : GaussianState
        Its Gaussian summary (output and broadcast).
    innovation : ndarray, shape (m,)
        ``z − h(x̄)`` (EKF), ``z − ŷ`` (UKF, PF: over the prior cloud), ``z − h(x̂)`` (LS).
    labels : tuple of str
    ess : float
        Effective sample size after the correction (NaN except for the PF).
    resampled : bool
    ok : bool
        The correction was carried out (finite, non-singular).
    """

    belief: Belief
    summary: GaussianState
    innovation: FloatArray
    labels: tuple[str, ...]
    ess: float = float("nan")
    resampled: bool = False
    ok: bool = True


class NodeFilter(Protocol):
    """The interface every cooperative filter shares."""

    @property
    def name(self) -> str: ...

    def init(self, state: GaussianState) -> Belief:
        """The filter's belief started from the Gaussian ``state``."""
        ...

    def predict(self, belief: Belief, process: ProcessModel, t_s: float) -> Belief:
        """Time update to ``t_s``."""
        ...

    def update(self, belief: Belief, meas: MeasurementModel) -> NodeStep:
        """Correction with the stacked rows ``meas``."""
        ...

    def summary(self, belief: Belief) -> GaussianState:
        """Gaussian summary of ``belief``."""
        ...


def _gaussian(belief: Belief) -> GaussianState:
    if isinstance(belief, ParticleState):
        return belief.summary()
    return belief


def _failed(g: GaussianState, labels: tuple[str, ...], m: int) -> NodeStep:
    """A refused correction: the prior kept, NaN innovations."""
    return NodeStep(g, g, np.full(m, np.nan), labels, ok=False)


@dataclass(frozen=True)
class PlainUpdate:
    """The standard update as a robust policy of :mod:`robustrtk.estimation.filters`: every row
    kept at factor 1, one ``solve`` — :class:`~robustrtk.estimation.robust.NoRobust`'s numbers —
    without the standardized residuals and Δv̄ it adds for diagnostics (NaN here), which a
    node does not use and which cost as much as the rest of a small update."""

    name: str = "none"

    def run(self, solve: SolveFn, innovation: FloatArray, S: FloatArray, R: FloatArray) -> RobustOutcome:
        m = innovation.shape[0]
        factors = np.ones(m)
        trial = solve(factors, np.ones(m, dtype=bool))
        nan = np.full(m, np.nan)
        return RobustOutcome(trial, factors, nan, nan, 1)


_PLAIN = PlainUpdate()


@dataclass
class KalmanNode:
    """EKF (eqs. 12–13) or UKF (eqs. 14–19): :class:`robustrtk.estimation.filters.EKF` /
    :class:`~robustrtk.estimation.filters.UKF` without a robust policy.

    Parameters
    ----------
    kind : {"ekf", "ukf"}
    alpha, beta : float
        UKF spread and prior-knowledge parameters (``λ = (α² − 1) n``, κ = 0);
        ``1e-4 ≤ α ≤ 1``.
    """

    kind: Literal["ekf", "ukf"] = "ekf"
    alpha: float = 1.0
    beta: float = 2.0
    kalman: EKF | UKF = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if self.kind not in ("ekf", "ukf"):
            raise ValueError(f"kind: expected ekf or ukf, got {self.kind!r}")
        if not 1e-4 <= self.alpha <= 1.0:
            raise ValueError("alpha must be in [1e-4, 1]")
        self.kalman = EKF() if self.kind == "ekf" else UKF(alpha=self.alpha, beta=self.beta, kappa=0.0)

    @property
    def name(self) -> str:
        return self.kind

    def init(self, state: GaussianState) -> GaussianState:
        return state

    def predict(self, belief: Belief, process: ProcessModel, t_s: float) -> GaussianState:
        """The filter's time update (``F P Fᵀ + Q``; module notes for the UKF)."""
        return self.kalman.predict(_gaussian(belief), process, t_s)

    def update(self, belief: Belief, meas: MeasurementModel) -> NodeStep:
        """One correction by :meth:`robustrtk.estimation.filters.EKF.update` /
        :meth:`~robustrtk.estimation.filters.UKF.update`; a correction the filter refuses
        (non-finite prior or rows, a singular innovation covariance) keeps the prior and
        reports NaN innovations with ``ok`` False."""
        g = _gaussian(belief)
        labels = tuple(meas.labels)
        m = np.shape(meas.z)[0]
        if m == 0:
            return NodeStep(g, g, np.zeros(0), labels)
        res = self.kalman.update(g, meas, _PLAIN)
        if res.n_used != m:  # refused as a whole (no robust policy: every row or none)
            return _failed(g, labels, m)
        return NodeStep(res.state, res.state, res.innovation, labels)

    def summary(self, belief: Belief) -> GaussianState:
        return _gaussian(belief)


@dataclass
class ParticleNode:
    """The particle filter of :mod:`robustrtk.estimation.particle` behind :class:`NodeFilter`.

    Parameters are those of :class:`~robustrtk.estimation.particle.ParticleFilter`
    (``linear_idx``: the clock indices, drawn through the optimal linear proposal).
    """

    n_particles: int = 2000
    ess_threshold: float = 0.5
    roughening: float = 0.2
    seed: int = 0
    linear_idx: tuple[int, ...] = ()
    pf: ParticleFilter = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self.pf = ParticleFilter(
            n_particles=self.n_particles,
            ess_threshold=self.ess_threshold,
            roughening=self.roughening,
            seed=self.seed,
            linear_idx=self.linear_idx,
        )

    @property
    def name(self) -> str:
        return "pf"

    def init(self, state: GaussianState) -> ParticleState:
        return self.pf.init(state)

    def predict(self, belief: Belief, process: ProcessModel, t_s: float) -> ParticleState:
        cloud = belief if isinstance(belief, ParticleState) else self.pf.init(belief)
        return self.pf.predict(cloud, process, t_s)

    def update(self, belief: Belief, meas: MeasurementModel) -> NodeStep:
        cloud = belief if isinstance(belief, ParticleState) else self.pf.init(belief)
        if len(meas.labels) == 0:
            return NodeStep(cloud, cloud.summary(), np.zeros(0), (), cloud.ess, False)
        try:
            up = self.pf.update(cloud, meas)
        except (np.linalg.LinAlgError, ValueError):
            return NodeStep(
                cloud, cloud.summary(), np.full(len(meas.labels), np.nan), tuple(meas.labels), ok=False
            )
        return NodeStep(up.state, up.state.summary(), up.innovation, tuple(meas.labels), up.ess, up.resampled)

    def summary(self, belief: Belief) -> GaussianState:
        return _gaussian(belief)


@dataclass
class LeastSquaresNode:
    """Per-epoch weighted least squares (the paper's baseline): the prior only supplies the
    start of :func:`gauss_newton`; the estimated components are those some row depends on.
    """

    max_iter: int = 10

    @property
    def name(self) -> str:
        return "ls"

    def init(self, state: GaussianState) -> GaussianState:
        return state

    def predict(self, belief: Belief, process: ProcessModel, t_s: float) -> GaussianState:
        return replace(_gaussian(belief), t_s=t_s)

    def update(self, belief: Belief, meas: MeasurementModel) -> NodeStep:
        g = _gaussian(belief)
        if len(meas.labels) == 0:
            return NodeStep(g, g, np.zeros(0), (), ok=False)
        H = np.asarray(meas.jacobian(g.x), float)
        cols = np.flatnonzero(np.any(H != 0.0, axis=0))
        res = gauss_newton(meas, g.x, cols=cols, max_iter=self.max_iter, t_s=g.t_s, layout=g.layout)
        if not res.ok:
            return NodeStep(g, g, res.residual, tuple(meas.labels), ok=False)
        return NodeStep(res.state, res.state, res.residual, tuple(meas.labels))

    def summary(self, belief: Belief) -> GaussianState:
        return _gaussian(belief)


def make_node_filter(kind: str, **params: object) -> NodeFilter:
    """``ekf`` / ``ukf`` (:class:`KalmanNode`: alpha, beta), ``pf`` (:class:`ParticleNode`:
    n_particles, ess_threshold, roughening, seed, linear_idx) or ``ls``
    (:class:`LeastSquaresNode`: max_iter).

    Raises
    ------
    ValueError
        Unknown kind.
    """
    if kind in ("ekf", "ukf"):
        return KalmanNode(kind, **params)  # type: ignore[arg-type]
    if kind == "pf":
        return ParticleNode(**params)  # type: ignore[arg-type]
    if kind == "ls":
        return LeastSquaresNode(**params)  # type: ignore[arg-type]
    raise ValueError(f"unknown cooperative filter {kind!r}; expected one of {', '.join(FILTER_KINDS)}")


__all__ = [
    "FILTER_KINDS",
    "Belief",
    "FilterKind",
    "KalmanNode",
    "LeastSquaresNode",
    "LsqResult",
    "NodeFilter",
    "NodeStep",
    "ParticleNode",
    "gauss_newton",
    "make_node_filter",
]
