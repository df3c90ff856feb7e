"""Robust weighting policies, usable by every filter.

A filter exposes one function ``solve(gamma, keep) -> Trial``: the measurement update of
the same prior with the equivalent covariance ``R̄ = G R G`` (``G = diag(√γ)``, which keeps
the correlation coefficients, algorithms.md §2) using only the rows in ``keep`` (rejected
rows, γ = ∞, are removed, never divided by). A policy decides the factors γ from the
innovations and posterior residuals and may call ``solve`` several times. The prior it
sees is the one after any prior scaling (``Filter.update(..., prior_scale=)``): the
innovation covariance ``S`` and every ``solve`` use the scaled ``P̄``.

Policies
--------
* :class:`NoRobust` — standard filter.
* :class:`DeltaVIGG3` — Li et al. (2019) robust UKF: posterior residuals → standardized
  residuals (eq. 12) → error-discriminant statistic Δv̄ (eq. 13) → IGG-III factor
  (eq. 14, k0 = 2, k1 = 8) → equivalent variance → re-update (eq. 15).
* :class:`StdResidualIGG3` — IGG-III on plain standardized posterior residuals.
* :class:`Huber` — Huber's weight on standardized posterior residuals.
* :class:`PrefitIGG3` — smartphone seed pre-fit innovation test (k0 = 2.5, k1 = 7).
* :class:`PostfitIGG3` — smartphone seed post-fit test that inflates only the worst row per
  iteration (k0 = 1.5, k1 = 3).
* :class:`Chain` — apply several policies in turn, factors multiplying.
* :class:`FixedFactors` — given factors, one update (a decision reused on another prior).
"""

from __future__ import annotations

import math
import sys
from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from robustrtk.core import BoolArray, FloatArray


@dataclass(frozen=True)
class Trial:
    """One measurement update of the prior with given factors.

    Attributes
    ----------
    x, P : ndarray
        Posterior mean (n,) and covariance (n, n).
    residual : ndarray, shape (m,)
        Posterior residuals ``v = z − h(x̂)`` for **all** rows (rejected rows included).
    residual_cov : ndarray, shape (m, m)
        ``Cvv = R̄ − H P̂ Hᵀ`` of this update over all rows (rows not used: ``R̄ᵢᵢ`` on the
        diagonal with the nominal variance), used by the post-fit test.
    """

    x: FloatArray
    P: FloatArray
    residual: FloatArray
    residual_cov: FloatArray


SolveFn = Callable[[FloatArray, BoolArray], Trial]


@dataclass(frozen=True)
class RobustOutcome:
    """Result of a policy: final trial, factors and the statistics it used."""

    trial: Trial
    factors: FloatArray
    std_residual: FloatArray
    dv: FloatArray
    iterations: int


def _nan_to_zero(v: FloatArray) -> FloatArray:
    """``np.nan_to_num(v, nan=0.0)`` (NaN → 0, ±inf → ±max float) without its generality,
    which costs more than the factor functions it feeds."""
    out = np.array(v, dtype=np.float64)
    out[np.isnan(out)] = 0.0
    inf = np.isinf(out)
    if inf.any():
        out[inf] = np.copysign(np.finfo(np.float64).max, out[inf])
    return out


def igg3_factor(u: FloatArray | float, k0: float, k1: float) -> FloatArray:
    """IGG-III variance inflation factor γ = 1/w (algorithms.md §1, Li et al. eq. 14).

    .. math::
        γ(u) = 1 \\; (|u| ≤ k_0), \\quad
        γ(u) = \\frac{|u| (k_1 − k_0)^2}{k_0 (k_1 − |u|)^2} \\; (k_0 < |u| ≤ k_1), \\quad
        γ(u) = ∞ \\; (|u| > k_1)

    Parameters
    ----------
    u : array_like
        Standardized statistic (any shape). NaN gives γ = 1.
    k0, k1 : float
        Thresholds, ``0 < k0 < k1``.

    Returns
    -------
    ndarray
        γ ≥ 1 with the shape of ``u`` (``inf`` for rejected).
    """
    if not 0 < k0 < k1:
        raise ValueError(f"IGG-III thresholds need 0 < k0 < k1, got k0={k0}, k1={k1}")
    a = np.abs(np.asarray(u, dtype=float))
    g = np.ones_like(a)
    mid = (a > k0) & (a <= k1)
    with np.errstate(divide="ignore"):
        g[mid] = a[mid] * (k1 - k0) ** 2 / (k0 * (k1 - a[mid]) ** 2)
    g[a > k1] = np.inf
    return g


