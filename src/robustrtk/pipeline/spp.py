"""Single point positioning (SPP) from code pseudoranges and broadcast ephemerides.

Two estimators share the same corrections:

* :func:`solve_spp` — per-epoch weighted least squares (Gauss–Newton) with one receiver
  clock per system, and RAIM-like fault detection and exclusion (FDE), on one L1/E1/B1
  code per satellite.
* :func:`solve_spp_kalman` — a robust Kalman filter on code, Doppler and carrier phase of
  one or two bands (position, velocity, code and phase clocks per system, a common clock
  drift, inter-frequency code biases, one float bias per carrier-phase arc), with an
  optional Rauch–Tung–Striebel smoother; model in :mod:`robustrtk.pipeline.spp_kalman`.

Observation equation of one L1/E1/B1 pseudorange ``P_i`` of system ``s`` (m)::

    P_i + c dt_i - I_i - T_i = rho_i(r) + b_s + e_i

with ``c dt_i`` the broadcast satellite clock minus the group delay (``T_GD``),
``rho_i`` the geometric range with the Sagnac term
(:func:`robustrtk.geometry.los.geometric_range`), ``I_i`` the Klobuchar delay scaled to the
signal frequency, ``T_i`` the Saastamoinen slant delay and ``b_s`` the receiver clock of
system ``s`` (m). Variance model::

    sigma_i^2 = sigma^2 / sin^2(el_i) * 10^(max(0, cn0_ref - cn0_i) / 10)

Doppler ``D_i`` (Hz, wavelength ``lambda_i``) gives the range rate
``-lambda_i D_i + c ddt_i = u_i . (v_i - v) + d + e`` (``d`` the receiver clock drift, m/s).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.stats import chi2

from robustrtk.core import CLIGHT, FloatArray, InputError, ObsBatch, Solution
from robustrtk.estimation.filters import EKF, UKF, Filter
from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.geometry.frames import ecef2enu_rotation, ecef2geodetic
from robustrtk.geometry.los import geometric_range
from robustrtk.io.rinex_nav import NavData
from robustrtk.measurement.corrections import iono_klobuchar, tropo_saastamoinen

#: Preferred code band digits per system for the single-frequency user (B1I is band 2).
BAND1_PREFERENCE: dict[str, tuple[str, ...]] = {
    "G": ("1",),
    "J": ("1",),
    "E": ("1",),
    "R": ("1",),
    "S": ("1",),
    "C": ("2", "1"),
    "I": ("5",),
}
F_L1_HZ = 1575.42e6


@dataclass(frozen=True)
class SppConfig:
    """Settings of the SPP estimators.

    Attributes
    ----------
    elev_mask_deg : float
        Elevation mask (deg).
    code_sigma_m : float
        Zenith code standard deviation at ``cn0_ref_dbhz`` (m).
    cn0_ref_dbhz : float
        C/N0 above which no C/N0 down-weighting is applied (dB-Hz).
    use_cn0 : bool
        Apply the C/N0 term of the variance model.
    min_cn0_dbhz : float
        Observations below this C/N0 are not used (0 = keep all).
    iono, tropo : bool
        Apply Klobuchar / Saastamoinen corrections.
    raim : bool
        Fault detection and exclusion in the least-squares solution.
    raim_alpha : float
        False-alarm probability of the chi-square test.
    max_exclusions : int
        Most observations FDE may exclude per epoch.
    max_iter : int
        Gauss–Newton iterations.
    filter : {"ekf", "ukf"}
        Filter of the Kalman SPP.
    robust : str
        Robust policy of the Kalman SPP (see :func:`robustrtk.estimation.robust.make_policy`),
        applied to all its rows (code, phase, Doppler) in one update. Default ``postfit``:
        the worst standardized posterior residual is down-weighted (IGG-III) one row at a
        time, which suits rows of very different precision; the relative statistic of
        ``igg3`` (Li et al.) is meant for a homogeneous set of double differences.
    sigma_acc_m_s2, sigma_acc_up_m_s2 : float
        Horizontal and vertical white-acceleration noise (m/s^2) of the Kalman SPP.
    q_clk_m2_s, q_drift_m2_s3 : float
        Receiver code-clock and drift noise densities (m^2/s, m^2/s^3).
    q_phase_clk_m2_s : float
        Noise density of the carrier-phase clock (m^2/s).
    use_doppler : bool
        Add Doppler range-rate rows to the Kalman update.
    doppler_sigma_m_s : float
        Range-rate standard deviation (m/s) at zenith.
    use_phase : bool
        Add carrier-phase rows with one float bias per continuous arc (Kalman SPP).
    phase_sigma_m : float
        Carrier-phase standard deviation at zenith (m).
    q_amb_m2_s : float
        Random walk of the carrier-phase biases (m^2/s; code–carrier ionospheric divergence).
    amb_var0_m2 : float
        Variance of a new carrier-phase bias (m^2).
    lli_reset : bool
        A set loss-of-lock bit starts a new arc; otherwise it only adds ``slip_var_m2``
        to the arc's bias (and a real slip is caught by the robust update).
    slip_var_m2 : float
        Variance added to a bias whose phase carries a loss-of-lock flag (m^2).
    dual_frequency : bool
        Kalman SPP: also use the second band (L5/E5a, else L2/E5b/B3) with an
        inter-frequency code bias per system.
    q_ifb_m2_s : float
        Random walk of the inter-frequency code biases (m^2/s).
    kalman_use_cn0 : bool
        Apply the C/N0 factor to the Kalman rows. Off by default: on the Pixel 5 drive,
        elevation-only weights with the post-fit test gave a mean of p50 and p95 of 2.5 m
        against 3.8 m with the C/N0 factor (low-C/N0 codes are biased by reflections, not
        only noisy).
    smoother : bool
        Kalman SPP: replace the forward estimates by Rauch–Tung–Striebel smoothed ones
        (post-processing; uses future data).
    clock_reset_m : float
        A per-system median innovation beyond this resets that clock state (m).
    reinit_m : float
        When the filter and the epoch's FDE least-squares solution disagree by more than
        this (m, 3D) for ``reinit_epochs`` epochs in a row, the filter is re-initialised.
    """

    elev_mask_deg: float = 15.0
    code_sigma_m: float = 3.0
    cn0_ref_dbhz: float = 45.0
    use_cn0: bool = True
    min_cn0_dbhz: float = 0.0
    iono: bool = True
    tropo: bool = True
    raim: bool = True
    raim_alpha: float = 1e-3
    max_exclusions: int = 6
    max_iter: int = 10
    filter: str = "ekf"
    robust: str = "postfit"
    sigma_acc_m_s2: float = 3.0
    sigma_acc_up_m_s2: float = 0.5
    q_clk_m2_s: float = 1000.0
    q_drift_m2_s3: float = 10.0
    q_phase_clk_m2_s: float = 100.0
    use_doppler: bool = True
    doppler_sigma_m_s: float = 0.5
    use_phase: bool = True
    phase_sigma_m: float = 0.05
    q_amb_m2_s: float = 1e-4
    amb_var0_m2: float = 1e4
    lli_reset: bool = False
    slip_var_m2: float = 0.01
    dual_frequency: bool = True
    q_ifb_m2_s: float = 1e-4
    kalman_use_cn0: bool = False
    smoother: bool = False
    clock_reset_m: float = 1000.0
    reinit_m: float = 100.0
    reinit_epochs: int = 5


@dataclass(frozen=True)
class SppEpoch:
    """One epoch of SPP output.

    Attributes
    ----------
    t_s : float
        GPST seconds.
    pos_ecef_m : ndarray, shape (3,)
    clock_m : dict str -> float
        Receiver clock per system (m).
    cov_m2 : ndarray, shape (3, 3)
        Position covariance (m^2) under the variance model.
    n_used : int
    status : str
        ``"single"`` or ``"none"``.
    excluded : tuple of str
        Satellites excluded by FDE; for the Kalman SPP the rows its robust update
        rejected (``"G05:P1"`` code, ``"G05:L5"`` phase, ``"G05:D1"`` Doppler).
    chi2_ok : bool
        The final chi-square test passed (Kalman SPP: at least four code or phase rows used).
    vel_ecef_m_s : ndarray, shape (3,) or None
    """

    t_s: float
    pos_ecef_m: FloatArray
    clock_m: dict[str, float]
    cov_m2: FloatArray
    n_used: int
    status: str
    excluded: tuple[str, ...] = ()
    chi2_ok: bool = True
    vel_ecef_m_s: FloatArray | None = None

    def to_solution(self) -> Solution:
        """As a :class:`robustrtk.core.Solution`."""
        return Solution(
            t_s=self.t_s,
            pos_m=self.pos_ecef_m,
            cov_m2=self.cov_m2,
            status=self.status,
            n_used=self.n_used,
            vel_m_s=self.vel_ecef_m_s,
        )


# ---------------------------------------------------------------------- signal choice
def select_band1(batch: ObsBatch, systems: str | None = None) -> ObsBatch:
    """One-signal batch with the first L1/E1/B1 code column that has data, per system.

    For each system the candidate columns are the batch's signals of the preferred band
    (:data:`BAND1_PREFERENCE`, in batch order); the first with any finite code for that
    system is used for all its satellites. Satellites of systems not in ``systems`` (or
    with no candidate column) are dropped.

    Returns
    -------
    ObsBatch
        ``K = 1``; ``signals = ("1",)``; ``meta["signal_by_system"]`` records the choice.
    """
    sys_arr = np.array(batch.system)
    keep_rows: list[int] = []
    col_of_row: list[int] = []
    choice: dict[str, str] = {}
    for s in dict.fromkeys(batch.system):
        if systems is not None and s not in systems:
            continue
        rows = np.flatnonzero(sys_arr == s)
        col = -1
        for band in BAND1_PREFERENCE.get(s, ("1",)):
            for k, sig in enumerate(batch.signals):
                if sig[:1] == band and np.isfinite(batch.code_m[:, rows, k]).any():
                    col = k
                    break
            if col >= 0:
                break
        if col < 0:
            continue
        choice[s] = batch.signals[col]
        keep_rows.extend(rows.tolist())
        col_of_row.extend([col] * rows.size)
    order = np.argsort(keep_rows, kind="stable")
    r = np.asarray(keep_rows, dtype=np.int64)[order]
    c = np.asarray(col_of_row, dtype=np.int64)[order]

    def take(a: np.ndarray) -> np.ndarray:
        return a[:, r, c][:, :, None]

    meta = dict(batch.meta)
    meta["signal_by_system"] = choice
    return replace(
        batch,
        tx_ids=tuple(batch.tx_ids[i] for i in r),
        system=tuple(batch.system[i] for i in r),
        signals=("1",),
        code_m=take(batch.code_m),
        phase_cyc=take(batch.phase_cyc),
        doppler_hz=take(batch.doppler_hz),
        cn0_dbhz=take(batch.cn0_dbhz),
        lli=take(batch.lli),
        wavelength_m=batch.wavelength_m[r, c][:, None],
        meta=meta,
    )


# ---------------------------------------------------------------------- corrections
@dataclass
class _EpochGeometry:
    """Satellite states and corrections of one epoch (rows = satellites)."""

    ids: tuple[str, ...]
    sys: tuple[str, ...]
    code_m: FloatArray
    cn0_dbhz: FloatArray
    rate_m_s: FloatArray  # -lambda D (m/s), NaN when absent
    freq_hz: FloatArray
    sat_pos_m: FloatArray
    sat_vel_m_s: FloatArray
    sat_clk_m: FloatArray
    sat_drift_m_s: FloatArray
    ok: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))


def _epoch_geometry(batch: ObsBatch, i: int, eph: EphemerisSource) -> _EpochGeometry:
    code = batch.code_m[i, :, 0]
    have = np.isfinite(code)
    idx = np.flatnonzero(have)
    ids = tuple(batch.tx_ids[j] for j in idx)
    t = float(batch.t_s[i])
    wl = batch.wavelength_m[idx, 0]
    freq = np.where(np.isfinite(wl), CLIGHT / np.where(np.isfinite(wl), wl, 1.0), F_L1_HZ)
    if idx.size:
        t_tx = eph.transmission_time(t, ids, code[idx])
        pos, vel, clk, drift, ok = eph.sat_states(t_tx, ids)
        tgd = eph.group_delay_s(t_tx, ids)
        clk_m = (clk - tgd) * CLIGHT
        ok = ok & np.isfinite(clk_m)
    else:
        pos = vel = np.zeros((0, 3))
        clk_m = drift = np.zeros(0)
        ok = np.zeros(0, bool)
    return _EpochGeometry(
        ids=ids,
        sys=tuple(batch.system[j] for j in idx),
        code_m=code[idx],
        cn0_dbhz=batch.cn0_dbhz[i, idx, 0],
        rate_m_s=-wl * batch.doppler_hz[i, idx, 0],
        freq_hz=freq,
        sat_pos_m=pos,
        sat_vel_m_s=vel,
        sat_clk_m=clk_m,
        sat_drift_m_s=drift * CLIGHT,
        ok=ok,
    )


def _atmosphere(
    t_s: float, g: _EpochGeometry, rx_m: FloatArray, nav: NavData, cfg: SppConfig
) -> tuple[FloatArray, FloatArray]:
    """Elevation (rad) and the sum of ionospheric and tropospheric delays (m) per row.

    Near the Earth's centre (start of the iteration) elevations are pi/2 and delays 0.
    """
    n = len(g.ids)
    if not 6.2e6 < float(np.linalg.norm(rx_m)) < 6.6e6:
        return np.full(n, np.pi / 2), np.zeros(n)
    lat, lon, h = ecef2geodetic(rx_m)
    rot = ecef2enu_rotation(float(lat), float(lon))
    enu = (g.sat_pos_m - rx_m) @ rot.T
    el = np.arcsin(np.clip(enu[:, 2] / np.linalg.norm(enu, axis=1), -1.0, 1.0))
    az = np.mod(np.arctan2(enu[:, 0], enu[:, 1]), 2 * np.pi)
    delay = np.zeros(n)
    if cfg.tropo and -1000.0 < float(h) < 1.0e4:
        delay += tropo_saastamoinen(float(lat), float(h), el)
    if cfg.iono and nav.ion_gps_alpha is not None and nav.ion_gps_beta is not None:
        delay += iono_klobuchar(
            t_s, float(lat), float(lon), az, el, nav.ion_gps_alpha, nav.ion_gps_beta, g.freq_hz
        )
    return el, delay


def _variance(
    cfg: SppConfig, el: FloatArray, cn0: FloatArray, sigma: float, use_cn0: bool | None = None
) -> FloatArray:
    """``sigma^2 / sin^2(el) * 10^(max(0, cn0_ref - cn0)/10)`` (el floored at 5 deg); the
    C/N0 factor only when ``use_cn0`` (default ``cfg.use_cn0``)."""
    s = np.sin(np.maximum(el, np.deg2rad(5.0)))
    v = sigma**2 / s**2
    if cfg.use_cn0 if use_cn0 is None else use_cn0:
        c = np.nan_to_num(cn0, nan=cfg.cn0_ref_dbhz)
        v = v * 10.0 ** (np.maximum(0.0, cfg.cn0_ref_dbhz - c) / 10.0)
    return v


# ---------------------------------------------------------------------- least squares
@dataclass
class _LsqOut:
    pos: FloatArray
    clk: dict[str, float]
    cov: FloatArray
    v: FloatArray  # residuals of used rows
    var: FloatArray
    H: FloatArray
    rows: np.ndarray  # indices of used rows
    n_unknowns: int


def _gauss_newton(
    t_s: float,
    g: _EpochGeometry,
    use: np.ndarray,
    nav: NavData,
    cfg: SppConfig,
    x0: FloatArray | None,
) -> _LsqOut | None:
    """Weighted Gauss–Newton on ``use`` rows; the elevation mask is applied once the
    position is near the Earth's surface. None when under-determined or singular."""
    pos = np.zeros(3) if x0 is None else np.asarray(x0, float).copy()
    clk: dict[str, float] = {}
    mask = np.deg2rad(cfg.elev_mask_deg)
    out: _LsqOut | None = None
    for _ in range(cfg.max_iter):
        el, delay = _atmosphere(t_s, g, pos, nav, cfg)
        act = np.flatnonzero(use & (el >= mask))
        systems = sorted({g.sys[j] for j in act})
        n_unk = 3 + len(systems)
        if act.size < n_unk:
            return None
        rng, u = geometric_range(g.sat_pos_m[act], pos)
        col = np.array([systems.index(g.sys[j]) for j in act])
        b = np.array([clk.get(s, 0.0) for s in systems])
        v = g.code_m[act] + g.sat_clk_m[act] - delay[act] - rng - b[col]
        H = np.zeros((act.size, n_unk))
        H[:, :3] = -u
        H[np.arange(act.size), 3 + col] = 1.0
        var = _variance(cfg, el[act], g.cn0_dbhz[act], cfg.code_sigma_m)
        sw = 1.0 / np.sqrt(var)
        Hw = H * sw[:, None]
        N = Hw.T @ Hw
        if np.linalg.cond(N) > 1e14:
            return None
        dx = np.linalg.solve(N, Hw.T @ (v * sw))
        pos = pos + dx[:3]
        for k, s in enumerate(systems):
            clk[s] = float(b[k] + dx[3 + k])
        out = _LsqOut(pos, dict(clk), np.linalg.inv(N), v - H @ dx, var, H, act, n_unk)
        if np.linalg.norm(dx) < 1e-4:
            break
    return out


