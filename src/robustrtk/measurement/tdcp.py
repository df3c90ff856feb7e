"""Time-differenced carrier phase (TDCP) of one receiver: arcs, deltas and the displacement.

Between two consecutive epochs ``k − 1`` and ``k`` of one unbroken carrier-phase arc of
satellite ``i`` on band ``b`` (wavelength ``λ_b``), the carrier phase in metres
``Φ = λ_b φ`` gives (docs/algorithms.md §35)::

    ΔΦ_i + Δ(c dt_i) − ΔT_i + ΔI_i,b = ρ_i,k(r_k) − ρ_i,k−1(r_k−1) + Δc_s + ε

where ``Δ(c dt_i)`` is the change of the satellite clock (broadcast ephemeris), ``ΔT`` and
``ΔI`` the changes of the modelled tropospheric and ionospheric delays (centimetres over a
second at most), ``ρ`` the range with the Earth-rotation term to the satellite's position at
each epoch (its motion comes from the ephemeris, not from the data) and ``Δc_s`` the change
of the receiver's carrier-phase clock of system ``s``. The integer ambiguity, the phase
hardware delays and the phone's arbitrary ADR origin cancel; so does the code multipath.
``Δc_s`` is kept as an unknown per epoch pair and system: eliminating it is exactly the
between-satellite single difference, but every satellite keeps its own residual, so a robust
re-weighting can down-weight one satellite without the reference satellite's errors leaking
into all the others.

An arc breaks (:func:`arc_breaks`) where the phone says so — phase absent at either epoch, a
gap longer than ``max_gap_s`` (duty cycling: the ADR is not tracked through it), the
loss-of-lock bit (when ``lli_break``), the half-cycle bit cleared (the receiver resolved the
half-cycle ambiguity and may have moved the phase by half a cycle) — or where a test says
so: the geometry-free change ``Δ(Φ_1 − Φ_2)`` beyond ``gf_max_m`` (a slip on either band;
the ionosphere changes by millimetres per second), or the phase change against the
Doppler-integrated range change beyond ``doppler_k`` standard deviations after the common
receiver-clock term (the per-epoch median over the satellites) is removed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robustrtk.core import FloatArray
from robustrtk.geometry.los import geometric_range

#: Reason codes of :func:`arc_breaks` (index into :data:`BREAK_NAMES`).
CONTINUES, ABSENT, GAP, LLI, HALF_CYCLE, GEOMETRY_FREE, DOPPLER = range(7)
BREAK_NAMES: tuple[str, ...] = ("", "absent", "gap", "lli", "half-cycle", "gf", "doppler")


@dataclass(frozen=True)
class ArcTests:
    """Settings of the arc-break tests.

    Attributes
    ----------
    max_gap_s : float
        Longest epoch spacing an arc is carried across (s).
    lli_break : bool
        The loss-of-lock bit (LLI bit 0) breaks the arc.
    gf_max_m : float
        Largest geometry-free change between two epochs (m); a quarter of the L1 wavelength
        by default: one cycle on either band moves it by 19–25 cm, the ionosphere by
        millimetres per second.
    doppler_k : float
        Threshold of the Doppler test in standard deviations.
    doppler_sigma_m_s : float
        Range-rate σ at ``cn0_ref_dbhz`` (m/s); the law ``σ 10^((cn0_ref − cn0)/20)``.
    cn0_ref_dbhz : float
    phase_sigma_m : float
        Carrier-phase σ (m) added to the Doppler test's variance.
    """

    max_gap_s: float = 1.5
    lli_break: bool = False
    gf_max_m: float = 0.048
    doppler_k: float = 5.0
    doppler_sigma_m_s: float = 0.05
    cn0_ref_dbhz: float = 45.0
    phase_sigma_m: float = 0.05
    half_cycle_break: bool = False  # the half-cycle bit cleared between the epochs breaks


def arc_breaks(
    t_s: FloatArray,
    phase_cyc: FloatArray,
    lli: FloatArray,
    doppler_hz: FloatArray,
    cn0_dbhz: FloatArray,
    wavelength_m: FloatArray,
    tests: ArcTests | None = None,
) -> np.ndarray:
    """Why the phase of epoch ``k`` does not continue the arc of epoch ``k − 1``.

    Parameters
    ----------
    t_s : ndarray, shape (T,)
    phase_cyc, lli, doppler_hz, cn0_dbhz : ndarray, shape (T, N, B)
        Carrier phase (cycles; NaN absent), loss-of-lock indicator (RINEX bits: 1 lost
        lock, 2 half-cycle ambiguity), Doppler (Hz), C/N0 (dB-Hz) of ``N`` satellites on ``B``
        bands.
    wavelength_m : ndarray, shape (N, B)
    tests : ArcTests, optional

    Returns
    -------
    ndarray of int8, shape (T, N, B)
        :data:`CONTINUES` (0) where the delta ``k − 1 → k`` is usable, else the first reason
        found (:data:`BREAK_NAMES`); epoch 0 is :data:`ABSENT`.
    """
    ts = tests or ArcTests()
    T, N, B = phase_cyc.shape
    out = np.full((T, N, B), ABSENT, np.int8)
    if T < 2:
        return out
    lam = np.asarray(wavelength_m, float)[None, :, :]
    have = np.isfinite(phase_cyc) & np.isfinite(lam)
    both = have[1:] & have[:-1]
    reason = np.where(both, CONTINUES, ABSENT).astype(np.int8)
    dt = np.diff(np.asarray(t_s, float))[:, None, None]
    reason[(reason == 0) & (dt > ts.max_gap_s)] = GAP
    bits = np.nan_to_num(lli, nan=0.0).astype(np.int64)
    if ts.lli_break:
        reason[(reason == 0) & ((bits[1:] & 1) != 0)] = LLI
    half = (bits & 2) != 0
    if ts.half_cycle_break:
        reason[(reason == 0) & half[:-1] & ~half[1:]] = HALF_CYCLE
    with np.errstate(invalid="ignore"):
        dphi_m = lam * (phase_cyc[1:] - phase_cyc[:-1])
        if B >= 2:
            gf = dphi_m[:, :, 0] - dphi_m[:, :, 1]
            bad = np.abs(gf) > ts.gf_max_m  # NaN compares False
            for b in range(2):
                reason[:, :, b][(reason[:, :, b] == 0) & bad] = GEOMETRY_FREE
        dop = -lam * doppler_hz  # range rate (m/s)
        pred = 0.5 * (dop[1:] + dop[:-1]) * dt
        miss = dphi_m - pred
        sig = ts.doppler_sigma_m_s * 10.0 ** (
            (ts.cn0_ref_dbhz - np.nan_to_num(cn0_dbhz, nan=ts.cn0_ref_dbhz)) / 20.0
        )
        var = 0.25 * (sig[1:] ** 2 + sig[:-1] ** 2) * dt**2 + 2.0 * ts.phase_sigma_m**2
        for b in range(B):
            m = miss[:, :, b]
            ok = (reason[:, :, b] == 0) & np.isfinite(m)
            mm = np.where(ok, m, np.nan)
            cnt = ok.sum(axis=1)
            med = np.zeros(T - 1)
            rows = cnt > 0
            med[rows] = np.nanmedian(mm[rows], axis=1)
            z = np.abs(m - med[:, None]) / np.sqrt(var[:, :, b])
            reason[:, :, b][ok & (z > ts.doppler_k)] = DOPPLER
    out[1:] = reason
    return out


def phase_deltas(
    phase_cyc: FloatArray, wavelength_m: FloatArray, corr_m: FloatArray, breaks: np.ndarray
) -> FloatArray:
    """``λ(φ_k − φ_k−1) + (corr_k − corr_k−1)`` where the arc continues, NaN elsewhere.

    Parameters
    ----------
    phase_cyc : ndarray, shape (T, N, B)
    wavelength_m : ndarray, shape (N, B)
    corr_m : ndarray, shape (T, N) or (T, N, B)
        Model terms added to the phase in metres: ``c dt_i − T_i + I_i,b`` (satellite clock,
        minus the tropospheric delay, plus the ionospheric advance).
    breaks : ndarray, shape (T, N, B)
        :func:`arc_breaks`.

    Returns
    -------
    ndarray, shape (T, N, B); row 0 is NaN.
    """
    c = np.asarray(corr_m, float)
    if c.ndim == 2:
        c = c[:, :, None]
    lam = np.asarray(wavelength_m, float)[None]
    out = np.full(phase_cyc.shape, np.nan)
    d = lam * (phase_cyc[1:] - phase_cyc[:-1]) + (c[1:] - c[:-1])
    out[1:] = np.where(breaks[1:] == CONTINUES, d, np.nan)
    return out


def solve_displacement(
    delta_m: FloatArray,
    var_m2: FloatArray,
    sat_prev_m: FloatArray,
    sat_now_m: FloatArray,
    rx_prev_m: FloatArray,
    rx_now_m: FloatArray | None = None,
    iterations: int = 4,
) -> tuple[FloatArray, float, FloatArray]:
    """Receiver displacement and phase-clock change from one epoch pair's TDCP.

    Weighted Gauss–Newton on ``δ_i = ρ_i(r_prev + Δr, now) − ρ_i(r_prev, prev) + Δc`` with
    ``r_prev`` held (an SPP position: an error ``e`` in it biases ``Δr`` by about
    ``|e| |Δu|``, micro-radians of line-of-sight change times metres).

    Parameters
    ----------
    delta_m : ndarray, shape (m,)
        :func:`phase_deltas` of the pair (m ≥ 4).
    var_m2 : ndarray, shape (m,)
    sat_prev_m, sat_now_m : ndarray, shape (m, 3)
        Satellite positions (ECEF at transmission) of the two epochs.
    rx_prev_m : ndarray, shape (3,)
    rx_now_m : ndarray, shape (3,), optional
        Starting point of the iteration (``rx_prev_m`` when None).
    iterations : int

    Returns
    -------
    d_pos_m : ndarray, shape (3,)
    d_clk_m : float
    cov : ndarray, shape (4, 4)
        Covariance of ``(Δr, Δc)`` under ``var_m2``.
    """
    d = np.asarray(delta_m, float)
    w = 1.0 / np.asarray(var_m2, float)
    rp = np.asarray(rx_prev_m, float)
    rng_prev, _ = geometric_range(sat_prev_m, rp)
    x = np.zeros(4)
    if rx_now_m is not None:
        x[:3] = np.asarray(rx_now_m, float) - rp
    N = np.eye(4)
    for _ in range(max(1, iterations)):
        rng_now, u = geometric_range(sat_now_m, rp + x[:3])
        r = d - (rng_now - rng_prev + x[3])
        A = np.column_stack([-u, np.ones(len(d))])
        N = A.T @ (A * w[:, None])
        x = x + np.linalg.solve(N, A.T @ (w * r))
    return x[:3], float(x[3]), np.linalg.inv(N)


__all__ = [
    "ABSENT",
    "BREAK_NAMES",
    "CONTINUES",
    "DOPPLER",
    "GAP",
    "GEOMETRY_FREE",
    "HALF_CYCLE",
    "LLI",
    "ArcTests",
    "arc_breaks",
    "phase_deltas",
    "solve_displacement",
]
