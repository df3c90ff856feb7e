"""EKF and UKF behind one interface.

Contract
--------
A :class:`Filter` is a predictor and an updater, both pure (state in, new state out):

* ``predict(state, process, t_s) -> state`` — the time update. Both filters share it
  (:func:`robustrtk.estimation.models.predict`, exact for linear dynamics).
* ``update(state, meas, robust=None, prior_scale=None) -> UpdateResult`` — one measurement
  update of the prior, in three stages:

  1. *prior scaling* (the adaptive-factor hook, :mod:`robustrtk.estimation.prior_scale`):
     ``P̄ ← s P̄``, ``G P̄ G`` or ``T P̄ Tᵀ``, the factor given directly or returned by a
     :class:`~robustrtk.estimation.prior_scale.PriorScale` from the nominal prior's
     innovation ``d`` and ``S``. Skipped (bit-identical) when ``prior_scale`` is None;
  2. *linearisation* of the (scaled) prior — the only step where EKF and UKF differ
     (``_linearize`` gives ``ŷ``, ``Pyy − R``, ``Pxy`` and, for the EKF, ``H``);
  3. the *robust policy* (:mod:`robustrtk.estimation.robust`), which decides variance
     factors γ and calls ``solve(γ, keep)`` — the update of that same prior with
     ``R̄ = G R G`` — as often as it needs; policies are therefore usable by every filter.

The :class:`~robustrtk.estimation.state.UpdateResult` diagnostics (innovations, residuals, Δv̄,
factors, prior scale) all come from this single computation. The state operations the
engine needs besides the filter (add/drop/transform/condition/constrain) are methods of
the state (:class:`~robustrtk.estimation.state.State`).

EKF (Joseph form)::

    H = ∂h/∂x(x̄),  S = H P̄ Hᵀ + R̄,  K = P̄ Hᵀ S⁻¹,
    x̂ = x̄ + K (z − h(x̄)),  P̂ = (I − K H) P̄ (I − K H)ᵀ + K R̄ Kᵀ

UKF (Li et al. eqs. 6–10, 15; scaled sigma points via Cholesky)::

    λ = α²(n + κ) − n,  χ = [x̄, x̄ ± √(n+λ) colᵢ(chol P̄)]
    W0m = λ/(n+λ), W0c = W0m + 1 − α² + β, Wi = 1/(2(n+λ))
    ŷ = Σ Wm h(χ),  Pyy = Σ Wc (h(χ) − ŷ)(·)ᵀ + R̄,  Pxy = Σ Wc (χ − x̄)(h(χ) − ŷ)ᵀ
    K = Pxy Pyy⁻¹,  x̂ = x̄ + K (z − ŷ),  P̂ = P̄ − K Pyy Kᵀ

with ``R̄ = G R G``, ``G = diag(√γ)`` restricted to the rows kept (algorithms.md §2).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from robustrtk.core import BoolArray, FloatArray, identity
from robustrtk.estimation.checks import check_covariance, check_dt
from robustrtk.estimation.models import MeasurementModel, ProcessModel, predict
from robustrtk.estimation.prior_scale import (
    PriorScale,
    PriorScaleLike,
    ScaleFactor,
    apply_prior_scale,
    normalize_factor,
)
from robustrtk.estimation.robust import NoRobust, RobustPolicy, Trial
from robustrtk.estimation.state import GaussianState, UpdateResult


def symmetrize(P: FloatArray) -> FloatArray:
    """``(P + Pᵀ)/2``."""
    return 0.5 * (P + P.T)


def inflate(R: FloatArray, gamma: FloatArray) -> FloatArray:
    """Correlation-preserving inflation ``R̄ = G R G``, ``G = diag(√γ)`` (algorithms.md §2)."""
    g = np.sqrt(gamma)
    return R * (g[:, None] * g[None, :])  # np.outer(g, g)


def situation_of(factors: FloatArray) -> np.ndarray:
    """Situation class per row (Li et al. Table 1): 1 none, 2 down-weighted, 3 rejected."""
    f = np.asarray(factors, float)
    return np.where(np.isinf(f), 3, np.where(f > 1.0, 2, 1)).astype(np.int8)


def _finite(a: FloatArray) -> bool:
    return bool(np.isfinite(a).all())


def _rejected(
    state: GaussianState,
    z: FloatArray,
    R: FloatArray,
    applied: ScaleFactor | None,
    d: FloatArray | None = None,
    S: FloatArray | None = None,
) -> UpdateResult:
    """The update refused as a whole (non-finite prior or measurements, an innovation
    covariance that is not positive definite, a singular system): the state is returned
    unchanged and every row is marked rejected (factor ∞, situation 3)."""
    m = z.shape[0]
    d = np.full(m, np.nan) if d is None else d
    S = R if S is None else S
    factors = np.full(m, np.inf)
    return UpdateResult(
        state=state,
        innovation=d,
        innovation_cov=S,
        residual=d,
        residual_cov=S,
        std_residual=np.full(m, np.nan),
        dv=np.full(m, np.nan),
        factors=factors,
        situation=situation_of(factors),
        n_used=0,
        iterations=0,
        prior_scale=applied,
    )


class Filter(Protocol):
    """What the pipeline needs from a filter."""

    @property
    def name(self) -> str:
        """Short name."""
        ...

    def predict(self, state: GaussianState, process: ProcessModel, t_s: float) -> GaussianState: ...

    def update(
        self,
        state: GaussianState,
        meas: MeasurementModel,
        robust: RobustPolicy | None = None,
        prior_scale: PriorScaleLike | None = None,
    ) -> UpdateResult: ...


class _KalmanBase(ABC):
    name = "base"

    def predict(self, state: GaussianState, process: ProcessModel, t_s: float) -> GaussianState:
        """Time update (exact for linear dynamics; shared by EKF and UKF).

        Raises :class:`ValueError` when ``t_s - state.t_s`` is NaN or negative."""
        check_dt(t_s - state.t_s)
        return predict(state, process, t_s)

    @abstractmethod
    def _linearize(
        self, state: GaussianState, meas: MeasurementModel
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray | None]:
        """``(ŷ, Pyy − R, Pxy, H or None)`` of the prior."""

    def _scaled_prior(
        self,
        state: GaussianState,
        meas: MeasurementModel,
        z: FloatArray,
        R: FloatArray,
        prior_scale: PriorScaleLike,
    ) -> tuple[GaussianState, ScaleFactor]:
        """The prior with the scaled covariance, and the factor applied."""
        raw: ScaleFactor
        if isinstance(prior_scale, PriorScale):
            y0, Pyy_n, _, _ = self._linearize(state, meas)
            raw = prior_scale.scale(state, z - y0, Pyy_n + R, R)
        else:
            raw = prior_scale
        factor = normalize_factor(raw, state.n)
        return state.with_(P=apply_prior_scale(state.P, factor)), factor

    def update(
        self,
        state: GaussianState,
        meas: MeasurementModel,
        robust: RobustPolicy | None = None,
        prior_scale: PriorScaleLike | None = None,
    ) -> UpdateResult:
        """Measurement update with an optional prior scaling and robust policy.

        Parameters
        ----------
        state : GaussianState
            Prior ``(x̄, P̄)``, n states.
        meas : MeasurementModel
            ``z`` (m,), ``R`` (m, m), ``h``.
        robust : RobustPolicy, optional
            Decides the variance factors γ of the rows (default: none).
        prior_scale : float, ndarray or PriorScale, optional
            Applied to ``P̄`` before linearisation (:mod:`robustrtk.estimation.prior_scale`):
            ``s P̄``, ``G P̄ G`` (``G = diag(√g)``), ``T P̄ Tᵀ``, or the factor a
            :class:`~robustrtk.estimation.prior_scale.PriorScale` returns for the
            nominal prior's ``d`` and ``S``. None leaves the update bit-identical to the
            unscaled one.

        Returns
        -------
        UpdateResult
            Posterior and diagnostics (innovations, posterior residuals, Δv̄, factors,
            situations) of this single computation, all for the scaled prior;
            ``prior_scale`` is the factor applied (None when not scaled).

        Raises
        ------
        ValueError
            ``R`` or the prior ``P`` not symmetric or not positive semi-definite
            (:func:`robustrtk.estimation.checks.check_covariance`).
        """
        check_covariance(np.asarray(meas.R, float), "R")
        check_covariance(state.P, "prior P")
        policy: RobustPolicy = robust if robust is not None else NoRobust()
        z = np.asarray(meas.z, float)
        R = np.asarray(meas.R, float)
        applied: ScaleFactor | None = None
        if prior_scale is not None:
            state, applied = self._scaled_prior(state, meas, z, R, prior_scale)
        x0, P0 = state.x, state.P
        m = z.shape[0]
        if not (_finite(x0) and _finite(P0) and _finite(z) and _finite(R)):
            return _rejected(state, z, R, applied)
        try:
            y_hat, Pyy0, Pxy, H_lin = self._linearize(state, meas)
        except (np.linalg.LinAlgError, ValueError):
            return _rejected(state, z, R, applied)
        d = z - y_hat
        S = Pyy0 + R
        if not (_finite(d) and _finite(S) and _finite(Pxy)) or (m and S.diagonal().min() <= 0.0):
            return _rejected(state, z, R, applied, d, S)
        joseph = H_lin is not None
        H: FloatArray
        if H_lin is None:
            # statistical linearisation H = Pxyᵀ P̄⁻¹ (exact for linear models)
            try:
                H = np.linalg.solve(P0, Pxy).T
            except np.linalg.LinAlgError:
                H = np.linalg.lstsq(P0, Pxy, rcond=None)[0].T
        else:
            H = H_lin

        def solve(gamma: FloatArray, keep: BoolArray) -> Trial:
            Rb = inflate(R, gamma)
            if not keep.any():
                return Trial(x0, P0, z - meas.h(x0), Rb + Pyy0)
            if keep.all():  # the same numbers without the row selection's copies
                Rk, Pxy_k, d_k, H_k = Rb, Pxy, d, H
                Sk = Pyy0 + Rb
            else:
                k = np.flatnonzero(keep)
                kc = k[:, None]  # the rows and columns k: np.ix_(k, k) without its checks
                Rk, Pxy_k, d_k, H_k = Rb[kc, k], Pxy[:, k], d[k], H[k]
                Sk = Pyy0[kc, k] + Rk
            K = np.linalg.solve(Sk, Pxy_k.T).T  # K = Pxy S⁻¹
            x = x0 + K @ d_k
            P: FloatArray
            if joseph:
                IKH = identity(P0.shape[0]) - K @ H_k
                P = symmetrize(IKH @ P0 @ IKH.T + K @ Rk @ K.T)
            else:
                P = symmetrize(P0 - K @ Sk @ K.T)
            return Trial(x, P, z - meas.h(x), Rb - H @ P @ H.T)

        try:
            out = policy.run(solve, d, S, R)
        except np.linalg.LinAlgError:
            return _rejected(state, z, R, applied, d, S)
        trial = out.trial
        if not (_finite(trial.x) and _finite(trial.P)):
            return _rejected(state, z, R, applied, d, S)
        return UpdateResult(
            state=state.with_(x=trial.x, P=trial.P),
            innovation=d,
            innovation_cov=S,
            residual=trial.residual,
            residual_cov=trial.residual_cov,
            std_residual=out.std_residual,
            dv=out.dv,
            factors=out.factors,
            situation=situation_of(out.factors),
            n_used=int(np.isfinite(out.factors).sum()),
            iterations=out.iterations,
            prior_scale=applied,
        )


@dataclass
class EKF(_KalmanBase):
    """Extended Kalman filter (linearisation at the prior mean, Joseph-form covariance)."""

    name: str = "ekf"

    def _linearize(
        self, state: GaussianState, meas: MeasurementModel
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray | None]:
        H = meas.jacobian(state.x)
        PHt = state.P @ H.T
        return meas.h(state.x), H @ PHt, PHt, H


def sigma_points(
    x: FloatArray, P: FloatArray, alpha: float = 1.0, beta: float = 2.0, kappa: float = 0.0
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Scaled sigma points and weights (Li et al. eqs. 6–7, algorithms.md §6).

    Parameters
    ----------
    x : ndarray, shape (n,)
    P : ndarray, shape (n, n)
        Must be positive definite (a tiny diagonal jitter is added on failure).
    alpha, beta, kappa : float
        Spread, prior-knowledge and secondary scaling parameters.

    Returns
    -------
    X : ndarray, shape (2n+1, n)
        ``[x, x + √(n+λ) Lᵢ, x − √(n+λ) Lᵢ]`` with ``L = chol(P)`` (lower).
    Wm, Wc : ndarray, shape (2n+1,)
        Mean and covariance weights.
    """
    n = x.shape[0]
    lam = alpha**2 * (n + kappa) - n
    c = n + lam
    try:
        L = np.linalg.cholesky(P)
    except np.linalg.LinAlgError:
        jitter = 1e-12 * max(1.0, float(np.max(np.abs(np.diag(P)))))
        L = np.linalg.cholesky(symmetrize(P) + jitter * np.eye(n))
    D = np.sqrt(c) * L
    X = np.empty((2 * n + 1, n))
    X[0] = x
    X[1 : n + 1] = x + D.T
    X[n + 1 :] = x - D.T
    Wm = np.full(2 * n + 1, 1.0 / (2 * c))
    Wc = Wm.copy()
    Wm[0] = lam / c
    Wc[0] = lam / c + (1 - alpha**2 + beta)
    return X, Wm, Wc


@dataclass
class UKF(_KalmanBase):
    """Unscented Kalman filter (scaled sigma points, Cholesky square root).

    Parameters
    ----------
    alpha, beta, kappa : float
        Sigma-point parameters; defaults α = 1, β = 2, κ = 0.
    """

    alpha: float = 1.0
    beta: float = 2.0
    kappa: float = 0.0
    name: str = "ukf"

    def _linearize(
        self, state: GaussianState, meas: MeasurementModel
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray | None]:
        X, Wm, Wc = sigma_points(state.x, state.P, self.alpha, self.beta, self.kappa)
        Y = meas.h(X)  # (2n+1, m)
        y = Wm @ Y
        dY = Y - y
        dX = X - state.x  # mean of sigma points is x exactly
        Pyy = (dY * Wc[:, None]).T @ dY
        Pxy = (dX * Wc[:, None]).T @ dY
        return y, symmetrize(Pyy), Pxy, None
