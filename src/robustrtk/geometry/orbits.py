"""Broadcast orbit and clock models, vectorised over satellites.

* Keplerian broadcast ephemerides of GPS, QZSS, Galileo and BeiDou (IS-GPS-200 Table
  20-IV; Galileo OS SIS ICD 5.1.1; BeiDou ICD B1I 5.2.4 with CGCS2000 constants and the
  extra rotation for geostationary satellites).
* The relativistic clock correction ``dtr = F e sqrt(A) sin(E)``, ``F = -2 sqrt(GM) / c^2``.
* GLONASS: PZ-90 state vector propagated by RK4 integration of the ICD equations of motion
  (central body + J2 + Earth rotation terms + broadcast luni-solar accelerations).

Positions are ECEF of the system (WGS84, GTRF, CGCS2000, PZ-90.11 — all within a few cm of
each other, ignored here) at the evaluation time itself, i.e. not Sagnac-rotated.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robustrtk.core import CLIGHT, BoolArray, FloatArray
from robustrtk.geometry.los import OMEGA_E_RAD_S
from robustrtk.geometry.navdata import GloNav, KeplerNav


@dataclass(frozen=True)
class SystemConstants:
    """Earth constants a system's broadcast orbits are defined with.

    Attributes
    ----------
    gm_m3_s2 : float
        Gravitational constant times Earth mass (m^3/s^2).
    omega_e_rad_s : float
        Earth rotation rate (rad/s).
    """

    gm_m3_s2: float
    omega_e_rad_s: float

    @property
    def f_rel_s_m05(self) -> float:
        """Relativistic clock constant ``F = -2 sqrt(GM) / c^2`` (s/m^0.5)."""
        return -2.0 * np.sqrt(self.gm_m3_s2) / CLIGHT**2


#: Earth rotation rate of the BeiDou (CGCS2000) and GLONASS (PZ-90) ICDs (rad/s); GPS,
#: QZSS and Galileo use the WGS84 value :data:`robustrtk.geometry.los.OMEGA_E_RAD_S`.
OMEGA_E_CGCS2000_PZ90_RAD_S = 7.292115e-5

#: Constants per system letter.
CONSTANTS: dict[str, SystemConstants] = {
    "G": SystemConstants(3.986005e14, OMEGA_E_RAD_S),
    "J": SystemConstants(3.986005e14, OMEGA_E_RAD_S),
    "E": SystemConstants(3.986004418e14, OMEGA_E_RAD_S),
    "C": SystemConstants(3.986004418e14, OMEGA_E_CGCS2000_PZ90_RAD_S),
    "R": SystemConstants(3.9860044e14, OMEGA_E_CGCS2000_PZ90_RAD_S),
}

#: GLONASS (PZ-90) equatorial radius (m) and second zonal harmonic J2.
GLO_AE_M = 6_378_136.0
GLO_J2 = 1.0826257e-3
# the scalar factors of _glonass_deriv, evaluated as its expressions always evaluated them
_GLO_MU_NEG = -CONSTANTS["R"].gm_m3_s2
_GLO_J2_TERM = -1.5 * GLO_J2 * CONSTANTS["R"].gm_m3_s2 * GLO_AE_M**2
_GLO_WE2 = CONSTANTS["R"].omega_e_rad_s * CONSTANTS["R"].omega_e_rad_s
_GLO_2WE = 2.0 * CONSTANTS["R"].omega_e_rad_s

#: BeiDou GEO satellites with the extra -5 degree inclination rotation.
_BDS_GEO_PRNS = frozenset([1, 2, 3, 4, 5, 59, 60, 61, 62, 63])


def is_beidou_geo(sat_id: np.ndarray) -> BoolArray:
    """True for BeiDou geostationary satellites (C01-C05, C59-C63), shape of ``sat_id``."""
    ids = np.asarray(sat_id, dtype="U3")
    out = np.zeros(ids.shape, dtype=bool)
    for i, s in enumerate(ids.ravel()):
        out.flat[i] = s[:1] == "C" and int(s[1:]) in _BDS_GEO_PRNS
    return out


def eccentric_anomaly(m_rad: FloatArray, e: FloatArray, tol: float = 1e-14) -> FloatArray:
    """Solve Kepler's equation ``E - e sin(E) = M`` by Newton iteration (vectorised).

    ``E ← E − (E − e sin E − M) / (1 − e cos E)`` from ``E = M + e sin M``; each element
    stops at its own first step below ``tol`` (at most 30 steps), so an element's result
    does not depend on the other elements evaluated with it (one satellite, or all the
    satellites of all epochs at once, give the same numbers).
    """
    ecc = np.asarray(e, dtype=float)
    m = np.asarray(m_rad, dtype=float)
    big_e = m + ecc * np.sin(m)
    active = np.ones(np.shape(big_e), dtype=bool)
    for _ in range(30):
        d = (big_e - ecc * np.sin(big_e) - m) / (1.0 - ecc * np.cos(big_e))
        big_e = np.where(active, big_e - d, big_e)
        active &= ~(np.abs(d) < tol)
        if not active.any():
            break
    return big_e


def kepler_ecc_anomaly(eph: KeplerNav, t_s: FloatArray, system: str) -> FloatArray:
    """Eccentric anomaly (rad), shape (N,), of :func:`kepler_position` (same arithmetic) for
    the clock's relativistic term without the position: ``E − e sin E = M0 + n (t − toe)``."""
    k = CONSTANTS[system]
    tk = np.asarray(t_s, dtype=float) - eph.toe_s
    a = eph.sqrt_a_m05**2
    n = np.sqrt(k.gm_m3_s2 / a**3) + eph.delta_n_rad_s
    return eccentric_anomaly(eph.m0_rad + n * tk, eph.e)


