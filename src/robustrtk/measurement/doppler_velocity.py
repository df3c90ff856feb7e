"""A receiver's velocity from one epoch of its own Doppler, as a filter measurement.

A code-only filter of a moving receiver has to guess its motion from the dynamics model
and follows its noisy code; the Doppler of the same receiver measures the velocity to
cm/s every epoch, whatever the receiver does. Each epoch with enough Doppler rows on the
used signal (docs/algorithms.md §44):

1. the rows, one per satellite row, ``−λᵢ Dᵢ = uᵢ·(v_satᵢ − v) + ṡᵢ(v) + c ḋt_r − c ḋt_satᵢ``
   (``uᵢ`` the unit vector receiver → satellite, ``ṡᵢ`` the rate of the Sagnac term), with
   the satellite velocity and clock drift a central difference of the transmitter source's
   positions and clocks (:func:`satellite_rates`);
2. a robust weighted least-squares *snapshot* of the receiver velocity ``v`` (ECEF, m/s)
   and one common clock drift ``c ḋt_r`` (m/s; one oscillator drives every signal), rows
   weighted by the tracking-loop noise law of C/N0 (elevation where C/N0 is absent), the
   worst row dropped while the χ² test of the fit fails and that row stands out of the
   others (:func:`velocity_snapshot`), its covariance multiplied by the a-posteriori
   variance factor when that exceeds 1;
3. a linear measurement of the filter's velocity block (:class:`VelocityModel`,
   ``H = [0 I 0]``) stacked with the epoch's other rows.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from robustrtk.core import CLIGHT, BoolArray, FloatArray, IntArray, TransmitterSource
from robustrtk.geometry.los import OMEGA_E_RAD_S
from robustrtk.measurement.chi2 import chi2_ppf
from robustrtk.measurement.undifferenced import ELEV_FLOOR_RAD, cn0_variance

#: Half step (s) of the central difference that gives satellite velocities and clock drifts.
RATE_STEP_S = 0.5
#: C/N0 (dB-Hz) at which the Doppler σ applies (the tracking-loop law's reference).
DOPPLER_CN0_REF_DBHZ = 45.0
#: Probability of the χ² test of the snapshot's fit.
SNAPSHOT_ALPHA = 1e-3
#: A row is dropped only when its residual predicted by the other rows exceeds this many
#: times its predicted σ (scaled by the other rows' variance factor when above 1).
OUTLIER_K = 4.0
#: Condition number of the normal matrix above which the snapshot is refused.
MAX_CONDITION = 1e8
#: Unknowns of the snapshot: velocity (3) and one clock drift.
N_UNKNOWNS = 4
#: Extra rows beyond the unknowns the snapshot needs (after any row is dropped).
MIN_REDUNDANCY = 1


@dataclass(frozen=True)
class DopplerRows:
    """Linear range-rate rows ``y = A [v; c ḋt_r] + e``.

    Attributes
    ----------
    A : ndarray, shape (m, 4)
        ``[−uᵢ + ω/c (−y_sᵢ, x_sᵢ, 0), 1]``.
    y : ndarray, shape (m,)
        ``−λᵢ Dᵢ − uᵢ·v_satᵢ − ω/c (ẋ_sᵢ y_r − ẏ_sᵢ x_r) + c ḋt_satᵢ`` (m/s).
    var_m2_s2 : ndarray, shape (m,)
        Row variances.
    rows : ndarray of int, shape (m,)
        Index of each row in the epoch's rows.
    """

    A: FloatArray
    y: FloatArray
    var_m2_s2: FloatArray
    rows: IntArray

    @property
    def m(self) -> int:
        return int(self.y.shape[0])


@dataclass(frozen=True)
class VelocitySnapshot:
    """One epoch's receiver velocity from its Doppler.

    Attributes
    ----------
    vel_m_s : ndarray, shape (3,)
        Velocity (ECEF, m/s).
    cov_m2_s2 : ndarray, shape (3, 3)
        Its covariance, the a-posteriori variance factor applied when above 1.
    drift_m_s : float
        Receiver clock drift times c (m/s).
    n_used : int
        Rows kept.
    variance_factor : float
        ``σ̂₀²`` of the kept rows.
    """

    vel_m_s: FloatArray
    cov_m2_s2: FloatArray
    drift_m_s: float
    n_used: int
    variance_factor: float


def satellite_rates(
    source: TransmitterSource,
    t_s: float,
    tx_ids: Sequence[str],
    code_m: FloatArray,
    step_s: float = RATE_STEP_S,
) -> tuple[FloatArray, FloatArray]:
    """Satellite velocities and clock drifts from a central difference of ``source``.

    ``v = (r(t + h) − r(t − h)) / 2h`` and ``c ḋt = (c dt(t + h) − c dt(t − h)) / 2h`` with
    the positions and clocks of :meth:`~robustrtk.core.TransmitterSource.positions` (their
    transmission times follow the receiver time; any constant group delay cancels).

    Parameters
    ----------
    source : TransmitterSource
        ECEF satellite positions and clocks.
    t_s : float
        Receiver time tag (s).
    tx_ids : sequence of str, length N
    code_m : ndarray, shape (N,)
        Pseudoranges (m), for the transmission times.
    step_s : float
        Half step ``h`` (s).

    Returns
    -------
    vel_m_s : ndarray, shape (N, 3)
        ECEF (rotating frame) velocities (m/s); NaN where unavailable.
    drift_m_s : ndarray, shape (N,)
        Clock drifts times c (m/s); NaN where unavailable.
    """
    ids = tuple(tx_ids)
    p1, c1 = source.positions(t_s + step_s, ids, code_m)
    p0, c0 = source.positions(t_s - step_s, ids, code_m)
    inv = 0.5 / step_s
    vel = (np.asarray(p1, float) - np.asarray(p0, float)) * inv
    drift = (np.asarray(c1, float) - np.asarray(c0, float)) * inv
    return vel, drift


def doppler_rows(
    doppler_hz: FloatArray,
    wavelength_m: FloatArray,
    cn0_dbhz: FloatArray,
    rx_pos_m: FloatArray,
    sat_pos_m: FloatArray,
    sat_vel_m_s: FloatArray,
    sat_drift_m_s: FloatArray,
    elev_rad: FloatArray,
    use: BoolArray,
    sigma_m_s: float,
) -> DopplerRows:
    """The epoch's range-rate rows (module docstring, step 1) of the rows in ``use`` with a
    finite Doppler, wavelength, satellite state and drift.

    Parameters
    ----------
    doppler_hz, wavelength_m, cn0_dbhz : ndarray, shape (N,)
        Doppler (Hz, positive approaching), carrier wavelength (m), C/N0 (dB-Hz).
    rx_pos_m : ndarray, shape (3,)
        Receiver position (ECEF, m), the linearisation point of ``uᵢ``.
    sat_pos_m, sat_vel_m_s : ndarray, shape (N, 3)
        Satellite positions (m) and velocities (m/s), ECEF.
    sat_drift_m_s : ndarray, shape (N,)
        Satellite clock drifts times c (m/s).
    elev_rad : ndarray, shape (N,)
        Elevations (rad), for rows without C/N0.
    use : ndarray of bool, shape (N,)
    sigma_m_s : float
        Range-rate σ (m/s) at :data:`DOPPLER_CN0_REF_DBHZ` (or at zenith without C/N0).
    """
    D = np.asarray(doppler_hz, float)
    lam = np.asarray(wavelength_m, float)
    sp = np.asarray(sat_pos_m, float)
    sv = np.asarray(sat_vel_m_s, float)
    sd = np.asarray(sat_drift_m_s, float)
    ok = (
        np.asarray(use, bool)
        & np.isfinite(D)
        & np.isfinite(lam)
        & np.all(np.isfinite(sp), axis=1)
        & np.all(np.isfinite(sv), axis=1)
        & np.isfinite(sd)
    )
    rows = np.flatnonzero(ok)
    r = np.asarray(rx_pos_m, float)
    los = sp[rows] - r
    u = los / np.linalg.norm(los, axis=1)[:, None]
    w = OMEGA_E_RAD_S / CLIGHT
    A = np.empty((rows.size, N_UNKNOWNS))
    A[:, 0] = -u[:, 0] - w * sp[rows, 1]
    A[:, 1] = -u[:, 1] + w * sp[rows, 0]
    A[:, 2] = -u[:, 2]
    A[:, 3] = 1.0
    sag = w * (sv[rows, 0] * r[1] - sv[rows, 1] * r[0])
    y = -lam[rows] * D[rows] - np.sum(u * sv[rows], axis=1) - sag + sd[rows]
    cn0 = np.asarray(cn0_dbhz, float)[rows]
    el = np.maximum(np.asarray(elev_rad, float)[rows], ELEV_FLOOR_RAD)
    var = np.where(
        np.isfinite(cn0),
        cn0_variance(sigma_m_s, cn0, DOPPLER_CN0_REF_DBHZ),
        sigma_m_s**2 / np.sin(el) ** 2,
    )
    return DopplerRows(A, y, np.asarray(var, float), rows)


def velocity_snapshot(rows: DopplerRows, alpha: float = SNAPSHOT_ALPHA) -> VelocitySnapshot | None:
    """Robust weighted least squares of ``(v, c ḋt_r)`` from :class:`DopplerRows`.

    While the fit's ``T = Σ wᵢ vᵢ²`` exceeds ``χ²_{1−α}(m − 4)``, the row with the largest
    standardized residual ``|vᵢ|√wᵢ`` is dropped if the fit of the other rows predicts it
    worse than :data:`OUTLIER_K` times its predicted σ, that σ scaled by the other rows'
    variance factor when above 1 (a σ too small for every row makes no row an outlier: the
    variance factor takes care of it), and at least ``4 + MIN_REDUNDANCY`` rows remain.
    The covariance ``(AᵀWA)⁻¹`` of the velocity is multiplied by ``max(1, σ̂₀²)``,
    ``σ̂₀² = T / (m − 4)``.

    Returns
    -------
    VelocitySnapshot or None
        None with fewer than ``4 + MIN_REDUNDANCY`` rows or a normal matrix whose condition
        number exceeds :data:`MAX_CONDITION`.
    """
    need = N_UNKNOWNS + MIN_REDUNDANCY
    if rows.m < need:
        return None
    A, y = rows.A, rows.y
    w = 1.0 / rows.var_m2_s2
    keep = np.ones(rows.m, bool)
    while True:
        fit = _fit(A, y, w, keep)
        if fit is None:
            return None
        x, N, T = fit
        std = (y - A @ x) * np.sqrt(w)
        m = int(keep.sum())
        if T <= chi2_ppf(1.0 - alpha, m - N_UNKNOWNS) or m - 1 < need:
            break
        j = int(np.argmax(np.where(keep, np.abs(std), -1.0)))
        if not _stands_out(A, y, w, keep, j):
            break
        keep[j] = False
    s02 = T / (m - N_UNKNOWNS)
    C = np.linalg.inv(N)[:3, :3] * max(1.0, s02)
    return VelocitySnapshot(x[:3].copy(), 0.5 * (C + C.T), float(x[3]), m, s02)


def _fit(
    A: FloatArray, y: FloatArray, w: FloatArray, keep: BoolArray
) -> tuple[FloatArray, FloatArray, float] | None:
    """Weighted least squares of the kept rows: solution, normal matrix and ``Σ wᵢ vᵢ²``;
    None for a singular or ill-conditioned normal matrix."""
    Ak, wk = A[keep], w[keep]
    N = Ak.T @ (Ak * wk[:, None])
    if not np.all(np.isfinite(N)) or np.linalg.cond(N) > MAX_CONDITION:
        return None
    x = np.linalg.solve(N, Ak.T @ (wk * y[keep]))
    v = y[keep] - Ak @ x
    return x, N, float(np.sum(wk * v * v))


def _stands_out(A: FloatArray, y: FloatArray, w: FloatArray, keep: BoolArray, j: int) -> bool:
    """Row ``j`` against the fit of the other kept rows: its predicted residual beyond
    :data:`OUTLIER_K` times its predicted σ, that σ scaled by the other rows' own variance
    factor when above 1 (a σ too small for every row makes no row an outlier)."""
    others = keep.copy()
    others[j] = False
    fit = _fit(A, y, w, others)
    if fit is None:
        return False
    x, N, T = fit
    dof = int(others.sum()) - N_UNKNOWNS
    s02 = T / dof if dof > 0 else 1.0
    var = (1.0 / w[j] + float(A[j] @ np.linalg.solve(N, A[j]))) * max(1.0, s02)
    return abs(float(y[j] - A[j] @ x)) > OUTLIER_K * np.sqrt(var)


@dataclass(frozen=True)
class VelocityModel:
    """The velocity snapshot as a linear measurement of a state's velocity block.

    ``z = v`` (3,), ``R`` the snapshot's covariance, ``h(x) = x[vel]``."""

    z: FloatArray
    R: FloatArray
    vel_slice: slice
    labels: tuple[str, ...] = ("doppler:vx", "doppler:vy", "doppler:vz")

    def h(self, X: FloatArray) -> FloatArray:
        return np.asarray(X, float)[..., self.vel_slice]

    def jacobian(self, x: FloatArray) -> FloatArray:
        H = np.zeros((3, np.shape(x)[-1]))
        H[:, self.vel_slice] = np.eye(3)
        return H


