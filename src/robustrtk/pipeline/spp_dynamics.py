"""Dynamics of the Kalman SPP: state layout, process model, layout changes and the filter choice."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from functools import lru_cache
from typing import Any, Protocol

import numpy as np

from robustrtk.core import FloatArray, InputError
from robustrtk.estimation.filters import EKF, UKF, Filter
from robustrtk.estimation.state import GaussianState, StateLayout
from robustrtk.geometry.frames import ecef2enu_rotation, ecef2geodetic
from robustrtk.pipeline.config import Config


# ---------------------------------------------------------------------- estimators
def kalman_filter(cfg: Config) -> Filter:
    """The filter named by ``cfg.estimator.filter``: EKF, or UKF with ``ukf_alpha``,
    ``ukf_beta``, ``ukf_kappa``."""
    est = cfg.estimator
    if est.filter == "ekf":
        return EKF()
    if est.filter == "ukf":
        return UKF(alpha=est.ukf_alpha, beta=est.ukf_beta, kappa=est.ukf_kappa)
    raise InputError(f"filter: the Kalman SPP takes ekf or ukf, got {est.filter!r}")


# ---------------------------------------------------------------------- dynamics
def spp_layout(n_systems: int, phase: bool, n_band2: int) -> StateLayout:
    """Fixed blocks of the Kalman SPP state: ``pos``, ``vel``, ``clk``, ``drift``, then
    ``pclk`` (with carrier phase) and ``ifb`` (systems with a second band)."""
    blocks: list[tuple[str, int]] = [("pos", 3), ("vel", 3), ("clk", n_systems), ("drift", 1)]
    if phase:
        blocks.append(("pclk", n_systems))
    if n_band2:
        blocks.append(("ifb", n_band2))
    return StateLayout(blocks=tuple(blocks))


@dataclass(frozen=True)
class SppProcessModel:
    """Dynamics of the Kalman SPP state (:func:`spp_layout` blocks, arc biases after them).

    Over ``dt`` (``a = |dt|``), with ``q_a = Rᵀ diag(σ_h², σ_h², σ_up²) R`` (``R`` the
    ECEF→ENU rotation at ``up_at_m``; ``σ_h² I`` when None)::

        pos, vel : F = [[I, dt I], [0, I]],  Q = q_a [[a³/3, dt²/2], [dt²/2, a]]
        clocks c (clk_s and pclk_s), drift d :  c += dt d,
                   Q_cc' = q_d a³/3 + [c = c'] q_c a,  Q_cd = q_d dt²/2,  Q_dd = q_d a
        ifb, arc biases : random walks (q_ifb a, q_amb a)

    with ``q_c`` = ``q_clk_m2_s`` for code clocks and ``q_phase_clk_m2_s`` for phase clocks.
    """

    sigma_acc_m_s2: float = 3.0
    sigma_acc_up_m_s2: float = 0.5
    q_clk_m2_s: float = 1000.0
    q_phase_clk_m2_s: float = 100.0
    q_drift_m2_s3: float = 10.0
    q_ifb_m2_s: float = 1e-4
    q_amb_m2_s: float = 1e-4
    up_at_m: tuple[float, float, float] | None = None
    name: str = "spp"

    @classmethod
    def of(cls, cfg: Config) -> SppProcessModel:
        """The model with the noise densities of ``cfg``."""
        s = cfg.spp
        return cls(
            sigma_acc_m_s2=cfg.estimator.sigma_acc_m_s2,
            sigma_acc_up_m_s2=s.sigma_acc_up_m_s2,
            q_clk_m2_s=s.q_clk_m2_s,
            q_phase_clk_m2_s=s.q_phase_clk_m2_s,
            q_drift_m2_s3=s.q_drift_m2_s3,
            q_ifb_m2_s=s.q_ifb_m2_s,
            q_amb_m2_s=s.q_amb_m2_s,
        )

    def at(self, pos_m: FloatArray) -> SppProcessModel:
        """The same model with its vertical taken at ECEF ``pos_m``."""
        p = np.asarray(pos_m, float)
        up = (float(p[0]), float(p[1]), float(p[2]))
        key = (self, p[:3].tobytes())  # the bits: a signed zero is another position
        last = _LAST_AT.get("key")
        if last is not None and last == key:
            out: SppProcessModel = _LAST_AT["model"]
            return out
        out = replace(self, up_at_m=up)
        _LAST_AT.update(key=key, model=out)
        return out

    def transition(self, layout: StateLayout, dt_s: float) -> tuple[FloatArray, FloatArray]:
        """``F`` and ``Q`` for the whole state of ``layout`` over ``dt_s`` seconds (new
        arrays; the fixed blocks' part is remembered for the last model, blocks and step:
        an epoch takes it three times, for the integrity test, the linearisation and the
        prior)."""
        n, nf = layout.size, layout.n_fixed
        F_fixed, Q_fixed = self._fixed_transition(layout, dt_s)
        if n == nf:
            return F_fixed.copy(), Q_fixed.copy()
        F = np.eye(n)
        Q = np.zeros((n, n))
        F[:nf, :nf] = F_fixed
        Q[:nf, :nf] = Q_fixed
        r = np.arange(nf, n)
        Q[r, r] = self.q_amb_m2_s * abs(dt_s)
        return F, Q

    def _fixed_transition(self, layout: StateLayout, dt_s: float) -> tuple[FloatArray, FloatArray]:
        """``F`` and ``Q`` of the fixed blocks of ``layout`` (read-only, remembered for the
        last key; the sign of a zero step is part of the key, as ``F`` carries it)."""
        # the vertical by its bits (a signed zero is another position)
        up = None if self.up_at_m is None else np.array(self.up_at_m).tobytes()
        key = (self, up, layout.blocks, dt_s, math.copysign(1.0, dt_s))
        last = _LAST_FIXED.get("key")
        if last is not None and last == key:
            return _LAST_FIXED["F"], _LAST_FIXED["Q"]
        F, Q = self._build_fixed(layout, dt_s)
        F.setflags(write=False)
        Q.setflags(write=False)
        _LAST_FIXED.update(key=key, F=F, Q=Q)
        return F, Q

    def _build_fixed(self, layout: StateLayout, dt_s: float) -> tuple[FloatArray, FloatArray]:
        """``F`` and ``Q`` of the fixed blocks of ``layout`` (the class formulas): the
        position–velocity block of ``Q`` (which depends on the vertical) written into a copy
        of the rest, which depends on the step only (:meth:`_clock_part`)."""
        dt, a = dt_s, abs(dt_s)
        F0, Q0 = self._clock_part(layout.blocks, dt_s)
        F, Q = F0.copy(), Q0.copy()
        p, v = layout.slice("pos"), layout.slice("vel")
        qa = _acceleration_psd(self.up_at_m, self.sigma_acc_m_s2, self.sigma_acc_up_m_s2)
        Q[p, p] = qa * a**3 / 3
        Q[p, v] = Q[v, p] = qa * dt**2 / 2
        Q[v, v] = qa * a
        return F, Q

    def _clock_part(self, blocks: tuple[tuple[str, int], ...], dt_s: float) -> tuple[FloatArray, FloatArray]:
        """``F`` of the fixed blocks and ``Q`` without its position–velocity block (read-only;
        remembered for the last densities, blocks and step)."""
        # every density this part takes, the blocks and the step
        q = (self.q_clk_m2_s, self.q_phase_clk_m2_s, self.q_drift_m2_s3, self.q_ifb_m2_s)
        key = (q, blocks, dt_s, math.copysign(1.0, dt_s))
        last = _LAST_CLOCKS.get("key")
        if last is not None and last == key:
            return _LAST_CLOCKS["F"], _LAST_CLOCKS["Q"]
        layout = StateLayout(blocks=blocks)
        n = layout.n_fixed
        dt, a = dt_s, abs(dt_s)
        F = np.eye(n)
        Q = np.zeros((n, n))
        p, v, d = layout.slice("pos"), layout.slice("vel"), layout.slice("drift").start
        F[p, v] = np.eye(3) * dt
        clocks = list(range(layout.slice("clk").start, layout.slice("clk").stop))
        q_own = [self.q_clk_m2_s] * len(clocks)
        if layout.has("pclk"):
            pc = list(range(layout.slice("pclk").start, layout.slice("pclk").stop))
            clocks += pc
            q_own += [self.q_phase_clk_m2_s] * len(pc)
        ci = np.array(clocks)
        qd = self.q_drift_m2_s3
        F[ci, d] = dt
        Q[np.ix_(ci, ci)] = qd * a**3 / 3 + np.diag(q_own) * a
        Q[ci, d] = Q[d, ci] = qd * dt**2 / 2
        Q[d, d] = qd * a
        if layout.has("ifb"):
            f = layout.slice("ifb")
            Q[f, f] = np.eye(f.stop - f.start) * self.q_ifb_m2_s * a
        F.setflags(write=False)
        Q.setflags(write=False)
        _LAST_CLOCKS.update(key=key, F=F, Q=Q)
        return F, Q


#: The last model of :meth:`SppProcessModel.at` (an epoch asks twice for the same position).
_LAST_AT: dict[str, Any] = {}
#: The last step-only part of :meth:`SppProcessModel._clock_part`.
_LAST_CLOCKS: dict[str, Any] = {}
#: The last fixed-block transition of :meth:`SppProcessModel._fixed_transition`.
_LAST_FIXED: dict[str, Any] = {}


@lru_cache(maxsize=8)
def _acceleration_psd(
    up_at_m: tuple[float, float, float] | None, sigma_h_m_s2: float, sigma_up_m_s2: float
) -> FloatArray:
    """The acceleration spectral density (3, 3) in ECEF (m²/s³): ``sigma_h²`` on the two
    horizontal axes and ``sigma_up²`` on the vertical at ``up_at_m`` (ECEF m; isotropic
    ``sigma_h²`` when None). Remembered for the last few positions: an epoch's time updates
    (the integrity test's, the linearisation's, the prior's) take it at the same one.
    Read-only."""
    acc = np.diag([sigma_h_m_s2**2] * 2 + [sigma_up_m_s2**2])
    if up_at_m is None:
        qa = np.eye(3) * sigma_h_m_s2**2
    else:
        lat, lon, _ = ecef2geodetic(np.asarray(up_at_m, float))
        rot = ecef2enu_rotation(float(lat), float(lon))
        qa = rot.T @ acc @ rot
    qa.setflags(write=False)
    return qa


class TransitionModel(Protocol):
    """Anything with a square ``transition(layout, dt) -> (F, Q)`` (every
    :class:`robustrtk.estimation.models.ProcessModel`, :class:`SppProcessModel`)."""

    def transition(self, layout: StateLayout, dt_s: float) -> tuple[FloatArray, FloatArray]: ...


@dataclass(frozen=True)
class Relayout:
    """A process model that also changes the state's layout.

    ``transition(layout, dt)`` maps a state of ``layout`` onto ``target`` (same fixed
    blocks): the fixed states and the ambiguities present in both follow ``inner``;
    ambiguities absent from ``target`` are dropped (no row); ambiguities new in ``target``
    get a zero row of ``F`` and variance ``start_var``, their value coming from
    :meth:`offset` (``start``). ``extra_var`` adds variance to carried ambiguities (a
    suspected slip); ``restart`` maps a fixed state index to ``(value, variance)``: that
    state forgets its past (zero row of ``F``, no correlation). ``F`` has shape
    ``(target.size, layout.size)``; the prior is ``x̄ = F x + offset``, ``P̄ = F P Fᵀ + Q``
    (:func:`predict_relayout`).
    """

    inner: TransitionModel
    target: StateLayout
    start: Mapping[Any, float] = field(default_factory=dict)
    start_var: float = 1.0e4
    extra_var: Mapping[Any, float] = field(default_factory=dict)
    restart: Mapping[int, tuple[float, float]] = field(default_factory=dict)
    start_var_of: Mapping[Any, float] = field(default_factory=dict)
    name: str = "relayout"

    def transition(self, layout: StateLayout, dt_s: float) -> tuple[FloatArray, FloatArray]:
        if layout.blocks != self.target.blocks:
            raise ValueError("Relayout: the fixed blocks of the two layouts differ")
        F0, Q0 = self.inner.transition(layout, dt_s)
        nf, tgt = layout.n_fixed, self.target
        old = {k: nf + a for a, k in enumerate(layout.amb_keys)}
        dst, src = list(range(nf)), list(range(nf))
        for a, key in enumerate(tgt.amb_keys):
            if key in old:
                dst.append(nf + a)
                src.append(old[key])
            elif key not in self.start:
                raise ValueError(f"Relayout: no start value for the new state {key!r}")
        F = np.zeros((tgt.size, layout.size))
        Q = np.zeros((tgt.size, tgt.size))
        da, sa = np.array(dst), np.array(src)
        F[da] = F0[sa]
        Q[da[:, None], da] = Q0[sa[:, None], sa]  # np.ix_(dst, dst) ← np.ix_(src, src)
        for a, key in enumerate(tgt.amb_keys):
            r = nf + a
            if key in old:
                Q[r, r] += self.extra_var.get(key, 0.0)
            else:
                Q[r, r] = self.start_var_of.get(key, self.start_var)
        for index, (_, var) in self.restart.items():
            F[index, :] = 0.0
            Q[index, :] = 0.0
            Q[:, index] = 0.0
            Q[index, index] = var
        return F, Q

    def offset(self) -> FloatArray:
        """Values of the new ambiguities and restarted states (zero elsewhere)."""
        u = np.zeros(self.target.size)
        for key, val in self.start.items():
            u[self.target.amb_index(key)] = val
        for index, (val, _) in self.restart.items():
            u[index] = val
        return u


def predict_relayout(state: GaussianState, model: Relayout, t_s: float) -> tuple[GaussianState, FloatArray]:
    """Time update onto ``model.target``: ``x̄ = F x + u``, ``P̄ = F P Fᵀ + Q``; returns the
    prior and ``F`` (what a smoother needs)."""
    F, Q = model.transition(state.layout, t_s - state.t_s)
    P = F @ state.P @ F.T + Q
    x = F @ state.x + model.offset()
    return GaussianState(x=x, P=0.5 * (P + P.T), t_s=t_s, layout=model.target), F
