"""Robust batch smoother of a phone (or any single receiver) track: factor-graph SPP.

One sparse nonlinear least-squares problem over the whole track (docs/algorithms.md §36):
per epoch the position, velocity, code clock per system, clock drift, second-band code bias
per system and carrier-phase clock change per system (:mod:`robustrtk.pipeline.spp_fgo_factors`);
pseudorange rows, Doppler range-rate rows, time-differenced carrier-phase rows between
consecutive epochs of unbroken arcs (:mod:`robustrtk.measurement.tdcp`), and the Kalman
SPP's own process model (:class:`robustrtk.pipeline.spp_dynamics.SppProcessModel`) as the
motion prior. Solved by :func:`robustrtk.estimation.fgo.robust_batch_solve`: Gauss–Newton,
iteratively re-weighted — Huber, then IGG-III with the thresholds of ``cfg.robust`` — on
every measurement row; rows that stay inconsistent end with weight 0 (switched off). A
first, convex solve (Huber on every row) measures the scatter of the TDCP and of the Doppler
rows, whose σ are rescaled by it (:func:`residual_scale`, docs/algorithms.md §40) before the
robust solve.

Every constant is the Kalman SPP's (same σ, C/N0 laws, process noise, mask); the arc tests
use the physical thresholds of :class:`robustrtk.measurement.tdcp.ArcTests`. The start is the
epoch-wise least-squares (FDE) solution; the problem is linear in everything but the
positions, and the ranges are nearly linear over the metres the start is off.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
import scipy.sparse as sp

from robustrtk.core import CLIGHT, FloatArray, ObsBatch
from robustrtk.estimation.fgo import FactorGroup, Kernel, robust_batch_solve
from robustrtk.estimation.integrity import covariance_floor
from robustrtk.estimation.registry import make_robust_policy
from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.io.rinex_nav import NavData
from robustrtk.measurement.corrections import F_L1_HZ
from robustrtk.measurement.tdcp import BREAK_NAMES, CONTINUES, ArcTests, arc_breaks, phase_deltas
from robustrtk.measurement.undifferenced import atmosphere, cn0_variance, elevation_cn0_variance, lsq_fde
from robustrtk.pipeline.config import Config, preset
from robustrtk.pipeline.results import notify_progress
from robustrtk.pipeline.spp_common import SppEpoch, lsq_settings, nav_and_source, unsolved_epoch
from robustrtk.pipeline.spp_dynamics import SppProcessModel
from robustrtk.pipeline.spp_fgo_factors import (
    BlockLayout,
    CodeRows,
    DopplerRows,
    MotionRows,
    PriorRows,
    TdcpRows,
)
from robustrtk.pipeline.spp_fgo_iono import (
    CALIBRATED_SYSTEMS,
    FIELD_CHI2,
    BlocksOnly,
    IonoCodeTerm,
    IonoPriorRows,
    RowSet,
    field_observable,
    field_statistic,
    iono_unknowns,
    shell_geometry,
)
from robustrtk.pipeline.spp_signals import SatStates, Signals, lsq_geometry, spp_signals

#: σ of the weak priors that only make the normal matrix regular (m, m/s).
WEAK_PRIOR_SIGMA = 1.0e5


@dataclass
class FgoDiagnostics:
    """Per-epoch counts of the smoother's rows.

    Attributes
    ----------
    t_s : ndarray, shape (T,)
    rows, downweighted, switched_off : dict kind -> ndarray of int, shape (T,)
        Rows of kind ``"P"`` (code), ``"D"`` (Doppler), ``"L"`` (TDCP) per epoch; those with
        weight below 1; those with weight 0.
    arc_breaks : dict reason -> ndarray of int, shape (T,)
        Arc breaks per epoch by reason (:data:`robustrtk.measurement.tdcp.BREAK_NAMES`),
        where the phase was present at both epochs.
    iterations : int
        Gauss–Newton iterations of both solves.
    converged : bool
    tdcp_scale, doppler_scale : float or None
        Factors applied to the σ of the TDCP and of the Doppler rows before the second solve
        (:func:`residual_scale`); None when there was none.
    ionosphere : str
        How the ionosphere was corrected (the broadcast model, its estimated error and the
        test that kept or dropped it: docs/algorithms.md §48); empty when not decided here.
    """

    t_s: FloatArray
    rows: dict[str, np.ndarray] = field(default_factory=dict)
    downweighted: dict[str, np.ndarray] = field(default_factory=dict)
    switched_off: dict[str, np.ndarray] = field(default_factory=dict)
    arc_breaks: dict[str, np.ndarray] = field(default_factory=dict)
    iterations: int = 0
    converged: bool = False
    tdcp_scale: float | None = None
    doppler_scale: float | None = None
    ionosphere: str = ""
    long_rows: list[dict[str, object]] = field(default_factory=list)

    def table(self) -> list[dict[str, object]]:
        """Rows for :func:`robustrtk.io.diagnostics.write_diagnostics_csv`: one per
        measurement row (``dd`` = ``"G05:P1"``, ``"G05:D5"``, ``"G05:L1"`` — the TDCP ending at
        that epoch; ``residual`` in m or m/s, ``std_residual`` = r/σ, ``factor`` = 1/w,
        ``situation`` 1 kept, 2 down-weighted, 3 switched off) and one per arc break
        (``dd`` = ``"G05:L1 break:gf"``, situation 0, no numbers)."""
        return self.long_rows


@dataclass
class _Track:
    """Satellite states and the least-squares start of every epoch."""

    sat_pos: FloatArray  # (T, N, 3)
    sat_vel: FloatArray
    sat_clk: FloatArray  # (T, N)
    sat_drift: FloatArray
    tgd: FloatArray  # (T, N, 2)
    el: FloatArray  # (T, N)
    trop: FloatArray
    iono1: FloatArray
    pos0: FloatArray  # (T, 3)
    clk0: FloatArray  # (T, n_s)
    cov0: list[FloatArray | None]
    az: FloatArray  # (T, N)


@dataclass
class TrackStates:
    """Satellite states of every (epoch, satellite) row with code, epoch-major."""

    epoch: np.ndarray  # (M,)
    sat: np.ndarray  # (M,) index into Signals
    t_tx_s: FloatArray
    pos_m: FloatArray  # (M, 3)
    vel_m_s: FloatArray
    clk_m: FloatArray  # c dt, no group delay
    drift_m_s: FloatArray
    tgd_m: FloatArray  # (M, 2)


def track_states(sig: Signals, t_s: FloatArray, eph: EphemerisSource) -> TrackStates:
    """:func:`robustrtk.pipeline.spp_signals.sat_states` of all epochs in one vectorised pass:
    transmission time ``t_tx = t_rx − P/c − (dt(t_tx) − T_GD,1)`` iterated three times from
    the band-1 code (else band 2), then the states and each band's group delay at ``t_tx``;
    rows without a valid ephemeris or clock are dropped."""
    code = sig.code_m
    tt = np.where(np.isfinite(code[:, :, 0]), code[:, :, 0], code[:, :, 1])
    e, j = np.nonzero(np.isfinite(tt))
    ids = [sig.ids[q] for q in j.tolist()]
    t_sv = np.asarray(t_s, float)[e] - tt[e, j] / CLIGHT
    tgd1 = eph.group_delay_s(t_sv, ids)
    t = t_sv.copy()
    for _ in range(3):
        t = t_sv - (eph.sat_states(t, ids)[2] - tgd1)
    pos, vel, clk, drift, ok = eph.sat_states(t, ids)
    tgd = np.full((j.size, 2), np.nan)
    band = np.asarray(sig.band, dtype="U1").reshape(-1, 2) if sig.band else np.zeros((0, 2), "U1")
    for b in range(2):
        for name in set(band[j, b].tolist()) - {""}:
            sel = np.flatnonzero(band[j, b] == name)
            tgd[sel, b] = eph.group_delay_s(t[sel], [ids[q] for q in sel.tolist()], name)
    ok &= np.isfinite(clk)
    return TrackStates(e[ok], j[ok], t[ok], pos[ok], vel[ok], clk[ok] * CLIGHT, drift[ok] * CLIGHT,
                        tgd[ok] * CLIGHT)  # fmt: skip


def _track(
    sig: Signals,
    t_s: FloatArray,
    eph: EphemerisSource,
    cfg: Config,
    progress: Callable[[int, int], None] | None,
) -> _Track:
    T, N = len(t_s), len(sig.ids)
    nan3 = np.full((T, N, 3), np.nan)
    nan2 = np.full((T, N), np.nan)
    tr = _Track(nan3, nan3.copy(), nan2.copy(), nan2.copy(), np.full((T, N, 2), np.nan), nan2.copy(),
                np.zeros((T, N)), np.zeros((T, N)), np.full((T, 3), np.nan),
                np.full((T, len(sig.systems)), np.nan), [None] * T, nan2.copy())  # fmt: skip
    settings = lsq_settings(cfg)
    x0: FloatArray | None = None
    states = track_states(sig, t_s, eph)
    starts = np.searchsorted(states.epoch, np.arange(T + 1))
    for i in range(T):
        t = float(t_s[i])
        rs = slice(int(starts[i]), int(starts[i + 1]))
        st = states
        s = SatStates(st.sat[rs], st.t_tx_s[rs], st.pos_m[rs], st.vel_m_s[rs], st.clk_m[rs],
                      st.drift_m_s[rs], st.tgd_m[rs])  # fmt: skip
        j = s.idx
        tr.sat_pos[i, j], tr.sat_vel[i, j], tr.sat_clk[i, j] = s.pos_m, s.vel_m_s, s.clk_m
        tr.sat_drift[i, j], tr.tgd[i, j] = s.drift_m_s, s.tgd_m
        lsq, _, _ = lsq_fde(t, lsq_geometry(sig, i, s), eph.nav, settings, x0)
        if lsq is not None:
            x0 = np.asarray(lsq.pos, float)
            tr.pos0[i] = x0
            tr.cov0[i] = np.asarray(lsq.cov, float)[:3, :3]
            for q, name in enumerate(sig.systems):
                tr.clk0[i, q] = lsq.clk.get(name, np.nan)
        notify_progress(progress, i + 1, 2 * T, "single" if lsq is not None else "none")
    good = np.flatnonzero(np.isfinite(tr.pos0[:, 0]))
    if good.size:
        for c in range(3):
            tr.pos0[:, c] = np.interp(np.arange(T), good, tr.pos0[good, c])
        for q in range(tr.clk0.shape[1]):
            ok = np.flatnonzero(np.isfinite(tr.clk0[:, q]))
            tr.clk0[:, q] = np.interp(np.arange(T), ok, tr.clk0[ok, q]) if ok.size else 0.0
        meas = cfg.measurement
        for i in range(T):
            j = np.flatnonzero(np.isfinite(tr.sat_pos[i, :, 0]))
            if j.size:
                atm = atmosphere(float(t_s[i]), tr.sat_pos[i, j], tr.pos0[i], eph.nav, meas.tropo, meas.iono)
                tr.el[i, j], tr.trop[i, j], tr.iono1[i, j] = atm.el_rad, atm.tropo_m, atm.iono_m
                tr.az[i, j] = atm.az_rad
    return tr


#: Least redundancy ``m − p`` from which a scale is estimated (:func:`residual_scale`).
MIN_SCALE_ROWS = 50


def residual_scale(std_residual: FloatArray, n_params: int) -> float | None:
    """Robust a-posteriori scale of one kind of rows — TDCP, Doppler (docs/algorithms.md §40).

    ``s = 1.4826 · median |r/σ| · √(m / (m − p))`` over all ``m`` rows, ``p`` the unknowns
    they determine (three displacement components and one phase-clock change per system
    per epoch pair). The prior σ of a time-differenced phase (``phase_sigma_m``, elevation
    law) is a guess: a phone's phase noise is millimetres, but its multipath changes as the
    antenna moves, by an amount no constant fixes for every phone and drive. The MAD of the
    standardised residuals of a first, convex (Huber) solve measures it (outliers and switched-off rows do
    not move a median); the residuals of rows that determine their own unknowns are
    smaller than their errors by the redundancy ``(m − p)/m`` (a lower bound of it: the code,
    Doppler and motion rows also inform the displacement), hence the root.

    Parameters
    ----------
    std_residual : ndarray, shape (m,)
    n_params : int

    Returns
    -------
    float or None
        None (no rescaling) where ``m − p`` is below :data:`MIN_SCALE_ROWS`.
    """
    u = np.abs(np.asarray(std_residual, float))
    u = u[np.isfinite(u)]
    m = u.size
    if m - n_params < MIN_SCALE_ROWS:
        return None
    s = 1.4826 * float(np.median(u)) * float(np.sqrt(m / (m - n_params)))
    return s if s > 0.0 else None


def _position_blocks_inverse(info: sp.spmatrix, T: int, blk: int) -> FloatArray:
    """Inverses of the 3×3 position blocks of the normal matrix, all epochs at once
    (NaN where a block is singular), shape (T, 3, 3)."""
    base = np.arange(T)[:, None, None] * blk
    r = base + np.arange(3)[None, :, None]
    c = base + np.arange(3)[None, None, :]
    rr, cc = np.broadcast_arrays(r, c)
    blocks = np.asarray(sp.csr_matrix(info)[rr.ravel(), cc.ravel()], float)
    blocks = blocks.reshape(T, 3, 3)
    out = np.full((T, 3, 3), np.nan)
    ok = np.abs(np.linalg.det(blocks)) > 0.0
    if ok.any():
        out[ok] = np.linalg.inv(blocks[ok])
    return out


def arc_tests(cfg: Config, t_s: FloatArray) -> ArcTests:
    """The arc tests under ``cfg``: loss-of-lock breaks with ``lli_reset``; a gap of more than
    one and a half nominal epoch intervals breaks (a missed epoch of a duty-cycled phone);
    the Doppler law and phase σ of the Kalman SPP."""
    dt = np.diff(np.asarray(t_s, float))
    nominal = float(np.median(dt)) if dt.size else 1.0
    return ArcTests(
        max_gap_s=1.5 * nominal,
        lli_break=cfg.spp.lli_reset,
        doppler_sigma_m_s=cfg.spp.doppler_cn0_sigma_m_s,
        cn0_ref_dbhz=cfg.spp.cn0_ref_dbhz,
        phase_sigma_m=cfg.measurement.phase_sigma_m,
    )


def solve_spp_fgo(
    batch: ObsBatch,
    nav: NavData | EphemerisSource,
    cfg: Config | None = None,
    progress: Callable[[int, int], None] | None = None,
    systems: str | None = None,
    diagnostics: list[FgoDiagnostics] | None = None,
) -> list[SppEpoch]:
    """Robust batch (factor-graph) SPP of a whole track (module docstring).

    Parameters
    ----------
    batch : ObsBatch
    nav : NavData or EphemerisSource
    cfg : Config, optional
        Default ``preset("spp").updated(filter="ekf")``; the σ, C/N0 laws, mask, process
        noise, ``use_doppler``, ``use_phase``, ``dual_frequency``, ``lli_reset``,
        ``clock_reset_m`` and the robust thresholds (``cfg.robust``) are read.
    progress : callable (done, total), optional
    systems : str, optional
    diagnostics : list, optional
        Receives one :class:`FgoDiagnostics`.

    Returns
    -------
    list of SppEpoch, one per epoch; ``excluded`` lists the rows switched off
    (``"G05:P1"`` code, ``"G05:D1"`` Doppler, ``"G05:L1"`` TDCP ending at that epoch);
    status ``"single"`` where at least four code or TDCP rows kept a weight.
    """
    cfg = cfg or preset("spp").updated(filter="ekf")
    _, eph = nav_and_source(nav)
    sig = spp_signals(batch, eph.nav, cfg.spp.dual_frequency, systems)
    t_s = np.asarray(batch.t_s, float)
    tr = _track(sig, t_s, eph, cfg, progress)
    if len(t_s) == 0 or not np.isfinite(tr.pos0).all():
        return [unsolved_epoch(float(t)) for t in t_s]
    return _solve_track(sig, tr, t_s, cfg, progress, diagnostics)


def _solve_track(
    sig: Signals,
    tr: _Track,
    t_s: FloatArray,
    cfg: Config,
    progress: Callable[[int, int], None] | None,
    diagnostics: list[FgoDiagnostics] | None,
) -> list[SppEpoch]:
    """The smoother over a track whose satellite states and start are known
    (:func:`solve_spp_fgo`)."""
    spp, meas = cfg.spp, cfg.measurement
    T, N = len(t_s), len(sig.ids)
    band2 = sorted({sig.sys[j] for j in range(N) if sig.band[j][1]})
    lay = BlockLayout(len(sig.systems), len(band2))
    blk = lay.size
    nb = T * blk
    selP0 = np.isfinite(sig.code_m) & np.isfinite(tr.el)[:, :, None]
    free_sys = ~np.isin(np.asarray(sig.sys), CALIBRATED_SYSTEMS)
    unk, iono_note = None, ""
    if meas.iono != "off" and spp.fgo_iono:
        if field_observable(selP0[:, :, 0] & selP0[:, :, 1], ~free_sys):
            mapping, d_n, d_e = shell_geometry(np.nan_to_num(tr.el, nan=np.pi / 2), np.nan_to_num(tr.az))
            with np.errstate(invalid="ignore"):
                vert = np.nanmedian(np.where(np.isfinite(tr.el) & (tr.iono1 > 0), tr.iono1 / mapping, np.nan))
            two_free = selP0[:, :, 1] & free_sys[None, :]
            unk = iono_unknowns(
                t_s, np.asarray(selP0.any(axis=(1, 2))), float(np.nan_to_num(vert)), nb, two_free
            )
        else:
            iono_note = "broadcast model (too few calibrated two-band satellites to estimate its error)"
    n = nb + (unk.size if unk is not None else 0)
    sys_i = np.array([sig.systems.index(s) for s in sig.sys], int)
    ifb_i = np.array([band2.index(s) if s in band2 else -1 for s in sig.sys], int)
    mask = np.deg2rad(cfg.gnss.elev_mask_deg)
    cn0 = sig.cn0_dbhz
    lam = sig.wavelength_m
    freq = np.where(np.isfinite(lam), CLIGHT / np.where(np.isfinite(lam), lam, 1.0), F_L1_HZ)
    iono = tr.iono1[:, :, None] * (F_L1_HZ / freq[None]) ** 2  # (T, N, 2)
    above = np.isfinite(tr.el) & (tr.el >= mask)
    cn0_ok = ~(cn0 < meas.snr_mask_dbhz)
    el3 = np.repeat(tr.el[:, :, None], 2, axis=2)
    use_cn0 = cn0 if spp.kalman_use_cn0 else None

    def el_var(sigma: float, sel: np.ndarray) -> FloatArray:
        c = None if use_cn0 is None else use_cn0[sel]
        return elevation_cn0_variance(sigma, el3[sel], c, cn0_ref_dbhz=spp.cn0_ref_dbhz)

    # code
    z_code = sig.code_m + tr.sat_clk[:, :, None] - tr.tgd - iono - tr.trop[:, :, None]
    selP = np.isfinite(z_code) & above[:, :, None] & cn0_ok
    eP, jP, bP = np.nonzero(selP)
    code = CodeRows(eP, tr.sat_pos[eP, jP], z_code[selP], np.sqrt(el_var(meas.code_sigma_m, selP)),
                    lay.clk + sys_i[jP], np.where(bP == 1, lay.ifb + ifb_i[jP], -1), blk, n)  # fmt: skip
    code_rows: RowSet = BlocksOnly(code, nb)
    if unk is not None:
        g_m = (F_L1_HZ / freq[jP, bP]) ** 2 * mapping[eP, jP]
        coef = np.column_stack([g_m, g_m * d_n[eP, jP], g_m * d_e[eP, jP]])
        bias = np.where(bP == 1, unk.bias_of(eP, jP), -1)
        code_rows = IonoCodeTerm(code, nb, unk.seg_col[eP], coef, bias, n)
    # Doppler: the first band with a Doppler per satellite
    z_dop = -lam[None] * sig.doppler_hz + tr.sat_drift[:, :, None]
    okD = np.isfinite(z_dop) & above[:, :, None] & cn0_ok & spp.use_doppler
    okD[:, :, 1] &= ~okD[:, :, 0]
    eD, jD, bD = np.nonzero(okD)
    if spp.doppler_weighting == "cn0":
        varD = cn0_variance(spp.doppler_cn0_sigma_m_s, cn0[okD], spp.cn0_ref_dbhz)
    else:
        varD = el_var(spp.doppler_sigma_m_s, okD)
    dop = DopplerRows(
        eD, tr.sat_pos[eD, jD], tr.sat_vel[eD, jD], z_dop[okD], np.sqrt(varD), blk, lay.drift, n
    )
    # TDCP
    tests = arc_tests(cfg, t_s)
    breaks = arc_breaks(t_s, sig.phase_cyc, sig.lli, sig.doppler_hz, cn0, lam, tests)
    corr = tr.sat_clk[:, :, None] - tr.trop[:, :, None] + iono
    delta = phase_deltas(sig.phase_cyc, lam, corr, breaks)
    okL = np.isfinite(delta) & cn0_ok & spp.use_phase
    okL[1:] &= above[1:, :, None] & above[:-1, :, None] & cn0_ok[:-1]
    okL[0] = False
    eL, jL, bL = np.nonzero(okL)
    with np.errstate(invalid="ignore"):
        var_ph = elevation_cn0_variance(
            meas.phase_sigma_m, np.nan_to_num(el3, nan=mask), use_cn0, cn0_ref_dbhz=spp.cn0_ref_dbhz
        )
    varL = var_ph[eL, jL, bL] + var_ph[eL - 1, jL, bL]
    tdcp = TdcpRows(eL, tr.sat_pos[eL - 1, jL], tr.sat_pos[eL, jL], delta[okL], np.sqrt(varL),
                    lay.dpc + sys_i[jL], blk, n)  # fmt: skip
    # motion prior (the code clock released where the least-squares clock jumped)
    jump = np.zeros(T, bool)
    jump[1:] = np.any(np.abs(np.diff(tr.clk0, axis=0)) > spp.clock_reset_m, axis=1)
    motion = MotionRows(SppProcessModel.of(cfg).at(tr.pos0[0]), lay, t_s, jump, n)
    # start and weak priors
    x0 = np.zeros((T, blk))
    x0[:, 0:3] = tr.pos0
    x0[:, lay.clk : lay.clk + lay.n_systems] = tr.clk0
    x_start = np.concatenate([x0.ravel(), np.zeros(n - nb)])
    cols = np.concatenate(
        [np.arange(lay.n_fixed), (np.arange(T)[:, None] * blk + lay.dpc + np.arange(lay.n_systems)).ravel()]
    )
    prior = PriorRows(cols, x0.ravel()[cols], np.full(cols.size, WEAK_PRIOR_SIGMA), n)
    groups: list[FactorGroup] = []
    for name, rows, kernel in (("P", code_rows, "igg3"), ("D", BlocksOnly(dop, nb), "igg3"),
                               ("L", BlocksOnly(tdcp, nb), "igg3"), ("motion", motion, "huber"),
                               ("prior", prior, "none")):  # fmt: skip
        k: Kernel = kernel  # type: ignore[assignment]
        groups.append(FactorGroup(name, k, rows.linearize))
    if unk is not None:
        groups.append(FactorGroup("iono", "none", IonoPriorRows(unk, n).linearize))
    pol = make_robust_policy(cfg.robust.policy, k0=cfg.robust.k0, k1=cfg.robust.k1)
    k0 = float(getattr(pol, "k0", 1.5))
    k1 = float(getattr(pol, "k1", 3.0))
    robust = cfg.robust.policy != "none"
    k1 = k1 if np.isfinite(k1) else 3.0 * k0
    # first a convex (Huber) solve, whose TDCP residuals give their scale (variance component)
    convex = [FactorGroup(g.name, "huber" if g.kernel == "igg3" else g.kernel, g.linearize) for g in groups]
    # the field's unknowns couple every epoch of a minute and each free bias every epoch of its
    # satellite: a minimum-degree ordering of N + Nᵀ keeps their fill-in down (2× faster)
    order = "COLAMD" if unk is None else "MMD_AT_PLUS_A"
    res = robust_batch_solve(
        convex if robust else groups, x_start, k0=k0, k1=k1, robust=robust, ordering=order
    )
    n_par = 3 * np.unique(eL).size + np.unique(eL * blk + sys_i[jL]).size
    scale = residual_scale(res.std_residual["L"], n_par) if robust else None
    scale_d = residual_scale(res.std_residual["D"], 4 * np.unique(eD).size) if robust else None
    if robust:
        # then Huber and IGG-III from there, the TDCP and Doppler rows with their σ rescaled
        if scale is not None:
            tdcp = replace(tdcp, sigma_m=tdcp.sigma_m * scale)
            groups[2] = FactorGroup("L", "igg3", BlocksOnly(tdcp, nb).linearize)
        if scale_d is not None:
            dop = replace(dop, sigma_m_s=dop.sigma_m_s * scale_d)
            groups[1] = FactorGroup("D", "igg3", BlocksOnly(dop, nb).linearize)
        first_iterations = res.iterations
        res = robust_batch_solve(groups, res.x, k0=k0, k1=k1, robust=robust, ordering=order)
        res.iterations += first_iterations
    if unk is not None:
        stat = field_statistic(res, unk, eP, jP, bP)
        if stat <= FIELD_CHI2:
            # the two bands do not tell a model error from zero: the track without the field
            inner: list[FgoDiagnostics] = []
            plain = _solve_track(sig, tr, t_s, cfg.updated(fgo_iono=False), progress, inner)
            inner[0].ionosphere = f"broadcast model (its error estimated, not significant: χ² {stat:.1f})"
            if diagnostics is not None:
                diagnostics.extend(inner)
            return plain
        first = np.unique(unk.seg_col[unk.seg_col >= 0])
        v, g_n, g_e = (float(np.mean(res.x[first + k])) for k in range(3))
        iono_note = (
            f"broadcast model + estimated error (χ² {stat:.0f}; mean vertical {v:+.2f} m, "
            f"gradients N {g_n:+.2f} E {g_e:+.2f} m per 1000 km)"
        )
    X = res.x[:nb].reshape(T, blk)
    w = res.weights
    kinds = {
        "P": (eP, jP, bP, sig.band, "P", code.sigma_m),
        "D": (eD, jD, bD, sig.band, "D", dop.sigma_m_s),
        "L": (eL, jL, bL, sig.band, "L", tdcp.sigma_m),
    }
    excluded: list[list[str]] = [[] for _ in range(T)]
    diag = FgoDiagnostics(
        t_s=t_s, iterations=res.iterations, converged=res.converged, tdcp_scale=scale, doppler_scale=scale_d,
        ionosphere=iono_note,
    )  # fmt: skip
    for kind, (e, j, b, bands, letter, sig_k) in kinds.items():
        wk = w[kind]
        u = res.std_residual[kind]
        with np.errstate(divide="ignore"):
            gam = np.where(wk > 0, 1.0 / np.where(wk > 0, wk, 1.0), np.inf)
        sit = np.where(wk == 0.0, 3, np.where(wk < 1.0, 2, 1))
        for r in range(e.size):
            label = f"{sig.ids[j[r]]}:{letter}{bands[j[r]][b[r]]}"
            diag.long_rows.append({"time": float(t_s[e[r]]), "dd": label,
                                   "residual": float(u[r] * sig_k[r]), "std_residual": float(u[r]),
                                   "factor": float(gam[r]), "situation": int(sit[r])})  # fmt: skip
        diag.rows[kind] = np.bincount(e, minlength=T)
        diag.downweighted[kind] = np.bincount(e[wk < 1.0], minlength=T)
        diag.switched_off[kind] = np.bincount(e[wk == 0.0], minlength=T)
        for r in np.flatnonzero(wk == 0.0).tolist():
            excluded[e[r]].append(f"{sig.ids[j[r]]}:{letter}{bands[j[r]][b[r]]}")
    both = np.zeros_like(breaks, bool)
    both[1:] = np.isfinite(sig.phase_cyc[1:]) & np.isfinite(sig.phase_cyc[:-1])
    for code_i, reason in enumerate(BREAK_NAMES):
        if code_i in (CONTINUES,) or not reason or reason == "absent":
            continue
        hit = (breaks == code_i) & both
        diag.arc_breaks[reason] = np.sum(hit, axis=(1, 2))
        for e_, j_, b_ in zip(*np.nonzero(hit), strict=True):
            name = f"{sig.ids[j_]}:L{sig.band[j_][b_]} break:{reason}"
            diag.long_rows.append({"time": float(t_s[e_]), "dd": name, "situation": 0})
    if diagnostics is not None:
        diagnostics.append(diag)
    pos_used = np.bincount(eP[w["P"] > 0], minlength=T) + np.bincount(eL[w["L"] > 0], minlength=T)
    n_code = np.bincount(eP[w["P"] > 0], minlength=T)
    info = res.normal if res.normal is not None else sp.eye(n, format="csc")
    out: list[SppEpoch] = []
    covs = _position_blocks_inverse(info, T, blk)
    for i in range(T):
        cov = covs[i]
        if tr.cov0[i] is not None:
            cov = covariance_floor(cov, tr.cov0[i])  # type: ignore[arg-type]
        ok = bool(pos_used[i] >= 4)
        clk = {s: float(X[i, lay.clk + q]) for q, s in enumerate(sig.systems)}
        status = "single" if ok else "none"
        out.append(SppEpoch(float(t_s[i]), X[i, 0:3].copy(), clk, cov, int(n_code[i]), status,
                            tuple(excluded[i]), ok, X[i, 3:6].copy(), 1.0))  # fmt: skip
    notify_progress(progress, 2 * T, 2 * T, "single")
    return out


__all__ = [
    "MIN_SCALE_ROWS", "WEAK_PRIOR_SIGMA", "FgoDiagnostics", "TrackStates", "arc_tests", "solve_spp_fgo",
    "residual_scale", "track_states",
]  # fmt: skip
