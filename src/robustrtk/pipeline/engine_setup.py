"""What the DD engine is built from: the filter, process model, IMM and adaptive factor of a
configuration, the initial state, and single-epoch helpers (re-referencing a DD group,
innovations, a least-squares position from DD code)."""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from robustrtk.core import FloatArray, InputError, ObsEpoch, Solution, replaced, vector_norm
from robustrtk.estimation.adaptive import AdaptiveFactor, make_adaptive_factor
from robustrtk.estimation.filters import Filter
from robustrtk.estimation.integrity import unmodelled_covariance
from robustrtk.estimation.models import ProcessModel
from robustrtk.estimation.registry import make_filter as make_filter_named
from robustrtk.estimation.registry import make_process_model
from robustrtk.estimation.state import GaussianState, StateLayout
from robustrtk.measurement.dd import DDRangeModel, DDSet
from robustrtk.measurement.doppler_velocity import (
    VelocityModel,
    carry_transition,
    doppler_prediction,
    standing,
)
from robustrtk.measurement.tdcp_carry import Displacement, tdcp_prediction
from robustrtk.measurement.weighting import variance
from robustrtk.pipeline.config import Config

if TYPE_CHECKING:  # the IMM is imported where it runs (the auto dynamics of the code modes)
    from robustrtk.estimation.imm import ImmTracker
    from robustrtk.pipeline.geometry_cache import GeometryCache


def rereference(dd: DDSet, rows: np.ndarray, j: int) -> DDSet:
    """The DDs ``rows`` of one group re-expressed against the transmitter of row ``j``.

    Rows ``i − r`` become ``(i − r) − (j − r) = i − j`` and row ``j − r`` becomes ``r − j``:
    a linear map ``T`` (``z ← T z``, ``R ← T R Tᵀ``, ``D ← T D``) that keeps all the
    information, so a DPL update with all rows is unchanged.
    """
    m = dd.m
    T = np.eye(m)
    T[rows, j] -= 1.0
    T[j, :] = 0.0
    T[j, j] = -1.0
    tx, ref = list(dd.tx), list(dd.ref)
    i_tx, i_ref = dd.i_tx.copy(), dd.i_ref.copy()
    new, old, i_new, i_old = dd.tx[j], dd.ref[j], int(dd.i_tx[j]), int(dd.i_ref[j])
    for k in rows:
        ref[k], i_ref[k] = new, i_new
    tx[j], i_tx[j] = old, i_old
    R = T @ dd.R @ T.T
    return replace(
        dd, labels=tuple(f"{a}-{b}" for a, b in zip(tx, ref, strict=True)), tx=tuple(tx),
        ref=tuple(ref), i_tx=i_tx, i_ref=i_ref, D=T @ dd.D, z=T @ dd.z, R=0.5 * (R + R.T),
    )  # fmt: skip


def make_filter(cfg: Config) -> Filter:
    """EKF or UKF from the configuration."""
    est = cfg.estimator
    if est.filter == "ekf":
        return make_filter_named("ekf")
    if est.filter == "ukf":
        return make_filter_named("ukf", alpha=est.ukf_alpha, beta=est.ukf_beta, kappa=est.ukf_kappa)
    raise InputError(f"filter: {est.filter!r} is not a Kalman filter; the DD engine takes ukf or ekf")


def make_process(cfg: Config) -> ProcessModel:
    """Dynamics from the configuration (ambiguities: constant)."""
    est = cfg.estimator
    if est.dynamics == "static":
        return make_process_model("static", q_m2_s=est.q_static_m2_s)
    cv = est.kinematic_model == "constant-velocity" or (est.kinematic_model == "auto" and cfg.mode == "rtk")
    cv |= est.dynamics == "auto"  # the moving hypothesis needs a velocity
    if cv:
        return make_process_model("constant-velocity", sigma_m_s2=est.sigma_acc_m_s2)
    return make_process_model("random-walk", sigma_m_s=est.sigma_vel_m_s)


def make_adaptive(cfg: Config) -> AdaptiveFactor | None:
    """The adaptive factor of the configuration (None when off)."""
    est = cfg.estimator
    return make_adaptive_factor(est.adaptive, est.adaptive_c0, est.adaptive_c1, est.adaptive_max_iter)