def igg3_factor_scalar(u: float, k0: float, k1: float) -> float:
    """:func:`igg3_factor` of one value, in plain floats (the same number; a policy that
    inflates one row at a time calls it once per iteration)."""
    if not 0 < k0 < k1:
        raise ValueError(f"IGG-III thresholds need 0 < k0 < k1, got k0={k0}, k1={k1}")
    a = abs(float(u))
    if a > k1:
        return math.inf
    if a > k0:
        t = k1 - a  # squared as the array path squares (a product, not pow)
        den = k0 * (t * t)
        return a * (k1 - k0) ** 2 / den if den != 0.0 else math.inf  # |u| = k1: ∞ as there
    return 1.0  # NaN too


def igg3_weight(u: FloatArray | float, k0: float, k1: float) -> FloatArray:
    """IGG-III equivalent weight w = 1/γ ∈ [0, 1] (0 = rejected)."""
    g = igg3_factor(u, k0, k1)
    with np.errstate(divide="ignore"):
        return np.where(np.isinf(g), 0.0, 1.0 / g)


def huber_factor(u: FloatArray | float, k: float) -> FloatArray:
    """Huber variance inflation γ = |u|/k beyond ``k`` (weight k/|u|), else 1."""
    a = np.abs(np.asarray(u, dtype=float))
    return np.where(a > k, a / k, 1.0)


def standardize(v: FloatArray, Cvv: FloatArray, R: FloatArray | None = None) -> FloatArray:
    """Standardized residuals ``v̄ᵢ = vᵢ / √Cvv[i, i]`` (Li et al. eq. 12).

    NaN where the variance is not positive, or — when ``R`` is given — where the
    redundancy number ``rᵢ = Cvvᵢᵢ / Rᵢᵢ`` is below 1e-4: such a row (e.g. a phase DD
    whose ambiguity was just added) cannot be tested at all.
    """
    d = np.asarray(Cvv).diagonal()
    out = np.empty(v.shape)
    out.fill(np.nan)
    ok = d > 0
    if R is not None:
        ok &= d > 1e-4 * np.asarray(R).diagonal()
    out[ok] = v[ok] / np.sqrt(d[ok])
    return out


def worst_kept_row(v: FloatArray, Cvv: FloatArray, floor: list[float], keep: BoolArray) -> tuple[int, float]:
    """``i = argmax(u)`` and ``u[i]`` of ``u = where(keep, |nan_to_zero(standardize(v, Cvv,
    R))|, 0)`` (``floor`` the list ``1e-4 · diag(R)``): the same numbers, row by row in
    floats (the post-fit loop's test, a few dozen rows many times per epoch).

    Raises :class:`ValueError` for no rows, as ``np.argmax`` does.
    """
    if not len(v):
        raise ValueError("attempt to get argmax of an empty sequence")
    big = sys.float_info.max
    sqrt = math.sqrt
    best_i, best = 0, -1.0
    rows = zip(v.tolist(), np.asarray(Cvv).diagonal().tolist(), floor, keep.tolist(), strict=True)
    for i, (vi, ci, fi, ki) in enumerate(rows):
        a = 0.0
        if ki and ci > 0.0 and ci > fi:
            a = abs(vi / sqrt(ci))
            if a != a:  # NaN -> 0, inf -> the largest float (nan_to_zero)
                a = 0.0
            elif a == math.inf:
                a = big
        if a > best:
            best_i, best = i, a
    return best_i, best


