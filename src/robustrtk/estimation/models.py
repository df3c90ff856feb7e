"""Process and measurement models.

Process models are linear (``x_k = F x_{k-1} + w``), so prediction is exact for every
filter (algorithms.md §6: with an identity or linear state function the unscented
prediction equals ``F P Fᵀ + Q``). Measurement models may be nonlinear; they evaluate
``h`` on a batch of states (sigma points) and give a Jacobian for the EKF.

Ambiguity states (if any) are constant with a small random walk ``q_amb_cyc2_s``. A model's
``transition`` covers one layout; adding, dropping or re-referencing ambiguities between
epochs are state operations (:class:`~robustrtk.estimation.state.State`), and the smoother
records their combined linear map with
:func:`robustrtk.estimation.smoother.layout_transition`. Models are available by name
through :mod:`robustrtk.estimation.registry` (their ``name`` attribute).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from robustrtk.core import FloatArray
from robustrtk.core import MeasurementModel as MeasurementModel  # the filters' protocol, re-exported
from robustrtk.estimation.state import GaussianState, StateLayout


class ProcessModel(Protocol):
    """Linear dynamics ``x_k = F(dt) x_{k-1} + w``, ``w ~ N(0, Q(dt))``."""

    @property
    def name(self) -> str:
        """Short name."""
        ...

    def blocks(self) -> tuple[tuple[str, int], ...]:
        """Fixed state blocks this model needs (e.g. ``(("pos", 3), ("vel", 3))``)."""
        ...

    def transition(self, layout: StateLayout, dt_s: float) -> tuple[FloatArray, FloatArray]:
        """``F`` and ``Q`` for the whole state of ``layout`` over ``dt_s`` seconds."""
        ...


def _amb_block(F: FloatArray, Q: FloatArray, layout: StateLayout, q: float, dt: float) -> None:
    nf = layout.n_fixed
    na = len(layout.amb_keys)
    if na:
        F[nf:, nf:] = np.eye(na)
        Q[nf:, nf:] = np.eye(na) * q * abs(dt)


def _position_walk(
    layout: StateLayout, q_m2_s: float, q_amb: float, dt_s: float
) -> tuple[FloatArray, FloatArray]:
    """``F = I``, ``Q = q·|dt|·I`` on the position (static and random-walk models)."""
    n = layout.size
    F = np.eye(n)
    Q = np.zeros((n, n))
    p = layout.slice("pos")
    Q[p, p] = np.eye(3) * q_m2_s * abs(dt_s)
    _amb_block(F, Q, layout, q_amb, dt_s)
    return F, Q


@dataclass(frozen=True)
class StaticModel:
    """Static position: ``F = I``, ``Q = q_m2_s · dt · I`` (tiny)."""

    q_m2_s: float = 1e-8
    q_amb_cyc2_s: float = 0.0
    name: str = "static"

    def blocks(self) -> tuple[tuple[str, int], ...]:
        return (("pos", 3),)

    def transition(self, layout: StateLayout, dt_s: float) -> tuple[FloatArray, FloatArray]:
        return _position_walk(layout, self.q_m2_s, self.q_amb_cyc2_s, dt_s)


@dataclass(frozen=True)
class RandomWalkModel:
    """Kinematic random walk on position: ``F = I``, ``Q = σ_v² dt · I`` with the velocity
    noise given in m/s (``sigma_m_s``), i.e. the position moves by ~σ_v·√dt per step."""

    sigma_m_s: float = 0.1
    q_amb_cyc2_s: float = 0.0
    name: str = "random-walk"

    def blocks(self) -> tuple[tuple[str, int], ...]:
        return (("pos", 3),)

    def transition(self, layout: StateLayout, dt_s: float) -> tuple[FloatArray, FloatArray]:
        return _position_walk(layout, self.sigma_m_s**2, self.q_amb_cyc2_s, dt_s)


#: The latest transitions of :class:`ConstantVelocityModel`: (model, id of the layout,
#: step) -> (the layout, F, Q); an entry serves only its very layout object.
_CV_MEMO: dict[tuple[object, int, float], tuple[StateLayout, FloatArray, FloatArray]] = {}


@dataclass(frozen=True)
class ConstantVelocityModel:
    """Constant velocity with white acceleration noise of spectral density ``sigma_m_s2²``:

    ``F = [[I, dt I], [0, I]]``, ``Q = [[dt³/3 A, dt²/2 A], [dt²/2 A, dt A]]`` with
    ``A = σ² I``; with ``sigma_up_m_s2`` the acceleration is split about the unit vector
    ``up`` (default z): ``A = σ² (I − u uᵀ) + σ_up² u uᵀ`` (a land vehicle brakes and turns
    hard, but hardly accelerates up or down).
    """

    sigma_m_s2: float = 0.05
    q_amb_cyc2_s: float = 0.0
    name: str = "constant-velocity"
    sigma_up_m_s2: float | None = None
    up: tuple[float, float, float] = (0.0, 0.0, 1.0)

    def accel_psd(self) -> FloatArray:
        """``A`` (3, 3), the white acceleration's spectral density (m²/s³)."""
        q = self.sigma_m_s2**2
        if self.sigma_up_m_s2 is None:
            return q * np.eye(3)
        u = np.asarray(self.up, float)
        u = u / np.linalg.norm(u)
        uu = np.outer(u, u)
        return q * (np.eye(3) - uu) + self.sigma_up_m_s2**2 * uu

    def blocks(self) -> tuple[tuple[str, int], ...]:
        return (("pos", 3), ("vel", 3))

    def transition(self, layout: StateLayout, dt_s: float) -> tuple[FloatArray, FloatArray]:
        # the same layout object over the same step (an epoch loop at a steady rate whose
        # ambiguities did not change) gives the same matrices: copies of the last ones
        key = (self, id(layout), dt_s)
        try:
            hit = _CV_MEMO.get(key) if dt_s != 0.0 else None  # (±0 s: F's signed zeros differ)
        except TypeError:  # a model given unhashable parameters (an array for ``up``)
            return self._transition(layout, dt_s)
        if hit is not None and hit[0] is layout:
            return hit[1].copy(), hit[2].copy()
        F, Q = self._transition(layout, dt_s)
        if dt_s != 0.0:
            if len(_CV_MEMO) >= 8:
                _CV_MEMO.clear()
            _CV_MEMO[key] = (layout, F.copy(), Q.copy())
        return F, Q

    def _transition(self, layout: StateLayout, dt_s: float) -> tuple[FloatArray, FloatArray]:
        n = layout.size
        dt = dt_s
        F = np.eye(n)
        Q = np.zeros((n, n))
        p, v = layout.slice("pos"), layout.slice("vel")
        F[p, v] = np.eye(3) * dt
        A = self.accel_psd()
        Q[p, p] = abs(dt) ** 3 / 3 * A
        Q[p, v] = dt**2 / 2 * A
        Q[v, p] = dt**2 / 2 * A
        Q[v, v] = abs(dt) * A
        _amb_block(F, Q, layout, self.q_amb_cyc2_s, dt_s)
        return F, Q


def predict(state: GaussianState, process: ProcessModel, t_s: float) -> GaussianState:
    """Time update to ``t_s``: ``x̄ = F x``, ``P̄ = F P Fᵀ + Q`` (exact for linear dynamics,
    identical for EKF and UKF)."""
    dt = t_s - state.t_s
    F, Q = process.transition(state.layout, dt)
    x = F @ state.x
    P = F @ state.P @ F.T + Q
    return state.with_(x=x, P=0.5 * (P + P.T), t_s=t_s)


@dataclass(frozen=True)
class LinearMeasurement:
    """``z = H x + v`` (tests, and the linear parts of larger models)."""

    H: FloatArray
    z: FloatArray
    R: FloatArray
    labels: tuple[str, ...] = ()

    def h(self, X: FloatArray) -> FloatArray:
        return np.asarray(X) @ self.H.T

    def jacobian(self, x: FloatArray) -> FloatArray:
        return self.H