def kepler_position(eph: KeplerNav, t_s: FloatArray, system: str) -> tuple[FloatArray, FloatArray]:
    """Satellite ECEF position from Keplerian broadcast elements (IS-GPS-200 Table 20-IV).

    With ``tk = t - toe``::

        A = sqrtA^2, n = sqrt(GM / A^3) + dn, M = M0 + n tk, E - e sin E = M
        v = atan2(sqrt(1 - e^2) sin E, cos E - e),  phi = v + omega
        u = phi + cus sin 2phi + cuc cos 2phi
        r = A (1 - e cos E) + crs sin 2phi + crc cos 2phi
        i = i0 + idot tk + cis sin 2phi + cic cos 2phi
        Omega = Omega0 + (Omega_dot - we) tk - we toe_sow
        x = r cos u cos Omega - r sin u cos i sin Omega
        y = r cos u sin Omega + r sin u cos i cos Omega,  z = r sin u sin i

    BeiDou GEO satellites (C01-C05, C59-C63) use ``Omega = Omega0 + Omega_dot tk - we toe``
    and ``r_ecef = Rz(we tk) Rx(-5 deg) r_gk`` (BeiDou ICD 5.2.4.12).

    Parameters
    ----------
    eph : KeplerNav
        One row per satellite (N rows), already selected.
    t_s : ndarray, shape (N,)
        Evaluation time (GPST s).
    system : str
        ``"G" "J" "E" "C"`` (selects GM and Earth rotation rate).

    Returns
    -------
    pos_ecef_m : ndarray, shape (N, 3)
    ecc_anomaly_rad : ndarray, shape (N,)
        Eccentric anomaly (for the relativistic clock term).
    """
    k = CONSTANTS[system]
    we = k.omega_e_rad_s
    tk = np.asarray(t_s, dtype=float) - eph.toe_s
    a = eph.sqrt_a_m05**2
    n = np.sqrt(k.gm_m3_s2 / a**3) + eph.delta_n_rad_s
    big_e = eccentric_anomaly(eph.m0_rad + n * tk, eph.e)
    sin_e, cos_e = np.sin(big_e), np.cos(big_e)
    v = np.arctan2(np.sqrt(1.0 - eph.e**2) * sin_e, cos_e - eph.e)
    phi = v + eph.omega_rad
    s2, c2 = np.sin(2.0 * phi), np.cos(2.0 * phi)
    u = phi + eph.cus_rad * s2 + eph.cuc_rad * c2
    r = a * (1.0 - eph.e * cos_e) + eph.crs_m * s2 + eph.crc_m * c2
    inc = eph.i0_rad + eph.idot_rad_s * tk + eph.cis_rad * s2 + eph.cic_rad * c2
    xp, yp = r * np.cos(u), r * np.sin(u)
    geo = is_beidou_geo(eph.sat_id) if system == "C" else np.zeros(len(eph), dtype=bool)
    omega_meo = eph.omega0_rad + (eph.omega_dot_rad_s - we) * tk - we * eph.toe_sow_s
    omega_geo = eph.omega0_rad + eph.omega_dot_rad_s * tk - we * eph.toe_sow_s
    big_om = np.where(geo, omega_geo, omega_meo)
    so, co = np.sin(big_om), np.cos(big_om)
    ci, si = np.cos(inc), np.sin(inc)
    x = xp * co - yp * ci * so
    y = xp * so + yp * ci * co
    z = yp * si
    if np.any(geo):
        # r = Rz(we tk) Rx(-5 deg) r_gk with Rx(p) = [[1,0,0],[0,cp,sp],[0,-sp,cp]],
        # Rz(p) = [[cp,sp,0],[-sp,cp,0],[0,0,1]].
        cp, sp = np.cos(np.radians(-5.0)), np.sin(np.radians(-5.0))
        y1 = cp * y + sp * z
        z1 = -sp * y + cp * z
        ang = we * tk
        ca, sa = np.cos(ang), np.sin(ang)
        x2 = ca * x + sa * y1
        y2 = -sa * x + ca * y1
        x = np.where(geo, x2, x)
        y = np.where(geo, y2, y)
        z = np.where(geo, z1, z)
    return np.stack([x, y, z], axis=-1), big_e