def initial_state(cfg: Config, pos0_m: FloatArray, t_s: float, process: ProcessModel) -> GaussianState:
    """Known-point initialization: position at ``pos0_m`` with ``init_sigma_m``.

    With ``known_point = False`` the position is only an approximation (σ ≥ 1 m) and RTK
    converges from DD code (see :mod:`robustrtk.pipeline.rtk`)."""
    est = cfg.estimator
    layout = StateLayout(blocks=process.blocks())
    n = layout.size
    x = np.zeros(n)
    P = np.zeros((n, n))
    p = layout.slice("pos")
    x[p] = pos0_m
    # without known-point initialization the initial position is only approximate
    sigma0 = est.init_sigma_m if est.known_point else max(est.init_sigma_m, 1.0)
    P[p, p] = np.eye(3) * sigma0**2
    if layout.has("vel"):
        v = layout.slice("vel")
        P[v, v] = np.eye(3) * est.init_sigma_vel_m_s**2
    return GaussianState(x=x, P=P, t_s=t_s, layout=layout)


def innovations(model: DDRangeModel, state: GaussianState) -> tuple[FloatArray, FloatArray]:
    """Innovations ``d = z − h(x̄)`` and their covariance ``S = H P̄ Hᵀ + R`` (linearised)."""
    H = model.jacobian(state.x)
    return model.z - model.h(state.x), H @ state.P @ H.T + model.R


def least_squares_fix(
    model: DDRangeModel, state: GaussianState, iterations: int = 6
) -> tuple[FloatArray, FloatArray] | None:
    """Single-epoch weighted least squares of the position from DD code rows.

    Gauss–Newton from the state's position: ``δx = (Hᵀ R⁻¹ H)⁻¹ Hᵀ R⁻¹ (z − h(x))`` on the
    position block, iterated. Returns the position (3,) and its covariance (3, 3), or None
    when the geometry is singular or the rows are too few.
    """
    p = model.pos_slice
    if len(model.labels) < 4:
        return None
    x = state.x.copy()
    try:
        W = np.linalg.inv(model.R)
        for _ in range(iterations):
            H = model.jacobian(x)[:, p]
            N = H.T @ W @ H
            dx = np.linalg.solve(N, H.T @ W @ (model.z - model.h(x)))
            x[p] = x[p] + dx
            if float(np.linalg.norm(dx)) < 1e-4:
                break
        H = model.jacobian(x)[:, p]
        C = np.linalg.inv(H.T @ W @ H)
    except np.linalg.LinAlgError:
        return None
    if not (np.all(np.isfinite(x[p])) and np.all(np.isfinite(C))):
        return None
    return x[p].copy(), 0.5 * (C + C.T)


def make_imm(cfg: Config) -> ImmTracker | None:
    """The IMM of the ``auto`` dynamics of the code modes (algorithms.md §32): stationary,
    cruising (``sigma_acc_m_s2``) and manoeuvring models; None for other dynamics, for RTK
    and with the RTS smoother on (their ``auto`` is the stationary-first selector: the
    smoother is a one-model smoother and follows the model the selector chose each epoch)."""
    if cfg.estimator.dynamics != "auto" or cfg.mode == "rtk" or cfg.estimator.smoother:
        return None
    from robustrtk.estimation.imm import ImmTracker, make_imm_models

    return ImmTracker(make_imm_models(cfg.estimator.sigma_acc_m_s2, cfg.estimator.q_static_m2_s))


def with_unmodelled_errors(sol: Solution, base_pos_ecef_m: FloatArray) -> Solution:
    """``sol`` (ECEF, a carrier-phase solution) with the unmodelled-error budget added to its
    covariance (algorithms.md §33): only what is reported changes, not the filter."""
    c_u = unmodelled_covariance(vector_norm(sol.pos_m - base_pos_ecef_m), sol.pos_m)
    return replaced(sol, cov_m2=np.asarray(sol.cov_m2, float) + c_u)


def restart_state(state: GaussianState, model: DDRangeModel, cfg: Config) -> GaussianState | None:
    """``state`` re-initialised on the single-epoch least-squares position of ``model``
    (velocity zero); None when there is none.

    Position σ is ``max(init_sigma_m, 10 m)`` about the least-squares point (a loose
    centre, so this epoch's update does not count its data twice); ambiguities are
    dropped (the RTK stage re-adds them from the new position).
    """
    fix = least_squares_fix(model, state)
    if fix is None:
        return None
    pos, _ = fix
    est = cfg.estimator
    state = state.drop_ambiguities(list(state.layout.amb_keys))
    x = state.x.copy()
    P = np.zeros_like(state.P)
    p = state.layout.slice("pos")
    x[p] = pos
    P[p, p] = np.eye(3) * max(est.init_sigma_m, 10.0) ** 2
    if state.layout.has("vel"):
        v = state.layout.slice("vel")
        x[v] = 0.0
        P[v, v] = np.eye(3) * max(est.init_sigma_vel_m_s, 10.0) ** 2
    return state.with_(x=x, P=P)


