"""Interacting multiple model (IMM) dynamics: stationary, cruising and manoeuvring.

One receiver may stand still, drive straight or turn hard; no single process model is
right for all three. The IMM of Blom & Bar-Shalom (1988) keeps one Gaussian per model and
the probability ``μⱼ`` that each model is the one in force, and every epoch
(docs/algorithms.md §32):

1. *mixing*: with the Markov transition matrix ``Πᵢⱼ = P(model j now | model i before)``,
   ``c̄ⱼ = Σᵢ Πᵢⱼ μᵢ``, ``μᵢ|ⱼ = Πᵢⱼ μᵢ / c̄ⱼ``, and each model starts from the mixture
   ``x⁰ⱼ = Σᵢ μᵢ|ⱼ xᵢ``, ``P⁰ⱼ = Σᵢ μᵢ|ⱼ (Pᵢ + (xᵢ − x⁰ⱼ)(xᵢ − x⁰ⱼ)ᵀ)``;
2. *model-matched filtering*: each model predicts from its mixed start and is updated with
   the same measurements (the filter's robust update, :func:`~robustrtk.estimation.adaptive.adaptive_update`);
3. *mode probabilities*: ``μⱼ ∝ Λⱼ c̄ⱼ`` with the likelihood ``Λⱼ`` of model j's innovations,
   here a row-wise Huber likelihood (:func:`huber_log_likelihood`: a few faulty rows must
   not decide which dynamics explain the data);
4. *output*: the moment-matched mixture ``x = Σ μⱼ xⱼ``, ``P = Σ μⱼ (Pⱼ + (xⱼ − x)(xⱼ − x)ᵀ)``.

The transition matrix comes from the models' mean dwell times ``τⱼ`` (how long a receiver
typically stays stationary, cruising or manoeuvring): over ``dt`` a model is left with
probability ``1 − exp(−dt/τⱼ)``, shared equally by the others (:func:`transition_matrix`).

:func:`make_imm_models` builds the default three models on a ``(pos, vel)`` layout from
physical quantities only: the stationary model (position held with the static model's
tiny noise, velocity reset to zero), constant velocity with white acceleration of the
configured σ (a car's ordinary accelerations), and constant velocity with white
acceleration of 1 g, the most tyre grip gives a road vehicle when it brakes or turns.
With one model, or with every other model's probability 0 and infinite dwell times, the
IMM is exactly the Kalman filter of that model.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from robustrtk.core import FloatArray
from robustrtk.estimation.adaptive import AdaptiveFactor, AdaptiveOutcome, StationaryModel, adaptive_update
from robustrtk.estimation.filters import Filter
from robustrtk.estimation.models import ConstantVelocityModel, MeasurementModel, ProcessModel
from robustrtk.estimation.robust import RobustPolicy
from robustrtk.estimation.state import GaussianState, StateLayout, UpdateResult

#: Standard gravity (m/s²): the manoeuvring model's acceleration σ, the grip limit of a tyre.
GRAVITY_M_S2 = 9.80665
#: Vertical acceleration σ of the cruising model (m/s²): the comfort limit to which road
#: vertical curves are designed (AASHTO, 0.3 m/s²); anything steeper is a manoeuvre.
VERTICAL_CRUISE_M_S2 = 0.3
#: Mean dwell times (s): a stop (a light, a parking) lasts about half a minute, a cruising
#: stretch between manoeuvres about ten seconds, a turn or a braking about three.
DWELL_STATIONARY_S = 30.0
DWELL_CRUISE_S = 10.0
DWELL_MANOEUVRE_S = 3.0
#: Rows beyond this many σ enter the mode likelihood linearly, not quadratically (Huber).
LIKELIHOOD_CAP_SIGMA = 3.0


def huber_log_likelihood(
    innovation: FloatArray, innovation_cov: FloatArray, k: float = LIKELIHOOD_CAP_SIGMA
) -> float:
    """Row-wise Huber log-likelihood of innovations (diagonal of ``S``).

    ``ℓ = −Σᵢ ρ(uᵢ) + ln σᵢ``, ``uᵢ = dᵢ/σᵢ``, ``σᵢ = √Sᵢᵢ``, with ``ρ(u) = u²/2`` for
    ``|u| ≤ k`` and ``k|u| − k²/2`` beyond (Huber's least-favourable density): a gross
    error on a few rows costs linearly, not quadratically, so it cannot decide alone; yet
    unlike a truncated likelihood the cost keeps growing with the innovation, so of two
    predictions that both miss, the one that misses by more is still the less likely
    (a capped cost would prefer the tighter of two wrong predictions).
    """
    d = np.asarray(innovation, float)
    sig = np.sqrt(np.maximum(np.diag(np.asarray(innovation_cov, float)), 1e-300))
    ok = np.isfinite(d)
    u = np.abs(d[ok] / sig[ok])
    rho = np.where(u <= k, 0.5 * u * u, k * u - 0.5 * k * k)
    return float(-np.sum(rho + np.log(sig[ok])))


def transition_matrix(dwell_s: Sequence[float], dt_s: float) -> FloatArray:
    """Markov mode-transition matrix over ``dt_s`` from mean dwell times.

    ``Πⱼⱼ = exp(−|dt|/τⱼ)`` and ``Πⱼₖ = (1 − Πⱼⱼ)/(M − 1)`` for ``k ≠ j`` (rows sum to 1;
    ``τ = inf`` never leaves). One model: ``[[1]]``.

    Parameters
    ----------
    dwell_s : sequence of float, length M
        Mean time ``τⱼ`` (s) spent in each model before leaving it.
    dt_s : float
        Time step (s).

    Returns
    -------
    ndarray, shape (M, M)
    """
    tau = np.asarray(dwell_s, float)
    m = tau.size
    if m == 1:
        return np.ones((1, 1))
    with np.errstate(divide="ignore"):
        stay = np.exp(-abs(dt_s) / tau)
    Pi = np.repeat(((1.0 - stay) / (m - 1))[:, None], m, axis=1)
    np.fill_diagonal(Pi, stay)
    return Pi


def moment_match(
    xs: Sequence[FloatArray], Ps: Sequence[FloatArray], w: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Mean and covariance of the Gaussian mixture ``Σ wⱼ N(xⱼ, Pⱼ)`` (``w`` sums to 1).

    ``x = Σ wⱼ xⱼ``, ``P = Σ wⱼ (Pⱼ + (xⱼ − x)(xⱼ − x)ᵀ)``."""
    x = np.zeros_like(np.asarray(xs[0], float))
    for wj, xj in zip(w, xs, strict=True):
        x = x + wj * xj
    P = np.zeros_like(np.asarray(Ps[0], float))
    for wj, xj, Pj in zip(w, xs, Ps, strict=True):
        if wj > 0.0:
            d = xj - x
            P = P + wj * (Pj + np.outer(d, d))
    return x, 0.5 * (P + P.T)


def combine(states: Sequence[GaussianState], w: FloatArray) -> GaussianState:
    """The moment-matched mixture of states with one layout and time (:func:`moment_match`)."""
    if len(states) == 1:
        return states[0]
    x, P = moment_match([s.x for s in states], [s.P for s in states], w)
    return states[0].with_(x=x, P=P)


def mix(
    states: Sequence[GaussianState], mu: FloatArray, Pi: FloatArray
) -> tuple[list[GaussianState], FloatArray]:
    """The IMM interaction step: each model's mixed start and the predicted probabilities.

    Returns
    -------
    list of GaussianState, length M
        ``(x⁰ⱼ, P⁰ⱼ)`` (module docstring, step 1).
    ndarray, shape (M,)
        ``c̄ⱼ = Σᵢ Πᵢⱼ μᵢ``.
    """
    c = Pi.T @ mu
    out = []
    for j in range(len(states)):
        if c[j] <= 0.0:
            out.append(states[j])
            continue
        w = Pi[:, j] * mu / c[j]
        out.append(combine(states, w) if np.count_nonzero(w) > 1 else states[int(np.argmax(w))])
    return out, c


def posterior_probabilities(c: FloatArray, loglik: FloatArray) -> FloatArray:
    """``μⱼ ∝ c̄ⱼ exp(ℓⱼ)`` (log-sum-exp; non-finite ``ℓ`` leaves ``c̄``)."""
    ll = np.asarray(loglik, float)
    if not np.all(np.isfinite(ll)):
        return np.asarray(c, float).copy()
    with np.errstate(divide="ignore"):
        a = np.log(np.maximum(c, 0.0)) + ll - np.max(ll)
    a = a - np.max(a)
    p = np.exp(a)
    return p / p.sum()


@dataclass(frozen=True)
class ImmModels:
    """The models of an IMM, their names and mean dwell times (s)."""

    models: tuple[ProcessModel, ...]
    dwell_s: tuple[float, ...]
    mu0: tuple[float, ...]
    cap_sigma: float = LIKELIHOOD_CAP_SIGMA

    def __post_init__(self) -> None:
        if not (len(self.models) == len(self.dwell_s) == len(self.mu0) >= 1):
            raise ValueError("IMM: models, dwell times and initial probabilities differ in number")

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(m.name for m in self.models)

    def blocks(self) -> tuple[tuple[str, int], ...]:
        """The state blocks every model's layout has (the first model's)."""
        return self.models[0].blocks()


def make_imm_models(sigma_acc_m_s2: float, q_static_m2_s: float) -> ImmModels:
    """The default three models on a ``(pos, vel)`` layout (module docstring): stationary,
    cruising at constant velocity (acceleration σ ``sigma_acc_m_s2`` horizontally and
    :data:`VERTICAL_CRUISE_M_S2` along the local vertical set by :meth:`ImmTracker.predict`'s
    ``up``) and manoeuvring (1 g on every axis); starting with equal probabilities."""
    return ImmModels(
        models=(
            StationaryModel(q_m2_s=q_static_m2_s),
            ConstantVelocityModel(sigma_m_s2=sigma_acc_m_s2, name="cruise"),
            ConstantVelocityModel(sigma_m_s2=GRAVITY_M_S2, name="manoeuvre"),
        ),
        dwell_s=(DWELL_STATIONARY_S, DWELL_CRUISE_S, DWELL_MANOEUVRE_S),
        mu0=(1 / 3, 1 / 3, 1 / 3),
    )


@dataclass
class ImmTracker:
    """The IMM's per-model states between epochs, around a filter's single-state interface.

    The caller sees one state: :meth:`predict` returns the combined prediction and
    :meth:`update` an :class:`UpdateResult` whose state is the combined posterior. When the
    state the caller hands back is not the one the tracker produced (re-initialised,
    widened by an integrity test, restarted), every model restarts from it and the mode
    probabilities are kept.

    Attributes
    ----------
    spec : ImmModels
    mu : ndarray, shape (M,)
        The mode probabilities after the last update (the predicted ones when there was none).
    """

    spec: ImmModels
    mu: FloatArray | None = None
    posts: list[GaussianState] | None = None
    combined: GaussianState | None = None
    priors: list[GaussianState] | None = None
    c: FloatArray | None = None
    prior_combined: GaussianState | None = None

    def __post_init__(self) -> None:
        if self.mu is None:
            mu = np.asarray(self.spec.mu0, float)
            self.mu = mu / mu.sum()

    @property
    def probabilities(self) -> FloatArray:
        """Current mode probabilities (M,)."""
        assert self.mu is not None
        return self.mu.copy()

    def dominant(self) -> ProcessModel:
        """The most probable model."""
        return self.spec.models[int(np.argmax(self.probabilities))]

    def _sync(self, prev: GaussianState) -> tuple[list[GaussianState], FloatArray]:
        assert self.mu is not None
        if self.posts is not None and prev is self.combined:
            return self.posts, self.mu
        if self.priors is not None and self.c is not None and prev is self.prior_combined:
            return self.priors, self.c  # a prediction not updated (an epoch without rows)
        return [prev] * len(self.spec.models), self.mu

    def predict(
        self, filt: Filter, prev: GaussianState, t_s: float, up: FloatArray | None = None
    ) -> GaussianState:
        """Mix, predict each model to ``t_s``; returns the combined prediction (``c̄``-weighted).

        ``up`` (3,): the local vertical of the state's frame (ECEF: the receiver's), for
        models whose acceleration differs along it (``ConstantVelocityModel.sigma_up_m_s2``)."""
        states, mu = self._sync(prev)
        Pi = transition_matrix(self.spec.dwell_s, t_s - prev.t_s)
        mixed, c = mix(states, mu, Pi)
        models = list(self.spec.models)
        if up is not None:
            u = (float(up[0]), float(up[1]), float(up[2]))
            models = [
                replace(m, up=u)
                if isinstance(m, ConstantVelocityModel) and m.sigma_up_m_s2 is not None
                else m
                for m in models
            ]
        self.priors = [filt.predict(s, m, t_s) for s, m in zip(mixed, models, strict=True)]
        self.c = c
        self.mu = c.copy()
        self.posts = None
        self.prior_combined = combine(self.priors, c)
        return self.prior_combined

    def update(
        self,
        filt: Filter,
        prior: GaussianState,
        meas: MeasurementModel,
        robust: RobustPolicy | None,
        adaptive: AdaptiveFactor | None = None,
    ) -> tuple[UpdateResult, AdaptiveOutcome | None]:
        """Update every model with ``meas``; the mode probabilities from their likelihoods.

        ``prior`` is the state :meth:`predict` returned (or one the caller replaced it with:
        then every model starts from it). Returns the most probable model's update result
        with the combined posterior as its state, and its adaptive outcome.
        """
        M = len(self.spec.models)
        if self.priors is not None and self.c is not None and prior is self.prior_combined:
            priors, c = self.priors, self.c
        else:
            assert self.mu is not None
            priors, c = [prior] * M, self.mu
        results = [adaptive_update(filt, p, meas, robust, adaptive) for p in priors]
        ll = np.array(
            [
                huber_log_likelihood(r.innovation, r.innovation_cov, k=self.spec.cap_sigma)
                if r.n_used > 0
                else np.nan
                for r, _ in results
            ]
        )
        mu = posterior_probabilities(c, ll) if M > 1 else np.ones(1)
        posts = [r.state for r, _ in results]
        combined = combine(posts, mu)
        self.mu, self.posts, self.combined = mu, posts, combined
        best = int(np.argmax(mu))
        res, outcome = results[best]
        return replace(res, state=combined), outcome


def is_imm_layout(layout: StateLayout, spec: ImmModels) -> bool:
    """The layout carries every block the IMM's models need."""
    return all(layout.has(b) for b, _ in spec.blocks())


__all__ = [
    "DWELL_CRUISE_S", "DWELL_MANOEUVRE_S", "DWELL_STATIONARY_S", "GRAVITY_M_S2", "LIKELIHOOD_CAP_SIGMA",
    "ImmModels", "ImmTracker", "combine", "huber_log_likelihood", "is_imm_layout", "make_imm_models", "mix",
    "moment_match", "posterior_probabilities", "transition_matrix",
]  # fmt: skip