def _lsq_fde(
    t_s: float, g: _EpochGeometry, nav: NavData, cfg: SppConfig, x0: FloatArray | None
) -> tuple[_LsqOut | None, list[str], bool]:
    """Least squares with chi-square fault detection and exclusion.

    Test ``T = v^T W v > chi2_{1-alpha}(m - n)``; while it fails and at least two degrees
    of freedom remain, exclude the row with the largest standardized residual
    ``|v_i| / sqrt((R - H N^-1 H^T)_ii)`` and re-solve.
    """
    use = g.ok.copy()
    if cfg.min_cn0_dbhz > 0:
        use &= ~(g.cn0_dbhz < cfg.min_cn0_dbhz)
    excluded: list[str] = []
    out = _gauss_newton(t_s, g, use, nav, cfg, x0)
    if out is not None and float(np.linalg.norm(out.pos)) < 6.0e6:
        out = None
    while out is not None:
        dof = out.rows.size - out.n_unknowns
        if dof < 1 or not cfg.raim:
            return out, excluded, True
        test = float(np.sum(out.v**2 / out.var))
        if test <= chi2.ppf(1.0 - cfg.raim_alpha, dof):
            return out, excluded, True
        if dof < 2 or len(excluded) >= cfg.max_exclusions:
            return out, excluded, False
        cvv = out.var - np.einsum("ij,jk,ik->i", out.H, out.cov, out.H)
        w = np.abs(out.v) / np.sqrt(np.maximum(cvv, 1e-12 * out.var))
        worst = int(out.rows[int(np.argmax(w))])
        use[worst] = False
        excluded.append(g.ids[worst])
        nxt = _gauss_newton(t_s, g, use, nav, cfg, out.pos)
        if nxt is None:
            return out, excluded[:-1], False
        out = nxt
    return None, excluded, False


