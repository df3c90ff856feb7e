"""A GNSS receiver in software: the observations a geodetic receiver would make along a known
track, computed from the broadcast ephemerides and the broadcast models — what a hardware
signal simulator produces when its atmosphere follows the broadcast message.

For satellite ``s`` on band ``b`` (wavelength ``λ_b``, ``γ_b = (f_1 / f_b)²``) at receiver
time ``t`` (docs/algorithms.md §47)::

    P_b = ρ + c δt_r − c (δt^s − T_GD,b) + T + γ_b I + ε_P
    Φ_b = ρ + c δt_r − c (δt^s − T_GD,b) + T − γ_b I + λ_b N_b + ε_Φ
    D_b = −(u · (v^s − v_r) + c δṫ_r − c δṫ^s) / λ_b + ε_D

``ρ`` the range to the satellite at transmission with the Earth-rotation term, ``δt^s`` the
broadcast clock (relativistic term included), ``T_GD,b`` the broadcast group delay of the
band, ``T`` Saastamoinen's standard atmosphere, ``I`` the broadcast (Klobuchar) delay
times ``iono_scale``, ``N_b`` an arbitrary integer per satellite and band, ``ε`` white noise
(the code optionally with a Gauss–Markov multipath term). With ``iono_scale = 1`` the
solver's own models explain the observations exactly: what is left is what the noise — or a
degradation such as :func:`robustrtk.sim.phone.phone_profile` — adds. The receiver clock
drifts linearly; satellites below the elevation mask (and, in a street canyon, below the
walls across the road) are not observed.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from robustrtk.core import CLIGHT, FloatArray, ObsBatch
from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.geometry.frames import ecef2enu_rotation, ecef2geodetic
from robustrtk.geometry.los import azimuth_elevation, geometric_range
from robustrtk.measurement.corrections import iono_klobuchar, tropo_saastamoinen

__all__ = ["grid_track", "simulate_drive"]


def grid_track(
    t_s: FloatArray,
    origin_ecef_m: FloatArray,
    seed: int = 0,
    *,
    speed_m_s: tuple[float, float] = (8.0, 14.0),
    leg_m: tuple[float, float] = (150.0, 400.0),
    stop_s: int = 30,
    accel_m_s2: float = 2.0,
) -> FloatArray:
    """A car on a street grid: legs of ``U(leg_m)`` metres at up to ``U(speed_m_s)``,
    accelerating and braking at ``accel_m_s2``, a right-angle turn and a stop of
    ``0..stop_s`` epochs after each leg; corners rounded by a 5-epoch moving average.

    Parameters
    ----------
    t_s : ndarray, shape (T,)
        Epoch times at 1 s spacing (s).
    origin_ecef_m : ndarray, shape (3,)
        Start of the track (ECEF, m); the track is level in the local east-north plane.
    seed : int

    Returns
    -------
    ndarray, shape (T, 3): ECEF positions (m).
    """
    rng = np.random.default_rng(seed)
    T = len(t_s)
    en = np.zeros((T, 2))
    p = np.zeros(2)
    heading, v, k = 0.0, 0.0, 0
    while k < T:
        leg = rng.uniform(*leg_m)
        vmax = rng.uniform(*speed_m_s)
        d = 0.0
        while d < leg and k < T:
            v_to = min(vmax, math.sqrt(2.0 * accel_m_s2 * max(leg - d, 0.0)) + 1.0)
            v = min(v_to, v + accel_m_s2) if v < v_to else max(v_to, v - accel_m_s2)
            p = p + v * np.array([math.cos(heading), math.sin(heading)])
            d += v
            en[k] = p
            k += 1
        for _ in range(int(rng.integers(0, stop_s + 1))):
            if k >= T:
                break
            en[k] = p
            k += 1
        v = 0.0
        heading += float(rng.choice([-1.0, 1.0])) * math.pi / 2
    ker = np.ones(5) / 5.0
    for c in range(2):
        en[:, c] = np.convolve(np.pad(en[:, c], 2, mode="edge"), ker, mode="valid")
    o = np.asarray(origin_ecef_m, float)
    lat, lon, _ = (float(x) for x in np.ravel(ecef2geodetic(o)))
    rot = ecef2enu_rotation(lat, lon)
    return np.asarray(o + np.column_stack([en, np.zeros(T)]) @ rot, float)


def _gauss_markov_step(prev: FloatArray, rng: np.random.Generator, a: float, sigma: float) -> FloatArray:
    """One step of a first-order Gauss–Markov process of stationary σ ``sigma``."""
    return np.asarray(a * prev + math.sqrt(1.0 - a * a) * sigma * rng.standard_normal(prev.shape), float)


def simulate_drive(
    layout: ObsBatch,
    eph: EphemerisSource,
    t_s: FloatArray,
    pos_ecef_m: FloatArray,
    *,
    seed: int = 0,
    code_sigma_m: float = 0.1,
    multipath_sigma_m: float = 0.0,
    multipath_tau_s: float = 60.0,
    phase_sigma_m: float = 0.001,
    doppler_sigma_m_s: float = 0.01,
    elev_mask_deg: float = 10.0,
    canyon_deg: float = 0.0,
    iono_scale: float = 1.0,
    clock_m: float = 3.0e4,
    clock_drift_m_s: float = 50.0,
) -> ObsBatch:
    """Observations along ``pos_ecef_m`` (module docstring).

    Parameters
    ----------
    layout : ObsBatch
        A receiver's file: its satellites, signals and wavelengths are simulated (a
        satellite's signal only where the file has that signal's code for it).
    eph : EphemerisSource
    t_s : ndarray, shape (T,)
        Receiver times (GPST s).
    pos_ecef_m : ndarray, shape (T, 3)
        The true track (ECEF, m).
    seed : int
    code_sigma_m, phase_sigma_m, doppler_sigma_m_s : float
        White noise σ of code (m), carrier phase (m) and range rate (m/s).
    multipath_sigma_m, multipath_tau_s : float
        Stationary σ (m) and correlation time (s) of a Gauss–Markov code error per
        satellite and band.
    elev_mask_deg : float
        Satellites below are not observed.
    canyon_deg : float
        Street canyon: a satellite is also hidden below ``elev_mask_deg + canyon_deg ·
        |sin(az − heading)|`` (walls along the road; heading of the track's velocity, none
        while standing).
    iono_scale : float
        The true ionospheric delay as a multiple of the broadcast model's.
    clock_m, clock_drift_m_s : float
        Receiver clock at the first epoch (m) and its drift (m/s).

    Returns
    -------
    ObsBatch with the layout's satellites and signals, ``lli`` 0, C/N0
    ``38 + 12 sin(el)`` dB-Hz, ``approx_pos_m`` the first position.
    """
    rng = np.random.default_rng(seed)
    t = np.asarray(t_s, float)
    pos = np.asarray(pos_ecef_m, float)
    T, ids = len(t), list(layout.tx_ids)
    N, S = len(ids), len(layout.signals)
    lam = np.asarray(layout.wavelength_m, float)
    observed = np.isfinite(layout.code_m).any(axis=0) & np.isfinite(lam)  # (N, S)
    lat, lon, h = (float(x) for x in np.ravel(ecef2geodetic(pos[0])))
    rot = ecef2enu_rotation(lat, lon)
    vel = np.gradient(pos, t, axis=0) if T > 1 else np.zeros_like(pos)
    nav = eph.nav
    code, phase, dop, cn0 = (np.full((T, N, S), np.nan) for _ in range(4))
    amb = rng.integers(-(10**6), 10**6, size=(N, S)).astype(float)
    mp: FloatArray = np.zeros((N, S))
    a_mp = math.exp(-1.0 / multipath_tau_s) if multipath_tau_s > 0 else 0.0
    bands = sorted({s[0] for s in layout.signals})
    for k in range(T):
        tk = float(t[k])
        clk_k = clock_m + clock_drift_m_s * (tk - t[0])
        sp, sclk = eph.positions(tk, ids)  # nominal travel time first, then the range's
        ok = np.all(np.isfinite(sp), axis=1) & np.isfinite(sclk)
        rng0, _ = geometric_range(np.where(ok[:, None], sp, 0.0), pos[k])
        travel = np.where(ok, rng0 + clk_k - sclk, np.nan)
        sp, sclk = eph.positions(tk, ids, travel)
        sp1, sclk1 = eph.positions(tk + 0.5, ids, travel)
        sp0, sclk0 = eph.positions(tk - 0.5, ids, travel)
        ok = np.all(np.isfinite(sp), axis=1) & np.isfinite(sclk)
        spz = np.where(ok[:, None], sp, 0.0)
        r, u = geometric_range(spz, pos[k])
        az, el = azimuth_elevation(spz, pos[k])
        floor = np.full(N, math.radians(elev_mask_deg))
        v_en = rot @ vel[k]
        if canyon_deg > 0 and math.hypot(v_en[0], v_en[1]) > 0.5:
            heading = math.atan2(v_en[0], v_en[1])
            floor = floor + math.radians(canyon_deg) * np.abs(np.sin(az - heading))
        vis = ok & (el > floor)
        trop = tropo_saastamoinen(lat, h, el)
        tgd = {b: np.nan_to_num(eph.group_delay_s(np.full(N, tk), ids, b)) for b in {"1", *bands}}
        rate = np.sum(u * (np.nan_to_num(sp1 - sp0) - vel[k]), axis=1) + clock_drift_m_s - (sclk1 - sclk0)
        if multipath_sigma_m > 0:
            a_k = a_mp if k else 0.0  # the first epoch draws from the stationary law
            mp = _gauss_markov_step(mp, rng, a_k, multipath_sigma_m)
        for s, name in enumerate(layout.signals):
            q = vis & observed[:, s]
            if not q.any():
                continue
            f = CLIGHT / lam[q, s]
            alpha, beta = nav.ion_gps_alpha, nav.ion_gps_beta
            if alpha is None or beta is None:  # no broadcast model: no ionosphere simulated
                ion: FloatArray = np.zeros(int(q.sum()))
            else:
                ion = iono_scale * iono_klobuchar(tk, lat, lon, az[q], el[q], alpha, beta, f)
            sat_b = sclk[q] + CLIGHT * (tgd["1"][q] - tgd[name[0]][q])
            geo = r[q] + clk_k - sat_b + trop[q]
            n_q = int(q.sum())
            code[k, q, s] = geo + ion + code_sigma_m * rng.standard_normal(n_q) + mp[q, s]
            phase[k, q, s] = (geo - ion + phase_sigma_m * rng.standard_normal(n_q)) / lam[q, s] + amb[q, s]
            dop[k, q, s] = -(rate[q] + doppler_sigma_m_s * rng.standard_normal(n_q)) / lam[q, s]
            cn0[k, q, s] = 38.0 + 12.0 * np.sin(el[q])
    return replace(
        layout,
        t_s=t,
        code_m=code,
        phase_cyc=phase,
        doppler_hz=dop,
        cn0_dbhz=cn0,
        lli=np.zeros((T, N, S), np.int8),
        approx_pos_m=pos[0].copy(),
        code_sigma_m=None,
        phase_sigma_cyc=None,
        meta={**layout.meta, "simulated": "robustrtk.sim.drive"},
    )
