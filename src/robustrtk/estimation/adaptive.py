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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robustrtk.core import FloatArray
from robustrtk.estimation.state import StateLayout

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
    return float(np.median(np.abs(d[ok]) / s[ok]) / MEDIAN_ABS_NORMAL)


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
    "MEDIAN_ABS_NORMAL", "InnovationAdaptiveFactor", "MotionSelector", "StationaryModel",
    "robust_log_likelihood",
    "robust_innovation_ratio", "yang_factor",
]  # fmt: skip