def discriminant_statistic(std_res: FloatArray) -> FloatArray:
    """Error-discriminant statistic Δv̄ (Li et al. eq. 13, algorithms.md §4).

    .. math:: Δ\\bar v_k = \\bar v_k \\Big/ \\Big(\\sum_{j≠k} |\\bar v_j| / (n − 1)\\Big)

    NaN entries are ignored (they are not part of the set). With fewer than 3 valid rows
    the statistic is undefined (NaN); a zero denominator gives ±inf for a non-zero
    numerator and 0 for a zero one.
    """
    v = np.asarray(std_res, dtype=float)
    ok = np.isfinite(v)
    n = int(ok.sum())
    out = np.full(v.shape, np.nan)
    if n < 3:
        return out
    a = np.where(ok, np.abs(v), 0.0)
    others = (a.sum() - a) / (n - 1)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(others > 0, v / np.where(others > 0, others, 1.0), np.sign(v) * np.inf)
    r = np.where((others == 0) & (v == 0), 0.0, r)
    out[ok] = r[ok]
    return out


def nominal_residual_cov(R: FloatArray, S: FloatArray) -> FloatArray:
    """Posterior residual covariance of a Kalman update ``Cvv = R S⁻¹ R`` (= R − H P⁺ Hᵀ)."""
    X = np.linalg.solve(S, R)
    C = R @ X
    return 0.5 * (C + C.T)


class RobustPolicy(Protocol):
    """Decides variance inflation factors for one measurement update."""

    @property
    def name(self) -> str:
        """Short name used in configs and reports."""
        ...

    def run(self, solve: SolveFn, innovation: FloatArray, S: FloatArray, R: FloatArray) -> RobustOutcome:
        """Run the policy.

        Parameters
        ----------
        solve : callable
            ``solve(gamma (m,), keep (m,) bool) -> Trial``.
        innovation : ndarray, shape (m,)
            ``d = z − h(x̄)``.
        S : ndarray, shape (m, m)
            Innovation covariance with the nominal R.
        R : ndarray, shape (m, m)
            Nominal measurement covariance.
        """
        ...


def _same_factors(a: FloatArray, b: FloatArray, rtol: float = 0.05) -> bool:
    """True when two factor vectors take the same decisions (inf where inf, close else)."""
    fa, fb = np.isfinite(a), np.isfinite(b)
    if not np.array_equal(fa, fb):
        return False
    return bool(np.allclose(a[fa], b[fb], rtol=rtol))


def _ones(m: int) -> tuple[FloatArray, BoolArray]:
    return np.ones(m), np.ones(m, dtype=bool)


@dataclass(frozen=True)
class NoRobust:
    """The standard (non-robust) update."""

    name: str = "none"

    def run(self, solve: SolveFn, innovation: FloatArray, S: FloatArray, R: FloatArray) -> RobustOutcome:
        g, keep = _ones(len(innovation))
        trial = solve(g, keep)
        std = standardize(trial.residual, nominal_residual_cov(R, S), R)
        return RobustOutcome(trial, g, std, discriminant_statistic(std), 1)