def _nav_source(nav: NavData | EphemerisSource) -> tuple[NavData, EphemerisSource]:
    if isinstance(nav, EphemerisSource):
        return nav.nav, nav
    return nav, EphemerisSource(nav)


def solve_spp(
    batch: ObsBatch,
    nav: NavData | EphemerisSource,
    cfg: SppConfig | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> list[SppEpoch]:
    """Per-epoch weighted least-squares SPP with FDE.

    Parameters
    ----------
    batch : ObsBatch
        Observations; the L1/E1/B1 column per system is selected with
        :func:`select_band1` unless the batch already has a single signal.
    nav : NavData or EphemerisSource
    cfg : SppConfig
    progress : callable (done, total), optional

    Returns
    -------
    list of SppEpoch, one per epoch (status ``"none"`` with NaN position when unsolved).
    """
    cfg = cfg or SppConfig()
    navd, eph = _nav_source(nav)
    b1 = batch if len(batch.signals) == 1 else select_band1(batch)
    out: list[SppEpoch] = []
    prev: FloatArray | None = None
    for i in range(len(b1)):
        t = float(b1.t_s[i])
        g = _epoch_geometry(b1, i, eph)
        lsq, excl, ok = _lsq_fde(t, g, navd, cfg, prev)
        if lsq is None:
            out.append(_none_epoch(t))
        else:
            prev = lsq.pos
            out.append(
                SppEpoch(
                    t,
                    lsq.pos.copy(),
                    lsq.clk,
                    lsq.cov[:3, :3].copy(),
                    int(lsq.rows.size),
                    "single",
                    tuple(excl),
                    ok,
                )
            )
        if progress is not None:
            progress(i + 1, len(b1))
    return out


def _none_epoch(t: float) -> SppEpoch:
    return SppEpoch(t, np.full(3, np.nan), {}, np.full((3, 3), np.nan), 0, "none", (), False)


# ---------------------------------------------------------------------- Kalman SPP
def _make_filter(name: str) -> Filter:
    if name == "ekf":
        return EKF()
    if name == "ukf":
        return UKF()
    raise InputError(f"filter: expected ekf or ukf, got {name!r}")


def solve_spp_kalman(
    batch: ObsBatch,
    nav: NavData | EphemerisSource,
    cfg: SppConfig | None = None,
    progress: Callable[[int, int], None] | None = None,
    *,
    systems: str | None = None,
) -> list[SppEpoch]:
    """Robust Kalman-filter SPP on code, Doppler and carrier phase (one or two bands).

    State: position, velocity, a code clock and a carrier-phase clock per system sharing
    one drift, an inter-frequency code bias per system with a second band, and one float
    bias per carrier-phase arc (model and equations in
    :mod:`robustrtk.pipeline.spp_kalman`). Initialised from the first least-squares (FDE)
    solution; each epoch: predict, restart a clock whose per-system median innovation
    exceeds ``clock_reset_m``, then one robust update (``cfg.robust``) of every row of the
    satellites above the mask at the predicted position. The filter is re-initialised from
    the FDE solution when the two disagree by more than ``reinit_m`` for ``reinit_epochs``
    consecutive epochs. With ``cfg.smoother`` the forward estimates are replaced by
    Rauch–Tung–Striebel smoothed ones.

    Parameters
    ----------
    batch : ObsBatch
        Observations with any signals: per system the first band-1 column with code and
        (``cfg.dual_frequency``) a second-band column are used; a batch reduced by
        :func:`select_band1` gives band 1 only.
    nav : NavData or EphemerisSource
    cfg : SppConfig
    progress : callable (done, total), optional
    systems : str, optional
        System letters to use (all with ephemerides when None).

    Returns
    -------
    list of SppEpoch, one per epoch: status ``"single"`` when at least four code or phase
    rows were used, ``"none"`` otherwise (before the first fix: NaN position); ``n_used``
    counts code rows; ``excluded`` lists rows the policy rejected (``"G05:P1"`` code,
    ``"G05:L5"`` phase, ``"G05:D1"`` Doppler).
    """
    from robustrtk.pipeline.spp_kalman import run_kalman

    cfg = cfg or SppConfig()
    _, eph = _nav_source(nav)
    return run_kalman(batch, eph, cfg, progress, systems)


__all__ = [
    "SppConfig",
    "SppEpoch",
    "select_band1",
    "solve_spp",
    "solve_spp_kalman",
]
