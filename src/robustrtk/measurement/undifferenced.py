"""Undifferenced code observations: satellite states of one epoch, atmosphere, variance
model, and the weighted least-squares position with fault detection and exclusion (FDE).

Observation equation of one pseudorange ``P_i`` of system ``s`` (m)::

    P_i + c dt_i - I_i - T_i = rho_i(r) + b_s + e_i

with ``c dt_i`` the broadcast satellite clock minus the group delay (``T_GD``), ``rho_i``
the geometric range with the Sagnac term (:func:`robustrtk.geometry.los.geometric_range`),
``I_i`` the Klobuchar delay scaled to the signal frequency, ``T_i`` the Saastamoinen slant
delay and ``b_s`` the receiver clock of system ``s`` (m). Variance model
(:func:`elevation_cn0_variance`)::

    sigma_i^2 = sigma^2 / sin^2(el_i) * 10^(max(0, cn0_ref - cn0_i) / 10)

Least squares (:func:`lsq_solve`) is Gauss–Newton from the Earth's centre (or a given
start); :func:`lsq_fde` adds the chi-square test of the weighted residuals and excludes the
largest standardized residual while the test fails.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from robustrtk.core import CLIGHT, FloatArray, ObsBatch, row_norms, vector_norm
from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.geometry.frames import ecef2enu_rotation, ecef2geodetic
from robustrtk.geometry.los import geometric_range
from robustrtk.io.rinex_nav import NavData
from robustrtk.measurement.chi2 import chi2_ppf
from robustrtk.measurement.corrections import F_L1_HZ, iono_klobuchar, tropo_saastamoinen

#: Tropospheric and ionospheric model names :func:`atmosphere` accepts.
TROPO_MODELS: tuple[str, ...] = ("off", "saastamoinen")
IONO_MODELS: tuple[str, ...] = ("off", "klobuchar")
#: Elevation floor of the variance model (rad).
ELEV_FLOOR_RAD = float(np.deg2rad(5.0))


# ---------------------------------------------------------------------- epoch geometry
@dataclass
class EpochGeometry:
    """Satellite states and code observations of one epoch (rows = satellites).

    Attributes
    ----------
    ids, sys : tuple of str
        Transmitter ids and system letters.
    code_m, cn0_dbhz : ndarray, shape (n,)
    rate_m_s : ndarray, shape (n,)
        ``-lambda D`` (m/s), NaN when absent.
    freq_hz : ndarray, shape (n,)
        Carrier frequency of the code (L1 when unknown).
    sat_pos_m, sat_vel_m_s : ndarray, shape (n, 3)
        At the transmission time.
    sat_clk_m : ndarray, shape (n,)
        ``c (dt - T_GD)`` (m).
    sat_drift_m_s : ndarray, shape (n,)
    ok : ndarray of bool, shape (n,)
        Usable rows (ephemeris and clock available).
    """

    ids: tuple[str, ...]
    sys: tuple[str, ...]
    code_m: FloatArray
    cn0_dbhz: FloatArray
    rate_m_s: FloatArray
    freq_hz: FloatArray
    sat_pos_m: FloatArray
    sat_vel_m_s: FloatArray
    sat_clk_m: FloatArray
    sat_drift_m_s: FloatArray
    ok: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))


def carrier_frequency(wavelength_m: FloatArray) -> FloatArray:
    """``c / lambda`` per row, the L1 frequency where the wavelength is unknown."""
    wl = np.asarray(wavelength_m, float)
    good = np.isfinite(wl)
    return np.where(good, CLIGHT / np.where(good, wl, 1.0), F_L1_HZ)


def epoch_geometry(batch: ObsBatch, i: int, eph: EphemerisSource, column: int = 0) -> EpochGeometry:
    """Satellite states of epoch ``i`` for the code of signal ``column`` (rows with code)."""
    code = batch.code_m[i, :, column]
    idx = np.flatnonzero(np.isfinite(code))
    ids = tuple(batch.tx_ids[j] for j in idx)
    t = float(batch.t_s[i])
    wl = batch.wavelength_m[idx, column]
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
    return EpochGeometry(
        ids=ids,
        sys=tuple(batch.system[j] for j in idx),
        code_m=code[idx],
        cn0_dbhz=batch.cn0_dbhz[i, idx, column],
        rate_m_s=-wl * batch.doppler_hz[i, idx, column],
        freq_hz=carrier_frequency(wl),
        sat_pos_m=pos,
        sat_vel_m_s=vel,
        sat_clk_m=clk_m,
        sat_drift_m_s=drift * CLIGHT,
        ok=ok,
    )


# ---------------------------------------------------------------------- atmosphere
@dataclass(frozen=True)
class Atmosphere:
    """Look angles and atmospheric delays of each satellite seen from one position.

    Attributes
    ----------
    el_rad, az_rad : ndarray, shape (n,)
    tropo_m : ndarray, shape (n,)
        Slant tropospheric delay (0 when off or outside the model's height range).
    iono_m : ndarray, shape (n,)
        Klobuchar group delay at the requested frequencies (0 when off or without
        broadcast coefficients).
    """

    el_rad: FloatArray
    az_rad: FloatArray
    tropo_m: FloatArray
    iono_m: FloatArray

    @property
    def code_delay_m(self) -> FloatArray:
        """``I + T``: what a pseudorange carries (m)."""
        return self.tropo_m + self.iono_m


def atmosphere(
    t_s: float,
    sat_pos_m: FloatArray,
    rx_m: FloatArray,
    nav: NavData,
    tropo: str = "saastamoinen",
    iono: str = "klobuchar",
    freq_hz: FloatArray | float = F_L1_HZ,
) -> Atmosphere:
    """Elevation, azimuth and delays of satellites at ``sat_pos_m`` seen from ``rx_m``.

    Away from the Earth's surface (the start of a Gauss–Newton iteration from the centre)
    elevations are ``pi/2``, azimuths 0 and delays 0.
    """
    if tropo not in TROPO_MODELS:
        raise ValueError(f"tropo: expected one of {', '.join(TROPO_MODELS)}, got {tropo!r}")
    if iono not in IONO_MODELS:
        raise ValueError(f"iono: expected one of {', '.join(IONO_MODELS)}, got {iono!r}")
    n = int(np.shape(sat_pos_m)[0])
    if not 6.2e6 < vector_norm(np.ravel(np.asarray(rx_m, float), order="K")) < 6.6e6:
        return Atmosphere(np.full(n, np.pi / 2), np.zeros(n), np.zeros(n), np.zeros(n))
    lat, lon, h = ecef2geodetic(rx_m)
    rot = ecef2enu_rotation(float(lat), float(lon))
    enu = (sat_pos_m - rx_m) @ rot.T
    # np.clip(·, -1, 1) as minimum of maximum: the same numbers without its wrapper
    el = np.arcsin(np.minimum(np.maximum(enu[:, 2] / row_norms(enu), -1.0), 1.0))
    az = np.mod(np.arctan2(enu[:, 0], enu[:, 1]), 2 * np.pi)
    trop: FloatArray = np.zeros(n)
    if tropo == "saastamoinen" and -1000.0 < float(h) < 1.0e4:
        trop = tropo_saastamoinen(float(lat), float(h), el)
    ion: FloatArray = np.zeros(n)
    if iono == "klobuchar" and nav.ion_gps_alpha is not None and nav.ion_gps_beta is not None:
        ion = iono_klobuchar(
            t_s, float(lat), float(lon), az, el, nav.ion_gps_alpha, nav.ion_gps_beta, freq_hz
        )
    return Atmosphere(el, az, trop, ion)


# ---------------------------------------------------------------------- variance
def elevation_cn0_variance(
    sigma_m: float,
    elev_rad: FloatArray,
    cn0_dbhz: FloatArray | None = None,
    *,
    cn0_ref_dbhz: float = 45.0,
    elev_floor_rad: float = ELEV_FLOOR_RAD,
) -> FloatArray:
    """``sigma^2 / sin^2(el) * 10^(max(0, cn0_ref - cn0) / 10)`` per row.

    The elevation is floored at ``elev_floor_rad``; without ``cn0_dbhz`` (None) there is no
    C/N0 term, and a NaN C/N0 counts as ``cn0_ref_dbhz`` (no down-weighting).
    """
    s = np.sin(np.maximum(np.asarray(elev_rad, float), elev_floor_rad))
    v: FloatArray = sigma_m**2 / s**2
    if cn0_dbhz is not None:
        c = np.asarray(cn0_dbhz, float)
        c = np.where(np.isnan(c), cn0_ref_dbhz, c)  # ±inf need no clamping: the same factor
        v = v * 10.0 ** (np.maximum(0.0, cn0_ref_dbhz - c) / 10.0)
    return v


def cn0_variance(sigma_ref: float, cn0_dbhz: FloatArray | float, cn0_ref_dbhz: float = 45.0) -> FloatArray:
    """``sigma_ref^2 * 10^((cn0_ref - cn0) / 10)`` per row: a tracking loop's thermal noise
    variance is inversely proportional to the carrier-to-noise density (docs/algorithms.md §19).

    ``sigma_ref`` is the σ at ``cn0_ref_dbhz`` (any unit; the result is in its square); a NaN
    C/N0 counts as ``cn0_ref_dbhz``. No elevation term: the C/N0 already carries the
    antenna gain pattern and the attenuation of low or obstructed signals.
    """
    c = np.asarray(cn0_dbhz, float)
    c = np.where(np.isnan(c), cn0_ref_dbhz, c)  # ±inf need no clamping: the same factor
    out: FloatArray = sigma_ref**2 * 10.0 ** ((cn0_ref_dbhz - c) / 10.0)
    return out


# ---------------------------------------------------------------------- least squares
@dataclass(frozen=True)
class LsqSettings:
    """Settings of the single-epoch least squares and its FDE.

    Attributes
    ----------
    elev_mask_deg : float
    code_sigma_m : float
        Zenith code standard deviation at ``cn0_ref_dbhz`` (m).
    use_cn0 : bool
        Apply the C/N0 term of the variance model.
    cn0_ref_dbhz : float
    snr_mask_dbhz : float
        Rows below this C/N0 are not used (0 = keep all).
    tropo, iono : str
        Models of :func:`atmosphere`.
    fde : bool
        Fault detection and exclusion.
    fde_alpha : float
        False-alarm probability of the chi-square test.
    max_exclusions : int
    max_iter : int
        Gauss–Newton iterations.
    """

    elev_mask_deg: float = 15.0
    code_sigma_m: float = 3.0
    use_cn0: bool = True
    cn0_ref_dbhz: float = 45.0
    snr_mask_dbhz: float = 0.0
    tropo: str = "saastamoinen"
    iono: str = "klobuchar"
    fde: bool = True
    fde_alpha: float = 1e-3
    max_exclusions: int = 6
    max_iter: int = 10


@dataclass
class LsqSolution:
    """One least-squares solution.

    Attributes
    ----------
    pos : ndarray, shape (3,)
        ECEF position (m).
    clk : dict str -> float
        Receiver clock per system (m).
    cov : ndarray, shape (3 + n_sys, 3 + n_sys)
        Covariance of position and clocks under the variance model.
    v, var : ndarray, shape (m,)
        Post-fit residuals and variances of the rows used.
    H : ndarray, shape (m, 3 + n_sys)
    rows : ndarray of int, shape (m,)
        Indices of the rows used (into the :class:`EpochGeometry`).
    n_unknowns : int
    """

    pos: FloatArray
    clk: dict[str, float]
    cov: FloatArray
    v: FloatArray
    var: FloatArray
    H: FloatArray
    rows: np.ndarray
    n_unknowns: int


#: One Gauss–Newton iteration of :func:`lsq_solve`: position, inverse normal matrix,
#: residuals, design, step, variances, rows used and number of unknowns.
_LsqIteration = tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, np.ndarray, int]


def lsq_solve(
    t_s: float,
    g: EpochGeometry,
    use: np.ndarray,
    nav: NavData,
    settings: LsqSettings,
    x0: FloatArray | None = None,
) -> LsqSolution | None:
    """Weighted Gauss–Newton on the ``use`` rows, one receiver clock per system.

    Starts at ``x0`` (the Earth's centre when None); the elevation mask applies once the
    position is near the Earth's surface. None when under-determined or singular.
    """
    pos = np.zeros(3) if x0 is None else np.asarray(x0, float).copy()
    clk: dict[str, float] = {}
    mask = np.deg2rad(settings.elev_mask_deg)
    last: (
        tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, np.ndarray, int] | None
    )
    last = None
    for _ in range(settings.max_iter):
        atm = atmosphere(t_s, g.sat_pos_m, pos, nav, settings.tropo, settings.iono, g.freq_hz)
        el, delay = atm.el_rad, atm.code_delay_m
        act = np.flatnonzero(use & (el >= mask))
        sys_act = [g.sys[j] for j in act.tolist()]
        systems = sorted(set(sys_act))
        n_unk = 3 + len(systems)
        if act.size < n_unk:
            return None
        rng, u = geometric_range(g.sat_pos_m[act], pos)
        col_of = {s: k for k, s in enumerate(systems)}
        col = np.array([col_of[s] for s in sys_act], dtype=int)
        b = np.array([clk.get(s, 0.0) for s in systems])
        v = g.code_m[act] + g.sat_clk_m[act] - delay[act] - rng - b[col]
        H = np.zeros((act.size, n_unk))
        H[:, :3] = -u
        H[np.arange(act.size), 3 + col] = 1.0
        cn0 = g.cn0_dbhz[act] if settings.use_cn0 else None
        var = elevation_cn0_variance(settings.code_sigma_m, el[act], cn0, cn0_ref_dbhz=settings.cn0_ref_dbhz)
        sw = 1.0 / np.sqrt(var)
        Hw = H * sw[:, None]
        N = Hw.T @ Hw
        N_inv = _inverse_if_conditioned(N)
        if N_inv is None:
            return None
        dx = np.linalg.solve(N, Hw.T @ (v * sw))
        pos = pos + dx[:3]
        for k, s in enumerate(systems):
            clk[s] = float(b[k] + dx[3 + k])
        last = (pos, N_inv, v, H, dx, var, act, n_unk)
        if vector_norm(dx) < 1e-4:
            break
    if last is None:
        return None
    # the solution of the last iteration (its clocks are the last ``clk``)
    p, N_inv, v, H, dx, var, act, n_unk = last
    return LsqSolution(p, dict(clk), N_inv, v - H @ dx, var, H, act, n_unk)


def _inverse_if_conditioned(N: FloatArray) -> FloatArray | None:
    """``inv(N)`` when ``cond₂(N) ≤ 1e14``, else None.

    ``cond₂(N) ≤ ‖N‖_F ‖N⁻¹‖_F``: where that bound is below 1e13 (a decade of margin for
    the rounding of both computations) the test passes without the singular values; the
    other matrices get :func:`numpy.linalg.cond`, the test itself.
    """
    try:
        inv = np.linalg.inv(N)
    except np.linalg.LinAlgError:
        inv = None
    if inv is not None:
        with np.errstate(over="ignore", invalid="ignore"):
            bound = float(np.sqrt(np.sum(N * N) * np.sum(inv * inv)))
        if bound <= 1e13:
            return inv
    if np.linalg.cond(N) > 1e14:
        return None
    return inv if inv is not None else np.linalg.inv(N)


def worst_row(w: FloatArray) -> int:
    """Index of the largest standardized residual ``w`` (m,), the lowest index among values
    within a relative 1e-6 of the largest: two rows the model makes symmetric (the only two
    satellites of a system with its own clock) have equal ``|v| / σ_v`` up to rounding and to
    the iteration's stop (a step under 0.1 mm), and the same row is excluded whatever the
    order of the arithmetic."""
    top = float(np.max(w))
    return int(np.flatnonzero(w >= top - 1e-6 * abs(top))[0])


def lsq_fde(
    t_s: float,
    g: EpochGeometry,
    nav: NavData,
    settings: LsqSettings,
    x0: FloatArray | None = None,
) -> tuple[LsqSolution | None, list[str], bool]:
    """Least squares with chi-square fault detection and exclusion.

    Test ``T = v^T W v > chi2_{1-alpha}(m - n)``; while it fails and at least two degrees
    of freedom remain, exclude the row with the largest standardized residual
    ``|v_i| / sqrt((R - H N^-1 H^T)_ii)`` and re-solve. Rows below ``snr_mask_dbhz`` are
    not used. A solution far below the Earth's surface counts as none.

    Returns
    -------
    solution : LsqSolution or None
    excluded : list of str
        Ids of the excluded rows, in order.
    ok : bool
        The final test passed (or had no degree of freedom, or FDE is off).
    """
    use = g.ok.copy()
    if settings.snr_mask_dbhz > 0:
        use &= ~(g.cn0_dbhz < settings.snr_mask_dbhz)
    excluded: list[str] = []
    out = lsq_solve(t_s, g, use, nav, settings, x0)
    if out is not None and vector_norm(out.pos) < 6.0e6:
        out = None
    while out is not None:
        dof = out.rows.size - out.n_unknowns
        if dof < 1 or not settings.fde:
            return out, excluded, True
        test = float(np.sum(out.v**2 / out.var))
        if test <= chi2_ppf(1.0 - settings.fde_alpha, dof):
            return out, excluded, True
        if dof < 2 or len(excluded) >= settings.max_exclusions:
            return out, excluded, False
        cvv = out.var - np.einsum("ij,jk,ik->i", out.H, out.cov, out.H)
        w = np.abs(out.v) / np.sqrt(np.maximum(cvv, 1e-12 * out.var))
        worst = int(out.rows[worst_row(w)])
        use[worst] = False
        excluded.append(g.ids[worst])
        nxt = lsq_solve(t_s, g, use, nav, settings, out.pos)
        if nxt is None:
            return out, excluded[:-1], False
        out = nxt
    return None, excluded, False


__all__ = [
    "ELEV_FLOOR_RAD",
    "IONO_MODELS",
    "TROPO_MODELS",
    "Atmosphere",
    "EpochGeometry",
    "LsqSettings",
    "LsqSolution",
    "atmosphere",
    "carrier_frequency",
    "cn0_variance",
    "elevation_cn0_variance",
    "epoch_geometry",
    "lsq_fde",
    "lsq_solve",
    "worst_row",
]