@dataclass(frozen=True)
class _PosteriorIGG(ABC):
    """Shared loop: factors from the posterior residuals of the latest trial, standardized
    with the nominal ``Cvv``; re-update from the same prior until the factors settle."""

    k0: float = 2.0
    k1: float = 8.0
    max_iter: int = 3
    name: str = "posterior"

    @abstractmethod
    def _factors(self, std: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Factors γ and the statistic they came from, given standardized residuals."""

    def run(self, solve: SolveFn, innovation: FloatArray, S: FloatArray, R: FloatArray) -> RobustOutcome:
        m = len(innovation)
        g, keep = _ones(m)
        trial = solve(g, keep)
        Cvv = nominal_residual_cov(R, S)
        first_std = standardize(trial.residual, Cvv, R)
        g_new, first_stat = self._factors(first_std)
        it = 1
        while it - 1 < self.max_iter and not _same_factors(g_new, g):
            g = g_new
            keep = np.isfinite(g)
            trial = solve(np.where(keep, g, 1.0), keep)
            it += 1
            g_new, _ = self._factors(standardize(trial.residual, Cvv, R))
        return RobustOutcome(trial, g, first_std, first_stat, it)


@dataclass(frozen=True)
class DeltaVIGG3(_PosteriorIGG):
    """Li et al. (2019) robust filter: IGG-III on the error-discriminant statistic Δv̄.

    Parameters
    ----------
    k0, k1 : float
        IGG-III thresholds on |Δv̄| (paper: 2 and 8).
    max_iter : int
        Re-updates after the nominal one (the paper does one).
    source : {"innovation", "posterior"}
        What Δv̄ is computed from. ``"posterior"`` is the paper's literal recipe: the
        posterior residuals of the nominal update, standardized with ``Cvv = R S⁻¹ R``.
        With few DDs and a prior that is not much stronger than the measurements, the
        nominal update smears one gross error over every residual (with 5 transmitters, 4
        DDs and 3 coordinates, a snapshot has redundancy one) and Δv̄ can no longer tell
        which DD is wrong. ``"innovation"`` (default) counts the filter's prior: Δv̄ is
        computed from the standardized innovations ``dᵢ/√Sᵢᵢ``, which a gross error does
        not smear, then the equivalent variances are applied and the update is redone
        once. The reported ``std_residual`` is always the posterior one (for plots).
    """

    name: str = "igg3"
    source: str = "innovation"

    def _factors(self, std: FloatArray) -> tuple[FloatArray, FloatArray]:
        dv = discriminant_statistic(std)
        return igg3_factor(_nan_to_zero(dv), self.k0, self.k1), dv

    def run(self, solve: SolveFn, innovation: FloatArray, S: FloatArray, R: FloatArray) -> RobustOutcome:
        if self.source == "posterior":
            return super().run(solve, innovation, S, R)
        if self.source != "innovation":
            raise ValueError(f"source must be 'innovation' or 'posterior', got {self.source!r}")
        m = len(innovation)
        u = standardize(innovation, S)
        g, dv = self._factors(u)
        keep = np.isfinite(g)
        trial0 = solve(np.ones(m), np.ones(m, dtype=bool))
        std = standardize(trial0.residual, nominal_residual_cov(R, S), R)
        if np.all(g == 1.0) or not keep.any():
            return RobustOutcome(trial0, np.ones(m), std, dv, 1)
        trial = solve(np.where(keep, g, 1.0), keep)
        return RobustOutcome(trial, g, std, dv, 2)


@dataclass(frozen=True)
class StdResidualIGG3(_PosteriorIGG):
    """IGG-III on plain standardized posterior residuals (k0 = 1.5, k1 = 3 typical)."""

    k0: float = 1.5
    k1: float = 3.0
    name: str = "igg3-std"

    def _factors(self, std: FloatArray) -> tuple[FloatArray, FloatArray]:
        g = igg3_factor(_nan_to_zero(std), self.k0, self.k1)
        return g, discriminant_statistic(std)


@dataclass(frozen=True)
class Huber(_PosteriorIGG):
    """Huber's M-estimator weight on standardized posterior residuals (threshold ``k0``)."""

    k0: float = 1.5
    k1: float = np.inf
    name: str = "huber"

    def _factors(self, std: FloatArray) -> tuple[FloatArray, FloatArray]:
        return huber_factor(_nan_to_zero(std), self.k0), discriminant_statistic(std)


@dataclass(frozen=True)
class FixedFactors:
    """Given factors γ applied in one update (γ = ∞ removes the row): the decision of an
    earlier robust run reused on another prior (the adaptive factor's discrepancy pass,
    :class:`robustrtk.estimation.adaptive.StateDiscrepancyFactor`)."""

    factors: tuple[float, ...]
    name: str = "fixed"

    def run(self, solve: SolveFn, innovation: FloatArray, S: FloatArray, R: FloatArray) -> RobustOutcome:
        g = np.asarray(self.factors, float)
        if g.shape != (len(innovation),):
            raise ValueError(f"FixedFactors: {g.size} factors for {len(innovation)} rows")
        keep = np.isfinite(g)
        trial = solve(np.where(keep, g, 1.0), keep)
        std = standardize(trial.residual, nominal_residual_cov(R, S), R)
        return RobustOutcome(trial, g, std, discriminant_statistic(std), 1)


@dataclass(frozen=True)
class PrefitIGG3:
    """Pre-fit innovation test (smartphone seed): ``uᵢ = dᵢ/√Sᵢᵢ``; every row beyond k0 is
    inflated at once by IGG-III (k0 = 2.5, k1 = 7), then one update runs."""

    k0: float = 2.5
    k1: float = 7.0
    name: str = "prefit"

    def run(self, solve: SolveFn, innovation: FloatArray, S: FloatArray, R: FloatArray) -> RobustOutcome:
        u = standardize(innovation, S)
        g = igg3_factor(_nan_to_zero(u), self.k0, self.k1)
        keep = np.isfinite(g)
        if not keep.any():
            keep = np.ones_like(keep)
            g = np.ones_like(g)
        trial = solve(np.where(keep, g, 1.0), keep)
        std = standardize(trial.residual, nominal_residual_cov(R, S), R)
        return RobustOutcome(trial, g, std, discriminant_statistic(std), 1)


@dataclass(frozen=True)
class PostfitIGG3:
    """Post-fit standardized-residual test (smartphone seed, algorithms.md §3).

    After each update, the single row with the largest ``|vᵢ|/√Cvvᵢᵢ`` above k0 (``Cvv`` of
    that update's equivalent covariance) has its factor multiplied by the IGG-III factor;
    the update is redone from the same prior; repeat until no row exceeds k0 or
    ``max_iter`` updates ran. One faulty reference transmitter spoils every DD of its
    group, so the cap must exceed a group's size (default 40).
    """

    k0: float = 1.5
    k1: float = 3.0
    max_iter: int = 40
    name: str = "postfit"
    start: Sequence[float] | None = field(default=None, compare=False)

    def run(self, solve: SolveFn, innovation: FloatArray, S: FloatArray, R: FloatArray) -> RobustOutcome:
        m = len(innovation)
        g = np.ones(m) if self.start is None else np.asarray(self.start, float).copy()
        keep = np.isfinite(g)
        trial = solve(np.where(keep, g, 1.0), keep)
        std0 = standardize(trial.residual, nominal_residual_cov(R, S), R)
        it = 1
        floor = (1e-4 * np.asarray(R).diagonal()).tolist()  # standardize's redundancy floor
        while it < self.max_iter:
            i, u_i = worst_kept_row(trial.residual, trial.residual_cov, floor, keep)
            if u_i <= self.k0 or keep.sum() <= 1:
                break
            g = g.copy()
            g[i] = g[i] * igg3_factor_scalar(u_i, self.k0, self.k1)
            keep = np.isfinite(g)
            trial = solve(np.where(keep, g, 1.0), keep)
            it += 1
        return RobustOutcome(trial, g, std0, discriminant_statistic(std0), it)


@dataclass(frozen=True)
class Chain:
    """Pre-fit then post-fit (the smartphone seed's robust Kalman filter): the factors of
    the first policy are the starting factors of the post-fit loop."""

    prefit: PrefitIGG3 = field(default_factory=PrefitIGG3)
    postfit: PostfitIGG3 = field(default_factory=PostfitIGG3)
    name: str = "prefit+postfit"

    def run(self, solve: SolveFn, innovation: FloatArray, S: FloatArray, R: FloatArray) -> RobustOutcome:
        u = standardize(innovation, S)
        g0 = igg3_factor(_nan_to_zero(u), self.prefit.k0, self.prefit.k1)
        if not np.isfinite(g0).any():
            g0 = np.ones_like(g0)
        post = PostfitIGG3(self.postfit.k0, self.postfit.k1, self.postfit.max_iter, start=tuple(g0.tolist()))
        return post.run(solve, innovation, S, R)


def rejection_threshold(policy: RobustPolicy) -> float:
    """The standardized residual beyond which ``policy`` rejects a row (its ``k1``; a
    pre-fit + post-fit chain: the post-fit test's); ``inf`` for a policy that only
    down-weights (Huber) or does nothing."""
    if isinstance(policy, Chain):
        return float(policy.postfit.k1)
    k1 = getattr(policy, "k1", None)
    return float(k1) if isinstance(k1, int | float) else float("inf")


#: Built-in policy names (:func:`robustrtk.estimation.registry.make_robust_policy`).
POLICY_NAMES = ("none", "igg3", "igg3-std", "huber", "prefit", "postfit", "prefit+postfit")