#: Longest step (s) over which the Doppler velocities carry the position (§44).
DOPPLER_CARRY_MAX_S = 5.0


def row_variances(
    cfg: Config,
    geo: GeometryCache,
    signal: int,
    sigma: float,
    epoch: ObsEpoch,
    pos_m: FloatArray,
    tx_pos: FloatArray,
    kind: str = "code",
) -> FloatArray:
    """Undifferenced variances (m²) of each row of ``epoch`` (signal column ``signal``)
    under the configured weighting, ``sigma`` the configured σ (m).

    ``reported``: the receiver's own σ of each measurement (``kind`` ``"code"``:
    ``code_sigma_m``; ``"phase"``: ``phase_sigma_cyc · λ``), and the ``snr`` model
    where it reports none (algorithms.md § 24).
    """
    w = cfg.measurement.weighting
    if w == "reported":
        k = signal
        rep = epoch.code_sigma_m if kind == "code" else epoch.phase_sigma_cyc
        rep_k = None
        if rep is not None:
            rep_k = rep[:, k] if kind == "code" else rep[:, k] * epoch.wavelength_m[:, k]
        return variance(sigma, "reported", snr_dbhz=epoch.cn0_dbhz[:, k], reported_sigma=rep_k)
    if w == "equal":
        return variance(sigma, "equal", n=epoch.n_tx)
    if w == "elevation":
        return variance(sigma, "elevation", elev_sin2=geo.elevation_sin2(pos_m, tx_pos))
    if w == "distance":
        return variance(sigma, "distance", dist_m=np.linalg.norm(tx_pos - pos_m, axis=1))
    return variance(sigma, "snr", snr_dbhz=epoch.cn0_dbhz[:, signal])


def doppler_carried(
    prev: GaussianState, state: GaussianState, vel: VelocityModel, jerk_m_s3: float
) -> GaussianState | None:
    """The prediction ``state`` replaced by the previous posterior ``prev`` carried to its
    time by the Doppler velocities (:func:`~robustrtk.measurement.doppler_velocity.doppler_prediction`);
    None unless both have the same layout and the step is in (0, :data:`DOPPLER_CARRY_MAX_S`]."""
    dt = state.t_s - prev.t_s
    if prev.layout != state.layout or not 0.0 < dt <= DOPPLER_CARRY_MAX_S:
        return None
    L = state.layout
    x, P = doppler_prediction(prev.x, prev.P, L.slice("pos"), L.slice("vel"), dt, vel.z, vel.R, jerk_m_s3**2)
    return state.with_(x=x, P=P)


#: Acceleration (m/s²) bounding the difference between a step's mean velocity and the
#: velocity at its end, ``a dt/2`` (the velocity of the TDCP carry, §45).
TDCP_CARRY_ACC_M_S2 = 2.0


def carried_prediction(
    prev: GaussianState,
    state: GaussianState,
    disp: Displacement | None,
    vel: VelocityModel | None,
    jerk_m_s3: float,
) -> tuple[GaussianState, VelocityModel | None, FloatArray | None]:
    """The prediction of a moving rover carried from the previous posterior ``prev``: by its
    TDCP displacement ``disp`` (centimetres, §45) when there is one and it moves, else by its
    Doppler velocities ``vel`` (decimetres, §44, when ``jerk_m_s3 > 0`` and it moves); else
    ``state`` unchanged. Returns the prediction, the velocity rows still to update with (None
    once carried) and the carry's transition (None when not carried)."""
    L = state.layout
    dt = state.t_s - prev.t_s
    if disp is not None and not disp.standing and prev.layout == L and abs(disp.dt_s - dt) < 1e-6:
        v = L.slice("vel") if L.has("vel") else None
        x, P, T = tdcp_prediction(prev.x, prev.P, L.slice("pos"), v, disp, TDCP_CARRY_ACC_M_S2)
        return state.with_(x=x, P=P), None, T
    if vel is not None and jerk_m_s3 > 0 and not standing(vel):
        carried = doppler_carried(prev, state, vel, jerk_m_s3)
        if carried is not None:
            return carried, None, carry_transition(L.size, L.slice("pos"), L.slice("vel"), dt)
    return state, vel, None


__all__ = [
    "DOPPLER_CARRY_MAX_S", "TDCP_CARRY_ACC_M_S2", "carried_prediction", "doppler_carried", "initial_state",
    "innovations", "least_squares_fix",
    "make_adaptive", "make_filter", "make_imm", "make_process", "rereference", "restart_state",
    "row_variances", "with_unmodelled_errors",
]  # fmt: skip