def carry_transition(n: int, pos: slice, vel: slice, dt_s: float) -> FloatArray:
    """``T`` (n, n) of :func:`doppler_prediction`: identity but ``T[pos, vel] = dt/2 I`` and
    ``T[vel, vel] = 0``."""
    T = np.eye(n)
    T[vel, vel] = 0.0
    T[pos, vel] = 0.5 * dt_s * np.eye(3)
    return T


def doppler_prediction(
    x_prev: FloatArray,
    P_prev: FloatArray,
    pos: slice,
    vel: slice,
    dt_s: float,
    vel_m_s: FloatArray,
    vel_cov_m2_s2: FloatArray,
    q_jerk_m2_s5: float,
) -> tuple[FloatArray, FloatArray]:
    """The position and velocity carried over ``dt_s`` by the Doppler velocity, not by a
    dynamics model (docs/algorithms.md §44).

    ``p = p⁻ + dt/2 (v⁻ + v̂)``, ``v = v̂``: the trapezoid of the previous posterior velocity
    ``v⁻`` and this epoch's snapshot ``v̂``, exact for a constant acceleration. As a linear map
    ``x = T x⁻ + G v̂`` with ``T = [[I, dt/2 I], [0, 0]]``, ``G = [dt/2 I; I]``:
    ``P = T P⁻ Tᵀ + G C_v Gᵀ + diag(q_j dt⁵/120 I, 0)``, the last term the trapezoid's error
    under a white jerk of density ``q_j`` (``e = −∫₀^dt r (dt − r)/2 j(r) dr``). The snapshot
    enters here and nowhere else (no velocity update on the same epoch). Other states are
    held with their covariance and their correlations to the position carried by ``T``.

    Parameters
    ----------
    x_prev : ndarray, shape (n,)
    P_prev : ndarray, shape (n, n)
        Previous posterior.
    pos, vel : slice
        Position (m) and velocity (m/s) blocks.
    dt_s : float
    vel_m_s : ndarray, shape (3,)
    vel_cov_m2_s2 : ndarray, shape (3, 3)
        The snapshot and its covariance.
    q_jerk_m2_s5 : float
        White-jerk density (m²/s⁵).

    Returns
    -------
    x : ndarray, shape (n,)
    P : ndarray, shape (n, n)
    """
    n = int(np.shape(x_prev)[0])
    T = carry_transition(n, pos, vel, dt_s)
    G = np.zeros((n, 3))
    G[pos] = 0.5 * dt_s * np.eye(3)
    G[vel] = np.eye(3)
    v = np.asarray(vel_m_s, float)
    x = T @ np.asarray(x_prev, float) + G @ v
    P = T @ np.asarray(P_prev, float) @ T.T + G @ np.asarray(vel_cov_m2_s2, float) @ G.T
    P[pos, pos] += np.eye(3) * (q_jerk_m2_s5 * dt_s**5 / 120.0)
    return x, 0.5 * (P + P.T)