def kepler_clock(
    eph: KeplerNav, t_s: FloatArray, system: str, ecc_anomaly_rad: FloatArray | None = None
) -> FloatArray:
    """Satellite clock offset (s) at ``t_s`` including the relativistic term, without TGD.

    ``dt = af0 + af1 (t - toc) + af2 (t - toc)^2 + F e sqrt(A) sin(E)``.

    Parameters
    ----------
    eph : KeplerNav, N rows
    t_s : ndarray, shape (N,)
        GPST seconds (satellite transmission time).
    system : str
    ecc_anomaly_rad : ndarray, shape (N,), optional
        Eccentric anomaly at ``t_s`` (computed when absent).
    """
    t = np.asarray(t_s, dtype=float)
    if ecc_anomaly_rad is None:
        _, ecc_anomaly_rad = kepler_position(eph, t, system)
    dt = t - eph.toc_s
    poly = eph.af0_s + eph.af1_s_s * dt + eph.af2_s_s2 * dt * dt
    rel = CONSTANTS[system].f_rel_s_m05 * eph.e * eph.sqrt_a_m05 * np.sin(ecc_anomaly_rad)
    return poly + rel


def kepler_states(
    eph: KeplerNav, t_s: FloatArray, system: str, h_s: float = 0.5
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Position, velocity, clock and clock drift from Keplerian elements.

    Velocity and drift are central differences over ``+-h_s`` (truncation error below
    1e-8 m/s for h = 0.5 s; the rounding floor is ~1e-8 m/s).

    Returns
    -------
    pos_ecef_m (N, 3), vel_ecef_m_s (N, 3), clk_s (N,), clk_drift_s_s (N,)
    """
    t = np.asarray(t_s, dtype=float)
    pos, big_e = kepler_position(eph, t, system)
    clk = kepler_clock(eph, t, system, big_e)
    pos_p, e_p = kepler_position(eph, t + h_s, system)
    pos_m, e_m = kepler_position(eph, t - h_s, system)
    vel = (pos_p - pos_m) / (2.0 * h_s)
    drift = (kepler_clock(eph, t + h_s, system, e_p) - kepler_clock(eph, t - h_s, system, e_m)) / (2.0 * h_s)
    return pos, vel, clk, drift


def _glonass_deriv(x: FloatArray, acc: FloatArray) -> FloatArray:
    """Right-hand side of the GLONASS ICD equations of motion (PZ-90, rotating frame).

    For state ``(r, v)`` (N, 6) with ``mu = GM``, ``rho = ae / r``::

        a_x = -mu/r^3 x - 1.5 J2 mu ae^2 / r^5 x (1 - 5 z^2/r^2) + we^2 x + 2 we vy + jx
        a_y = -mu/r^3 y - 1.5 J2 mu ae^2 / r^5 y (1 - 5 z^2/r^2) + we^2 y - 2 we vx + jy
        a_z = -mu/r^3 z - 1.5 J2 mu ae^2 / r^5 z (3 - 5 z^2/r^2) + jz

    Written column by column (a handful of numpy calls on (N,) arrays: this runs four times
    per integration step); every element is the same sequence of IEEE operations as the
    vectorised form ``np.sum(r * r, axis=1)`` … (tests/geometry/test_orbits.py checks bits).
    """
    x0, x1, x2 = x[:, 0], x[:, 1], x[:, 2]
    v0, v1 = x[:, 3], x[:, 4]
    r2 = x0 * x0 + x1 * x1 + x2 * x2
    rn = np.sqrt(r2)
    a_c = _GLO_MU_NEG / (r2 * rn)
    a_j = _GLO_J2_TERM / (r2 * r2 * rn)
    z2r = 5.0 * (x2 * x2) / r2
    f_xy = a_c + a_j * (1.0 - z2r)
    out = np.empty_like(x)
    out[:, :3] = x[:, 3:]
    out[:, 3] = f_xy * x0 + _GLO_WE2 * x0 + _GLO_2WE * v1 + acc[:, 0]
    out[:, 4] = f_xy * x1 + _GLO_WE2 * x1 - _GLO_2WE * v0 + acc[:, 1]
    out[:, 5] = (a_c + a_j * (3.0 - z2r)) * x2 + acc[:, 2]
    return out


def glonass_states(
    eph: GloNav, t_s: FloatArray, max_step_s: float = 60.0
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """GLONASS position, velocity, clock and clock drift by RK4 integration from ``tb``.

    Each query takes ``nᵢ = ceil(|t − tb| / max_step_s)`` steps of ``(t − tb) / nᵢ``
    (vectorised: all queries step together, each stopping after its own ``nᵢ``), so a row's
    result does not depend on the other rows of the call. The luni-solar accelerations are
    held constant (as the ICD prescribes for short intervals).

    Clock: ``dt = -tau_n + gamma_n (t - tb)`` (no separate relativistic term: GLONASS
    broadcast clocks include it).

    Parameters
    ----------
    eph : GloNav, N rows (one per query)
    t_s : ndarray, shape (N,)
        GPST seconds.

    Returns
    -------
    pos_ecef_m (N, 3), vel_ecef_m_s (N, 3), clk_s (N,), clk_drift_s_s (N,)
    """
    t = np.asarray(t_s, dtype=float)
    dt = t - eph.toe_s
    x = np.concatenate([eph.pos_m, eph.vel_m_s], axis=1).astype(float)
    if x.shape[0]:
        finite = np.isfinite(dt)
        dt0 = np.where(finite, dt, 0.0)
        n_i = np.ceil(np.abs(dt0) / max_step_s).astype(np.int64)
        h = (dt0 / np.maximum(n_i, 1))[:, None]
        half_h = 0.5 * h
        sixth_h = h / 6.0
        acc = eph.acc_m_s2
        n_min = int(n_i.min())
        for step in range(int(n_i.max())):
            k1 = _glonass_deriv(x, acc)
            k2 = _glonass_deriv(x + half_h * k1, acc)
            k3 = _glonass_deriv(x + half_h * k2, acc)
            k4 = _glonass_deriv(x + h * k3, acc)
            moved = x + sixth_h * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
            # every row still integrating takes the step (np.where only once some have stopped)
            x = moved if step < n_min else np.where((step < n_i)[:, None], moved, x)
        x[~finite] = np.nan
    clk = eph.minus_tau_n_s + eph.gamma_n * dt
    return x[:, :3], x[:, 3:], clk, eph.gamma_n.astype(float).copy()
