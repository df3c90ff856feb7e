"""Kalman-filter SPP on code, Doppler and carrier phase, on one or two bands, with RTS smoothing.

State (ECEF, metres; ``n_s`` systems, ``n_b`` systems with a second band)::

    x = [pos(3), vel(3), clk(n_s), drift(1), pclk(n_s), ifb(n_b), N_1 .. N_m]

``clk_s`` is the receiver clock seen by the code of system ``s``; ``pclk_s`` the clock seen
by its carrier phase (a separate state because phones re-estimate the clock bias they apply
to pseudoranges every epoch while the accumulated carrier phase runs on the hardware clock,
so the two differ by tens of metres epoch to epoch); both follow one clock drift ``d``
(m/s). ``ifb_s`` is the receiver's code bias of the second band (L5/E5a, else L2/E5b/B3)
relative to the first; ``N_j`` (m) is the float carrier-phase bias of one continuous arc of
one satellite and band (phase hardware delays, the initial integer and the code–carrier
ionospheric divergence, hence a small random walk).

Observation rows of satellite ``i`` on band ``b`` (frequency ``f_b``, wavelength
``lambda_b``)::

    code    P + c (dt_i − T_GD,b) − I_b − T        = rho_i + clk_s + [b = 2] ifb_s
    phase   lambda_b phi + c dt_i + I_b − T        = rho_i + pclk_s + N_(i,b,arc)
    Doppler −lambda_b D + c ddt_i                   = u_i · (v_i − v) − Sagnac rate + d

with ``rho_i`` the range with the Sagnac term, ``I_b`` Klobuchar scaled by ``(f_1/f_b)^2``
and ``T`` Saastamoinen (:func:`robustrtk.measurement.undifferenced.atmosphere`). Variances
``sigma^2 / sin^2(el)``, times the C/N0 factor when ``kalman_use_cn0``
(:func:`robustrtk.measurement.undifferenced.elevation_cn0_variance`); Doppler rows with
``doppler_weighting = "cn0"`` follow the tracking-loop law ``sigma_ref^2 10^((cn0_ref − cn0)/10)``
(:func:`robustrtk.measurement.undifferenced.cn0_variance`, docs/algorithms.md §19). With
``zupt``, an epoch whose Doppler rows alone give a speed below ``zupt_speed_m_s``
(:func:`doppler_standing`) also gets three zero-velocity rows.

Dynamics (:class:`SppProcessModel`): white acceleration, with separate horizontal and
vertical spectral densities (a road vehicle accelerates far less vertically); clocks driven
by the common drift plus their own white noise; ``ifb`` and ``N`` random walks. A
carrier-phase arc ends (its ``N`` is dropped and a new one starts from the phase minus the
predicted range) when the phase was absent at the previous epoch, when the robust update
rejected it at the previous epoch, or — with ``lli_reset`` — when the loss-of-lock bit is
set; without ``lli_reset`` a loss-of-lock flag only adds ``slip_var_m2`` to ``N`` (phones
set it far more often than the phase actually slips). These layout changes, and the
restart of a clock that jumped, are a :class:`Relayout` around the process model; the
time update is :func:`predict_relayout`. All rows go through one update of the filter
named by ``cfg.estimator.filter`` with the robust policy ``cfg.robust``
(:func:`robustrtk.estimation.registry.make_robust_policy`).

The forward filter records its transitions, so a Rauch–Tung–Striebel pass
(:mod:`robustrtk.estimation.smoother`) can smooth the whole track when
``cfg.estimator.smoother``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from typing import Any, Protocol

import numpy as np

from robustrtk.core import CLIGHT, FloatArray, InputError, ObsBatch
from robustrtk.estimation.adaptive import adaptive_update, make_adaptive_factor
from robustrtk.estimation.filters import EKF, UKF, Filter
from robustrtk.estimation.integrity import (
    IntegrityEvent,
    IntegrityMonitor,
    IntegrityPolicy,
    Snapshot,
    covariance_floor,
    widen,
)
from robustrtk.estimation.models import LinearMeasurement
from robustrtk.estimation.registry import make_robust_policy
from robustrtk.estimation.smoother import FilterStep, rts_smooth
from robustrtk.estimation.state import GaussianState, StateLayout
from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.geometry.frames import ecef2enu_rotation, ecef2geodetic
from robustrtk.geometry.los import OMEGA_E_RAD_S, geometric_range
from robustrtk.io.rinex_nav import NavData
from robustrtk.measurement.chi2 import chi2_ppf
from robustrtk.measurement.corrections import F_L1_HZ
from robustrtk.measurement.undifferenced import (
    EpochGeometry,
    atmosphere,
    carrier_frequency,
    cn0_variance,
    elevation_cn0_variance,
    lsq_fde,
)
from robustrtk.pipeline.config import Config, preset
from robustrtk.pipeline.results import notify_progress
from robustrtk.pipeline.spp_common import (
    BAND1_PREFERENCE,
    SppEpoch,
    lsq_settings,
    nav_and_source,
    unsolved_epoch,
)

#: Second band per system, in order of preference (L5/E5a first: ten times the chip rate
#: of L1 C/A, so far less code multipath on phones).
BAND2_PREFERENCE: dict[str, tuple[str, ...]] = {
    "G": ("5", "2"),
    "J": ("5", "2"),
    "E": ("5", "7"),
    "C": ("7", "6"),
    "R": ("2",),
    "S": ("5",),
    "I": (),
}
#: Carrier phases with ``|phi|`` below this (cycles) are treated as absent: Android
#: converters write 0 where the accumulated delta range is invalid.
PHASE_ZERO_CYC = 1e-3
#: Prior variance of the phase clock when the filter starts (m^2); its common mode with
#: the carrier-phase biases is not observable, so any finite value serves.
PHASE_CLOCK_VAR0_M2 = 1.0e2

AmbKey = tuple[str, int, int]  # (transmitter, band index 0/1, arc number)


# ---------------------------------------------------------------------- signals
@dataclass(frozen=True)
class Signals:
    """Columns of the two bands per transmitter, pulled out of a batch.

    Attributes
    ----------
    systems : tuple of str
        Systems with ephemerides and at least one chosen column, sorted.
    rows : ndarray of int, shape (N',)
        Batch transmitter indices kept.
    ids, sys : tuple of str, length N'
    band : tuple of (str, str)
        Band digit of columns 0 and 1 of each kept transmitter (``""`` when absent).
    code_m, phase_cyc, doppler_hz, cn0_dbhz, lli : ndarray, shape (T, N', 2)
    wavelength_m : ndarray, shape (N', 2)
    """

    systems: tuple[str, ...]
    rows: np.ndarray
    ids: tuple[str, ...]
    sys: tuple[str, ...]
    band: tuple[tuple[str, str], ...]
    code_m: FloatArray
    phase_cyc: FloatArray
    doppler_hz: FloatArray
    cn0_dbhz: FloatArray
    lli: FloatArray
    wavelength_m: FloatArray


def spp_signals(batch: ObsBatch, nav: NavData, dual_frequency: bool, systems: str | None = None) -> Signals:
    """Per system, the first band-1 column with code (:data:`BAND1_PREFERENCE`) and, when
    ``dual_frequency``, the first second-band column with code (:data:`BAND2_PREFERENCE`).

    A batch reduced by :func:`robustrtk.pipeline.spp_common.select_band1` (``signals == ("1",)``)
    gives band 1 only. Systems without ephemeris records, or not in ``systems`` (letters,
    all when None), are dropped.
    """
    sys_arr = np.array(batch.system)
    T = len(batch)
    single = batch.signals == ("1",)

    def pick(rows: np.ndarray, bands: tuple[str, ...]) -> int:
        for band in bands:
            for k, sig in enumerate(batch.signals):
                if sig[:1] == band and np.isfinite(batch.code_m[:, rows, k]).any():
                    return k
        return -1

    keep: list[int] = []
    cols: list[tuple[int, int]] = []
    used: list[str] = []
    for s in dict.fromkeys(batch.system):
        if nav.n_records(s) == 0 or (systems is not None and s not in systems):
            continue
        rows = np.flatnonzero(sys_arr == s)
        k1 = 0 if single else pick(rows, BAND1_PREFERENCE.get(s, ("1",)))
        k2 = -1 if (single or not dual_frequency) else pick(rows, BAND2_PREFERENCE.get(s, ()))
        if k1 < 0 and k2 < 0:
            continue
        used.append(s)
        keep.extend(rows.tolist())
        cols.extend([(k1, k2)] * rows.size)
    order = np.argsort(keep, kind="stable")
    r = np.asarray(keep, dtype=np.int64)[order]
    c = np.asarray(cols, dtype=np.int64).reshape(-1, 2)[order]
    n = r.size

    def take(a: np.ndarray) -> FloatArray:
        out = np.full((T, n, 2), np.nan)
        for b in range(2):
            ok = c[:, b] >= 0
            out[:, ok, b] = a[:, r[ok], c[ok, b]]
        return out

    wl = np.full((n, 2), np.nan)
    bands: list[tuple[str, str]] = []
    for q in range(n):
        pair = []
        for b in range(2):
            if c[q, b] >= 0:
                wl[q, b] = batch.wavelength_m[r[q], c[q, b]]
                pair.append("1" if single else batch.signals[c[q, b]][:1])
            else:
                pair.append("")
        bands.append((pair[0], pair[1]))
    phase = take(batch.phase_cyc)
    phase[np.abs(phase) < PHASE_ZERO_CYC] = np.nan
    return Signals(
        systems=tuple(sorted(used)),
        rows=r,
        ids=tuple(batch.tx_ids[i] for i in r),
        sys=tuple(batch.system[i] for i in r),
        band=tuple(bands),
        code_m=take(batch.code_m),
        phase_cyc=phase,
        doppler_hz=take(batch.doppler_hz),
        cn0_dbhz=take(batch.cn0_dbhz),
        lli=take(batch.lli),
        wavelength_m=wl,
    )


# ---------------------------------------------------------------------- zero velocity
def doppler_standing(
    A: FloatArray, y: FloatArray, var_m2_s2: FloatArray, vel_lin_m_s: FloatArray, speed_m_s: float
) -> bool:
    """Does one epoch's Doppler say the receiver stands? (docs/algorithms.md §19)

    Weighted least squares of ``y = A (δv, δd) + e`` (range-rate innovations at the
    linearisation velocity ``vel_lin_m_s``; ``A`` rows ``[−u_r, 1]``); while the chi-square
    test ``Σ w_r v_r² > χ²_0.999(m − 4)`` fails, the row with the largest ``|v_r|/σ_r`` is
    dropped, keeping at least five.

    Parameters
    ----------
    A : ndarray, shape (m, 4)
    y : ndarray, shape (m,)
        Innovations (m/s).
    var_m2_s2 : ndarray, shape (m,)
    vel_lin_m_s : ndarray, shape (3,)
        ECEF velocity the rows were linearised at.
    speed_m_s : float
        Standing means ``|vel_lin + δv| < speed_m_s``.

    Returns
    -------
    bool
        False also when fewer than five rows remain, the normal matrix is singular or the
        test never passes.
    """
    m0 = int(np.shape(y)[0])
    if m0 < 5:
        return False
    w = 1.0 / np.asarray(var_m2_s2, float)
    keep = np.ones(m0, bool)
    while True:
        Aw = A[keep] * w[keep, None]
        N = A[keep].T @ Aw
        if np.linalg.cond(N) > 1e12:
            return False
        delta = np.linalg.solve(N, Aw.T @ y[keep])
        res = y - A @ delta
        m = int(keep.sum())
        if float(np.sum(res[keep] ** 2 * w[keep])) <= chi2_ppf(0.999, m - 4):
            break
        if m <= 5:
            return False
        keep[int(np.argmax(np.where(keep, np.abs(res) * np.sqrt(w), -1.0)))] = False
    return float(np.linalg.norm(np.asarray(vel_lin_m_s, float) + delta[:3])) < speed_m_s


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
        return replace(self, up_at_m=(float(p[0]), float(p[1]), float(p[2])))

    def transition(self, layout: StateLayout, dt_s: float) -> tuple[FloatArray, FloatArray]:
        """``F`` and ``Q`` for the whole state of ``layout`` over ``dt_s`` seconds."""
        n, nf = layout.size, layout.n_fixed
        dt, a = dt_s, abs(dt_s)
        F = np.eye(n)
        Q = np.zeros((n, n))
        p, v, d = layout.slice("pos"), layout.slice("vel"), layout.slice("drift").start
        F[p, v] = np.eye(3) * dt
        acc = np.diag([self.sigma_acc_m_s2**2] * 2 + [self.sigma_acc_up_m_s2**2])
        if self.up_at_m is None:
            qa = np.eye(3) * self.sigma_acc_m_s2**2
        else:
            lat, lon, _ = ecef2geodetic(np.asarray(self.up_at_m, float))
            rot = ecef2enu_rotation(float(lat), float(lon))
            qa = rot.T @ acc @ rot
        Q[p, p] = qa * a**3 / 3
        Q[p, v] = Q[v, p] = qa * dt**2 / 2
        Q[v, v] = qa * a
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
        for r in range(nf, n):
            Q[r, r] = self.q_amb_m2_s * a
        return F, Q


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
        F[dst] = F0[src]
        Q[np.ix_(dst, dst)] = Q0[np.ix_(src, src)]
        for a, key in enumerate(tgt.amb_keys):
            r = nf + a
            if key in old:
                Q[r, r] += self.extra_var.get(key, 0.0)
            else:
                Q[r, r] = self.start_var
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


# ---------------------------------------------------------------------- epoch geometry
@dataclass
class _Sats:
    """Satellite states of one epoch (rows = transmitters with code and ephemeris)."""

    idx: np.ndarray  # indices into Signals
    t_tx_s: FloatArray
    pos_m: FloatArray
    vel_m_s: FloatArray
    clk_m: FloatArray  # c dt, no group delay
    drift_m_s: FloatArray
    tgd_m: FloatArray  # (n, 2) c T_GD of each band (NaN when not covered)


def _sat_states(sig: Signals, i: int, t_s: float, eph: EphemerisSource) -> _Sats:
    code = sig.code_m[i]
    tt = np.where(np.isfinite(code[:, 0]), code[:, 0], code[:, 1])
    idx = np.flatnonzero(np.isfinite(tt))
    ids = [sig.ids[j] for j in idx]
    if idx.size == 0:
        z = np.zeros((0, 3))
        return _Sats(idx, np.zeros(0), z, z, np.zeros(0), np.zeros(0), np.zeros((0, 2)))
    t_tx = eph.transmission_time(t_s, ids, tt[idx])
    pos, vel, clk, drift, ok = eph.sat_states(t_tx, ids)
    tgd = np.full((idx.size, 2), np.nan)
    for b in range(2):
        for band in {sig.band[j][b] for j in idx} - {""}:
            sel = np.array([sig.band[j][b] == band for j in idx])
            tgd[sel, b] = eph.group_delay_s(t_tx[sel], [ids[q] for q in np.flatnonzero(sel)], band)
    ok &= np.isfinite(clk)
    return _Sats(idx[ok], t_tx[ok], pos[ok], vel[ok], clk[ok] * CLIGHT, drift[ok] * CLIGHT, tgd[ok] * CLIGHT)


def _lsq_geometry(sig: Signals, i: int, sats: _Sats) -> EpochGeometry:
    """Band-1 code of the epoch in the form the least-squares SPP takes."""
    code1 = sig.code_m[i, sats.idx, 0]
    sel = np.isfinite(code1) & np.isfinite(sats.tgd_m[:, 0])
    j = sats.idx[sel]
    wl = sig.wavelength_m[j, 0]
    return EpochGeometry(
        ids=tuple(sig.ids[q] for q in j),
        sys=tuple(sig.sys[q] for q in j),
        code_m=code1[sel],
        cn0_dbhz=sig.cn0_dbhz[i, j, 0],
        rate_m_s=-wl * sig.doppler_hz[i, j, 0],
        freq_hz=carrier_frequency(wl),
        sat_pos_m=sats.pos_m[sel],
        sat_vel_m_s=sats.vel_m_s[sel],
        sat_clk_m=sats.clk_m[sel] - sats.tgd_m[sel, 0],
        sat_drift_m_s=sats.drift_m_s[sel],
        ok=np.ones(int(sel.sum()), bool),
    )


# ---------------------------------------------------------------------- rows
@dataclass
class _Rows:
    """Linearised observation rows at the prior (``d`` is the innovation ``z − h(x̄)``)."""

    d: list[float]
    H: list[FloatArray]
    var: list[float]
    labels: list[str]
    kind: list[str]  # "P", "L", "D"
    system: list[str]
    amb: list[AmbKey | None]

    def add(
        self, d: float, H: FloatArray, var: float, label: str, kind: str, s: str, amb: AmbKey | None
    ) -> None:
        self.d.append(float(d))
        self.H.append(H)
        self.var.append(float(var))
        self.labels.append(label)
        self.kind.append(kind)
        self.system.append(s)
        self.amb.append(amb)


class _KalmanSpp:
    """State bookkeeping of one Kalman SPP run: indices, arcs, initial state, rows."""

    def __init__(self, sig: Signals, eph: EphemerisSource, cfg: Config) -> None:
        self.sig, self.eph, self.nav, self.cfg = sig, eph, eph.nav, cfg
        self.systems = list(sig.systems)
        self.band2_systems = sorted({sig.sys[j] for j in range(len(sig.ids)) if sig.band[j][1]})
        self.fixed = spp_layout(len(self.systems), cfg.spp.use_phase, len(self.band2_systems))
        self.mask_rad = np.deg2rad(cfg.gnss.elev_mask_deg)
        self.arc: dict[tuple[str, int], int] = {}  # current arc number per (tx, band)
        self.last_seen: dict[tuple[str, int], int] = {}  # epoch index of the last phase
        self.restart: set[tuple[str, int]] = set()  # phases rejected: new arc next epoch

    # --------------------------------------------------------------- indices
    def _i(self, block: str, k: int = 0) -> int:
        return self.fixed.slice(block).start + k

    def clk_index(self, s: str) -> int:
        return self._i("clk", self.systems.index(s))

    def pclk_index(self, s: str) -> int:
        return self._i("pclk", self.systems.index(s))

    def ifb_index(self, s: str) -> int:
        return self._i("ifb", self.band2_systems.index(s))

    def initial_state(
        self, t: float, pos: FloatArray, pos_cov: FloatArray, clk: dict[str, float]
    ) -> GaussianState:
        L = self.fixed
        x = np.zeros(L.n_fixed)
        P = np.zeros((L.n_fixed, L.n_fixed))
        p, v, d = L.slice("pos"), L.slice("vel"), L.slice("drift").start
        x[p] = pos
        P[p, p] = pos_cov + np.eye(3)
        P[v, v] = np.eye(3) * 30.0**2
        for s in self.systems:
            c = self.clk_index(s)
            x[c] = clk.get(s, 0.0)
            P[c, c] = 1e2 if s in clk else 1e8
            if L.has("pclk"):
                P[self.pclk_index(s), self.pclk_index(s)] = PHASE_CLOCK_VAR0_M2
        P[d, d] = 1e4
        if L.has("ifb"):
            f = L.slice("ifb")
            P[f, f] = np.eye(f.stop - f.start) * 1e8
        return GaussianState(x=x, P=P, t_s=t, layout=L)

    # --------------------------------------------------------------- rows
    def build_rows(
        self, i: int, t: float, sats: _Sats, x: FloatArray, n: int
    ) -> tuple[_Rows, dict[AmbKey, float], list[AmbKey]]:
        """Rows at the prior ``x`` (fixed part valid; ambiguity values looked up later).

        Returns the rows (phase innovations without their ``N``), the initial value of each
        new arc's ``N`` and the keys of arcs that continue with a loss-of-lock flag.
        """
        cfg, sig = self.cfg, self.sig
        spp, meas = cfg.spp, cfg.measurement
        rows = _Rows([], [], [], [], [], [], [])
        new_amb: dict[AmbKey, float] = {}
        suspect: list[AmbKey] = []
        if sats.idx.size == 0:
            return rows, new_amb, suspect
        L = self.fixed
        p, v, d = L.slice("pos"), L.slice("vel"), L.slice("drift").start
        pos, vel = x[p], x[v]
        atm = atmosphere(t, sats.pos_m, pos, self.nav, meas.tropo, meas.iono)
        el, trop, iono1 = atm.el_rad, atm.tropo_m, atm.iono_m
        rng, u = geometric_range(sats.pos_m, pos)
        sp, sv = sats.pos_m, sats.vel_m_s
        sag_rate = (
            OMEGA_E_RAD_S
            / CLIGHT
            * (sv[:, 1] * pos[0] + sp[:, 1] * vel[0] - sv[:, 0] * pos[1] - sp[:, 0] * vel[1])
        )
        for q, j in enumerate(sats.idx):
            if el[q] < self.mask_rad:
                continue
            s, tx = sig.sys[j], sig.ids[j]
            doppler_done = False
            for b in range(2):
                band = sig.band[j][b]
                if not band:
                    continue
                lam = float(sig.wavelength_m[j, b])
                f = CLIGHT / lam if np.isfinite(lam) else (F_L1_HZ if b == 0 else np.nan)
                iono = float(iono1[q]) * (F_L1_HZ / f) ** 2 if np.isfinite(f) else np.nan
                cn0 = sig.cn0_dbhz[i, j, b]
                if cn0 < meas.snr_mask_dbhz:
                    continue

                def var(sigma: float, q: int = q, cn0: float = cn0) -> float:
                    c = np.array([cn0]) if spp.kalman_use_cn0 else None
                    return float(
                        elevation_cn0_variance(sigma, el[q : q + 1], c, cn0_ref_dbhz=spp.cn0_ref_dbhz)[0]
                    )

                code = sig.code_m[i, j, b]
                if np.isfinite(code) and np.isfinite(sats.tgd_m[q, b]) and np.isfinite(iono):
                    Hr = np.zeros(n)
                    Hr[p] = -u[q]
                    Hr[self.clk_index(s)] = 1.0
                    h0 = rng[q] + x[self.clk_index(s)]
                    if b == 1:
                        Hr[self.ifb_index(s)] = 1.0
                        h0 += x[self.ifb_index(s)]
                    z = code + sats.clk_m[q] - sats.tgd_m[q, b] - iono - trop[q]
                    rows.add(z - h0, Hr, var(meas.code_sigma_m), f"{tx}:P{band}", "P", s, None)
                dop = sig.doppler_hz[i, j, b]
                if spp.use_doppler and not doppler_done and np.isfinite(dop) and np.isfinite(lam):
                    doppler_done = True
                    Hr = np.zeros(n)
                    Hr[v] = -u[q]
                    Hr[d] = 1.0
                    z = -lam * dop + sats.drift_m_s[q]
                    h0 = float(u[q] @ (sv[q] - vel)) - sag_rate[q] + x[d]
                    if spp.doppler_weighting == "cn0":
                        vd = float(cn0_variance(spp.doppler_cn0_sigma_m_s, cn0, spp.cn0_ref_dbhz))
                    else:
                        vd = var(spp.doppler_sigma_m_s)
                    rows.add(z - h0, Hr, vd, f"{tx}:D{band}", "D", s, None)
                phase = sig.phase_cyc[i, j, b]
                if spp.use_phase and np.isfinite(phase) and np.isfinite(lam) and np.isfinite(iono):
                    z = lam * phase + sats.clk_m[q] + iono - trop[q]
                    h0 = rng[q] + x[self.pclk_index(s)]
                    sb = (tx, b)
                    lli = sig.lli[i, j, b]
                    lost = bool(np.isfinite(lli) and int(lli) & 1)
                    cont = (
                        sb in self.arc
                        and self.last_seen.get(sb) == i - 1
                        and sb not in self.restart
                        and not (lost and spp.lli_reset)
                    )
                    if not cont:
                        self.arc[sb] = self.arc.get(sb, -1) + 1
                    key: AmbKey = (tx, b, self.arc[sb])
                    if not cont:
                        new_amb[key] = z - h0
                    elif lost:
                        suspect.append(key)
                    self.last_seen[sb] = i
                    Hr = np.zeros(n)
                    Hr[p] = -u[q]
                    Hr[self.pclk_index(s)] = 1.0
                    rows.add(z - h0, Hr, var(meas.phase_sigma_m), f"{tx}:L{band}", "L", s, key)
        self.restart.clear()
        return rows, new_amb, suspect

    def zupt_rows(self, rows: _Rows, x_lin: FloatArray, n: int) -> bool:
        """Append three zero-velocity rows (kind ``"Z"``, labels ``ZUPT:vx|vy|vz``, each
        ``0 − v_k`` with σ ``zupt_sigma_m_s``) when :func:`doppler_standing` says the
        epoch's Doppler rows show a standing receiver. Returns whether they were added."""
        spp = self.cfg.spp
        sel = [r for r in range(len(rows.d)) if rows.kind[r] == "D"]
        L = self.fixed
        v, d = L.slice("vel"), L.slice("drift").start
        cols = [v.start, v.start + 1, v.start + 2, d]
        A = np.array([rows.H[r][cols] for r in sel]).reshape(len(sel), 4)
        y = np.array([rows.d[r] for r in sel])
        var = np.array([rows.var[r] for r in sel])
        if not doppler_standing(A, y, var, x_lin[v], spp.zupt_speed_m_s):
            return False
        for k, axis in enumerate("xyz"):
            Hr = np.zeros(n)
            Hr[v.start + k] = 1.0
            rows.add(-float(x_lin[v.start + k]), Hr, spp.zupt_sigma_m_s**2, f"ZUPT:v{axis}", "Z", "", None)
        return True

    def clock_restarts(
        self, rows: _Rows, d: FloatArray, x_prior: FloatArray, new_amb: Mapping[AmbKey, float]
    ) -> dict[int, tuple[float, float]]:
        """Clocks whose per-system median innovation (code; phase of continuing arcs) is
        beyond ``clock_reset_m``: state index -> (restart value, variance)."""
        out: dict[int, tuple[float, float]] = {}
        m = len(rows.d)
        for kind in ("P", "L") if self.cfg.spp.use_phase else ("P",):
            for s in self.systems:
                sel = [
                    r
                    for r in range(m)
                    if rows.kind[r] == kind
                    and rows.system[r] == s
                    and (kind == "P" or rows.amb[r] not in new_amb)
                ]
                if not sel:
                    continue
                med = float(np.median(d[sel]))
                if abs(med) > self.cfg.spp.clock_reset_m:
                    c = self.clk_index(s) if kind == "P" else self.pclk_index(s)
                    out[c] = (float(x_prior[c]) + med, 1e4)
        return out


def _design(
    rows: _Rows, layout: StateLayout, x_prior: FloatArray, x_lin: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Design matrix over ``layout`` and innovations at ``x_prior`` (rows were linearised
    at the fixed part ``x_lin``; the model is linear in every state but the position)."""
    nf = layout.n_fixed
    H = np.zeros((len(rows.d), layout.size))
    H[:, :nf] = np.array(rows.H).reshape(len(rows.d), nf)
    d = np.asarray(rows.d) - H[:, :nf] @ (x_prior[:nf] - x_lin)
    for r, key in enumerate(rows.amb):
        if key is not None:
            a = layout.amb_index(key)
            H[r, a] = 1.0
            d[r] -= x_prior[a]
    return H, d


def solve_spp_kalman(
    batch: ObsBatch,
    nav: NavData | EphemerisSource,
    cfg: Config | None = None,
    progress: Callable[[int, int], None] | None = None,
    systems: str | None = None,
    integrity: IntegrityPolicy | None = None,
    events: list[tuple[float, IntegrityEvent]] | None = None,
) -> list[SppEpoch]:
    """Robust Kalman-filter SPP on code, Doppler and carrier phase (one or two bands).

    State: position, velocity, a code clock and a carrier-phase clock per system sharing
    one drift, an inter-frequency code bias per system with a second band, and one float
    bias per carrier-phase arc (model in the module docstring). Initialised from the first
    least-squares (FDE) solution; each epoch: predict (:class:`SppProcessModel` inside a
    :class:`Relayout` for the arcs), restart a clock whose per-system median innovation
    exceeds ``clock_reset_m``, then one robust update (``cfg.robust``) of every row of the
    satellites above the mask at the predicted position. The filter is re-initialised from
    the FDE solution when the two disagree by more than ``reinit_m`` for
    ``cfg.estimator.reinit_epochs`` consecutive epochs (0 = never). With
    ``cfg.estimator.smoother`` the forward estimates are replaced by Rauch–Tung–Striebel
    smoothed ones.

    Integrity (:mod:`robustrtk.estimation.integrity`, algorithms.md §30): each epoch the
    predicted position is tested against the epoch's least-squares (FDE) solution; an
    inconsistent prediction is widened, and re-initialised from that solution when the
    test fails ``integrity.patience`` epochs in a row or after a gap longer than
    ``integrity.max_gap_s``. An epoch is solved only when at least four rows that carry
    position information were used (code, or the phase of an arc that continues: a new
    arc's bias absorbs its phase); its reported covariance is bounded below by the
    least-squares one (time-correlated code errors do not average out).

    Parameters
    ----------
    batch : ObsBatch
        Observations with any signals: per system the first band-1 column with code and
        (``cfg.spp.dual_frequency``) a second-band column are used; a batch reduced by
        :func:`robustrtk.pipeline.spp_common.select_band1` gives band 1 only.
    nav : NavData or EphemerisSource
    cfg : Config, optional
        Default ``preset("spp").updated(filter="ekf")``; ``cfg.estimator.filter`` must be
        ``ekf`` or ``ukf``.
    progress : callable (done, total), optional
    systems : str, optional
        System letters to use (all with ephemerides when None).
    integrity : IntegrityPolicy, optional
        The monitor's policy (default :class:`IntegrityPolicy`).
    events : list, optional
        Receives ``(t_s, IntegrityEvent)`` of every widening and re-initialisation.

    Returns
    -------
    list of SppEpoch, one per epoch: status ``"single"`` when at least four code or phase
    position rows were used, ``"none"`` otherwise (before the first fix: NaN position); ``n_used``
    counts code rows; ``excluded`` lists rows the policy rejected (``"G05:P1"`` code,
    ``"G05:L5"`` phase, ``"G05:D1"`` Doppler, ``"ZUPT:vx"`` a zero-velocity row).
    """
    cfg = cfg or preset("spp").updated(filter="ekf")
    kf = kalman_filter(cfg)
    rb = cfg.robust
    policy = make_robust_policy(rb.policy, k0=rb.k0, k1=rb.k1, prefit_k0=rb.prefit_k0, prefit_k1=rb.prefit_k1)
    est = cfg.estimator
    adaptive = make_adaptive_factor(est.adaptive, est.adaptive_c0, est.adaptive_c1, est.adaptive_max_iter)
    settings = lsq_settings(cfg)
    dynamics = SppProcessModel.of(cfg)
    reinit_epochs, reinit_m = cfg.estimator.reinit_epochs, cfg.spp.reinit_m
    _, eph = nav_and_source(nav)
    sig = spp_signals(batch, eph.nav, cfg.spp.dual_frequency, systems)
    run = _KalmanSpp(sig, eph, cfg)
    nf = run.fixed.n_fixed
    T = len(batch)
    out: list[SppEpoch] = []
    steps: list[FilterStep | None] = []
    state: GaussianState | None = None
    disagree = 0
    monitor = IntegrityMonitor(integrity or IntegrityPolicy())
    floors: list[FloatArray | None] = []
    for i in range(T):
        t = float(batch.t_s[i])
        sats = _sat_states(sig, i, t, eph)
        x0 = None if state is None or t - state.t_s > monitor.policy.max_gap_s else state.x[:3]
        lsq, _, _ = lsq_fde(t, _lsq_geometry(sig, i, sats), run.nav, settings, x0)
        snap = (
            None if lsq is None else Snapshot(np.asarray(lsq.pos, float), np.asarray(lsq.cov, float)[:3, :3])
        )
        floors.append(snap.cov_m2 if snap is not None and monitor.policy.floor_covariance else None)
        if state is not None and lsq is not None:
            far = float(np.linalg.norm(lsq.pos - state.x[:3])) > reinit_m
            disagree = disagree + 1 if far else 0
            if reinit_epochs > 0 and disagree >= reinit_epochs:
                state, disagree = None, 0
        scale = 1.0
        if state is not None and snap is None and t - state.t_s > monitor.policy.max_gap_s:
            state, disagree = None, 0  # no prediction across the gap, no snapshot to restart from
        if state is not None and snap is not None and monitor.policy.enabled:
            ev = _integrity_test(state, snap, t, dynamics, run.fixed, monitor)
            if ev.kind != "ok" and events is not None:
                events.append((t, ev))
            if ev.kind == "reinit":
                state, disagree = None, 0
            scale = ev.scale
        first = state is None
        if state is None:
            if lsq is None:
                out.append(unsolved_epoch(t))
                steps.append(None)
                notify_progress(progress, i + 1, T, "none")
                continue
            state = run.initial_state(t, lsq.pos, lsq.cov[:3, :3], lsq.clk)
            run.last_seen.clear()
            run.restart.clear()
        model = dynamics.at(state.x[:3])
        F_fixed, _ = model.transition(run.fixed, t - state.t_s)
        x_lin = F_fixed @ state.x[:nf]
        rows, new_amb, suspect = run.build_rows(i, t, sats, x_lin, nf)
        if cfg.spp.zupt:
            run.zupt_rows(rows, x_lin, nf)
        in_rows = set(rows.amb)
        kept = tuple(k for k in state.layout.amb_keys if k in in_rows)
        change = Relayout(
            model,
            replace(run.fixed, amb_keys=kept + tuple(new_amb)),
            start=new_amb,
            start_var=cfg.spp.amb_var0_m2,
            extra_var={k: cfg.spp.slip_var_m2 for k in suspect},
        )
        prior, F = predict_relayout(state, change, t)
        if scale > 1.0:
            prior = widen(prior, scale)
        m = len(rows.d)
        if m:
            H, d = _design(rows, prior.layout, prior.x, x_lin)
            resets = run.clock_restarts(rows, d, prior.x, new_amb)
            if resets:
                change = replace(change, restart=resets)
                prior, F = predict_relayout(state, change, t)
                prior = widen(prior, scale) if scale > 1.0 else prior
                H, d = _design(rows, prior.layout, prior.x, x_lin)
            meas = LinearMeasurement(H=H, z=d + H @ prior.x, R=np.diag(rows.var), labels=tuple(rows.labels))
            res, adapt = adaptive_update(kf, prior, meas, policy, adaptive)
            alpha = 1.0 if adapt is None else adapt.alpha_min
            post = res.state
            used = np.isfinite(res.factors)
            rejected = tuple(lab for lab, ok in zip(rows.labels, used, strict=True) if not ok)
            for r, key in enumerate(rows.amb):
                if key is not None and not used[r]:
                    run.restart.add((key[0], key[1]))
            kinds = np.array(rows.kind)
            n_code = int(np.sum(used & (kinds == "P")))
            # a new arc's bias absorbs its phase: that row tells nothing of the position
            cont = np.array([a is None or a not in new_amb for a in rows.amb], bool)
            n_pos = int(np.sum(used & cont & (kinds != "D") & (kinds != "Z")))
        else:
            post, rejected, n_code, n_pos, alpha = prior, (), 0, 0, 1.0
        steps.append(FilterStep(None if first else F, prior.x, prior.P, post.x, post.P))
        state = post
        out.append(_epoch(post.x, post.P, run, t, n_code, rejected, n_pos >= 4, alpha, floors[-1]))
        notify_progress(progress, i + 1, T, out[-1].status)
    if cfg.estimator.smoother:
        out = _smoothed(out, steps, run, floors)
    return out


def _integrity_test(
    state: GaussianState,
    snap: Snapshot,
    t: float,
    dynamics: SppProcessModel,
    fixed: StateLayout,
    monitor: IntegrityMonitor,
) -> IntegrityEvent:
    """The monitor's test of the position predicted from ``state`` to ``t`` (the fixed
    part's time update: the arc biases do not enter the position) against the snapshot; a
    gap beyond ``max_gap_s`` is a re-initialisation without test."""
    if t - state.t_s > monitor.policy.max_gap_s:
        monitor.reinit_now()
        return IntegrityEvent("reinit", float("nan"))
    nf = fixed.n_fixed
    F, Q = dynamics.at(state.x[:3]).transition(fixed, t - state.t_s)
    x = F @ state.x[:nf]
    P = F @ state.P[:nf, :nf] @ F.T + Q
    pred = GaussianState(x=x, P=0.5 * (P + P.T), t_s=t, layout=fixed)
    widened, ev = monitor.check(pred, snap)
    return ev if ev is not None else IntegrityEvent("ok", float("nan"))


def _epoch(
    x: FloatArray,
    P: FloatArray,
    run: _KalmanSpp,
    t: float,
    n_used: int,
    rejected: tuple[str, ...],
    ok: bool,
    alpha: float = 1.0,
    floor: FloatArray | None = None,
) -> SppEpoch:
    clk = {s: float(x[run.clk_index(s)]) for s in run.systems}
    cov = P[0:3, 0:3].copy() if floor is None else covariance_floor(P[0:3, 0:3], floor)
    return SppEpoch(
        t,
        x[0:3].copy(),
        clk,
        cov,
        n_used,
        "single" if ok else "none",
        rejected,
        ok,
        x[3:6].copy(),
        alpha,
    )


def _smoothed(
    out: list[SppEpoch],
    steps: list[FilterStep | None],
    run: _KalmanSpp,
    floors: list[FloatArray | None] | None = None,
) -> list[SppEpoch]:
    """Replace positions, velocities, clocks and covariances by their RTS estimates, one
    segment (a run of epochs the filter carried across) at a time."""
    res = list(out)
    segments: list[list[int]] = []
    for k, st in enumerate(steps):
        if st is None:
            continue
        if st.F is None or not segments or segments[-1][-1] != k - 1:
            segments.append([k])
        else:
            segments[-1].append(k)
    for seg in segments:
        chain = [steps[k] for k in seg]
        for k, (x, P) in zip(seg, rts_smooth([c for c in chain if c is not None]), strict=True):
            e = out[k]
            fl = None if floors is None else floors[k]
            res[k] = _epoch(x, P, run, e.t_s, e.n_used, e.excluded, e.chi2_ok, e.adaptive_alpha, fl)
    return res


__all__ = [
    "BAND2_PREFERENCE",
    "Relayout",
    "Signals",
    "SppProcessModel",
    "doppler_standing",
    "TransitionModel",
    "spp_signals",
    "kalman_filter",
    "predict_relayout",
    "solve_spp_kalman",
    "spp_layout",
]