def standing(model: VelocityModel, alpha: float = SNAPSHOT_ALPHA) -> bool:
    """Does the snapshot say the receiver stands? ``v̂ᵀ C_v⁻¹ v̂ ≤ χ²_{1−α}(3)``: a zero
    velocity is consistent with it."""
    v = np.asarray(model.z, float)
    try:
        t = float(v @ np.linalg.solve(np.asarray(model.R, float), v))
    except np.linalg.LinAlgError:
        return False
    return t <= chi2_ppf(1.0 - alpha, 3)


def doppler_velocity_model(
    source: TransmitterSource,
    t_s: float,
    tx_ids: Sequence[str],
    code_m: FloatArray,
    doppler_hz: FloatArray,
    wavelength_m: FloatArray,
    cn0_dbhz: FloatArray,
    rx_pos_m: FloatArray,
    sat_pos_m: FloatArray,
    elev_rad: FloatArray,
    use: BoolArray,
    vel_slice: slice,
    sigma_m_s: float,
) -> VelocityModel | None:
    """The epoch's :class:`VelocityModel` (module docstring), or None when fewer than
    ``4 + MIN_REDUNDANCY`` rows have a Doppler or the snapshot is refused.

    Arguments as :func:`doppler_rows` and :func:`satellite_rates` (``sat_pos_m`` the
    positions of the epoch's rows at their transmission times); ``vel_slice`` the velocity
    block of the filter's state.
    """
    D = np.asarray(doppler_hz, float)
    use = np.asarray(use, bool) & np.isfinite(D) & np.isfinite(np.asarray(wavelength_m, float))
    if int(np.count_nonzero(use)) < N_UNKNOWNS + MIN_REDUNDANCY:
        return None
    sv, sd = satellite_rates(source, t_s, tx_ids, code_m)
    rows = doppler_rows(D, wavelength_m, cn0_dbhz, rx_pos_m, sat_pos_m, sv, sd, elev_rad, use, sigma_m_s)
    snap = velocity_snapshot(rows)
    if snap is None:
        return None
    return VelocityModel(snap.vel_m_s, snap.cov_m2_s2, vel_slice)


__all__ = [
    "DOPPLER_CN0_REF_DBHZ", "DopplerRows", "MAX_CONDITION", "MIN_REDUNDANCY", "N_UNKNOWNS", "OUTLIER_K",
    "RATE_STEP_S", "SNAPSHOT_ALPHA", "VelocityModel", "VelocitySnapshot", "carry_transition",
    "doppler_prediction",
    "doppler_rows", "doppler_velocity_model", "satellite_rates", "standing", "velocity_snapshot",
]  # fmt: skip
