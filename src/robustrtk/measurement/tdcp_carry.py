"""The rover's displacement between consecutive epochs from its time-differenced carrier
phase, as the carry of the DGNSS filter (docs/algorithms.md §45).

Between two epochs of unbroken carrier-phase arcs (:func:`~robustrtk.measurement.tdcp.arc_breaks`
with the loss-of-lock and half-cycle bits breaking), each satellite's phase change plus its
broadcast clock change is the range change plus one receiver clock change per system
(§35). A robust weighted fit of the displacement and those clock changes — the largest
standardised residual (its variance ``V − A N⁻¹ Aᵀ``, each row's variance raised by
:data:`ROW_FLOOR_M`²) beyond :data:`REJECT_K` removed and the fit repeated, at least
:data:`MIN_REDUNDANCY` rows beyond the unknowns kept, no more than a third of the rows
removed — gives a snapshot whose covariance is scaled by its own a-posteriori variance
factor when above one, plus a floor :data:`FLOOR_M` per axis for what the model leaves
out. When any test fails there is no snapshot (the filter keeps its ordinary prediction).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robustrtk.core import FloatArray
from robustrtk.geometry.los import geometric_range
from robustrtk.measurement.chi2 import chi2_ppf
from robustrtk.measurement.tdcp import CONTINUES, ArcTests, arc_breaks

#: Threshold of the standardised TDCP residual (w-test) beyond which a row is removed.
REJECT_K = 4.0
#: σ (m) added in quadrature to each TDCP row: the unmodelled of one satellite over the step
#: (multipath and atmosphere changes), so that millimetre phase σ do not reject good rows.
ROW_FLOOR_M = 0.005
#: Rows beyond the unknowns (3 + one clock change per system) a snapshot needs.
MIN_REDUNDANCY = 2
#: Per-axis σ floor of the displacement (m): the unmodelled (ionosphere, troposphere,
#: orbit and multipath changes over the step).
FLOOR_M = 0.01
#: Longest step (s) a displacement is formed over.
MAX_STEP_S = 5.0
#: Significance of the standing test (zero displacement consistent with the snapshot).
STANDING_ALPHA = 1e-3


@dataclass(frozen=True)
class PhaseEpoch:
    """One rover epoch's carrier-phase inputs.

    Attributes
    ----------
    t_s : float
    tx_ids : tuple of str, length N
    phase_cyc, lli, doppler_hz, cn0_dbhz, wavelength_m : ndarray, shape (N, K)
    tx_pos_m : ndarray, shape (N, 3)
        Satellite positions (ECEF at transmission; NaN where unusable).
    tx_clk_m : ndarray, shape (N,)
        Satellite clock times c (m).
    var_m2 : ndarray, shape (N,)
        Undifferenced phase variance (m²) of the signal column; NaN or inf excludes a row.
    """

    t_s: float
    tx_ids: tuple[str, ...]
    phase_cyc: FloatArray
    lli: np.ndarray
    doppler_hz: FloatArray
    cn0_dbhz: FloatArray
    wavelength_m: FloatArray
    tx_pos_m: FloatArray
    tx_clk_m: FloatArray
    var_m2: FloatArray


@dataclass(frozen=True)
class Displacement:
    """A TDCP displacement snapshot.

    Attributes
    ----------
    d_pos_m : ndarray, shape (3,)
        ECEF displacement from the earlier to the later epoch (m).
    cov_m2 : ndarray, shape (3, 3)
    dt_s : float
    n_rows : int
        Rows of the final fit.
    standing : bool
        A zero displacement is consistent with the snapshot (χ², 3 dof).
    """

    d_pos_m: FloatArray
    cov_m2: FloatArray
    dt_s: float
    n_rows: int
    standing: bool


def robust_displacement(
    delta_m: FloatArray,
    var_m2: FloatArray,
    sat_prev_m: FloatArray,
    sat_now_m: FloatArray,
    rx_prev_m: FloatArray,
    systems: list[str],
) -> tuple[FloatArray, FloatArray, int] | None:
    """Robust fit of ``δ_i = ρ_i(r + Δr, now) − ρ_i(r, prev) + Δc_s(i)``.

    Returns ``(Δr, cov, rows)`` (cov scaled by the variance factor when above one, no floor)
    or None when too few rows remain or too many are removed.
    """
    sys_names = sorted(set(systems))
    S = np.array([[s == name for name in sys_names] for s in systems], float).reshape(len(systems), -1)
    n = 3 + len(sys_names)
    m0 = len(delta_m)
    keep = np.ones(m0, bool)
    rp = np.asarray(rx_prev_m, float)
    rng_prev, _ = geometric_range(sat_prev_m, rp)
    v = np.asarray(var_m2, float) + ROW_FLOOR_M**2
    while True:
        m = int(keep.sum())
        cols = S[keep].any(axis=0)
        if m < n + MIN_REDUNDANCY or not cols.all() or 3 * (m0 - m) > m0:
            return None
        w = 1.0 / v[keep]
        x = np.zeros(n)
        for _ in range(4):
            rng_now, u = geometric_range(sat_now_m[keep], rp + x[:3])
            A = np.column_stack([-u, S[keep]])
            r = delta_m[keep] - (rng_now - rng_prev[keep] + S[keep] @ x[3:])
            N = A.T @ (A * w[:, None])
            try:
                Ninv = np.linalg.inv(N)
            except np.linalg.LinAlgError:
                return None
            x = x + Ninv @ (A.T @ (w * r))
        rng_now, u = geometric_range(sat_now_m[keep], rp + x[:3])
        r = delta_m[keep] - (rng_now - rng_prev[keep] + S[keep] @ x[3:])
        # the residuals' own variances (V − A N⁻¹ Aᵀ): the w-test of each row
        q = v[keep] - np.einsum("ij,jk,ik->i", A, Ninv, A)
        z = np.abs(r) / np.sqrt(np.maximum(q, 1e-12 * v[keep]))
        worst = int(np.argmax(z))
        if z[worst] > REJECT_K:
            keep[np.flatnonzero(keep)[worst]] = False
            continue
        return x[:3], Ninv[:3, :3] * max(1.0, float(r @ (w * r)) / (m - n)), m


def displacement(
    prev: PhaseEpoch, now: PhaseEpoch, rx_prev_m: FloatArray, signal: int
) -> Displacement | None:
    """The rover's TDCP displacement from ``prev`` to ``now`` (signal column ``signal``),
    or None (step not in (0, :data:`MAX_STEP_S`], too few continuing arcs, a doubtful fit)."""
    dt = now.t_s - prev.t_s
    if not 0.0 < dt <= MAX_STEP_S:
        return None
    where = {tx: i for i, tx in enumerate(prev.tx_ids)}
    cur = np.array([i for i, tx in enumerate(now.tx_ids) if tx in where], int)
    if cur.size < 4:
        return None
    old = np.array([where[now.tx_ids[i]] for i in cur], int)

    def pair(a: FloatArray, b: FloatArray) -> FloatArray:
        return np.stack([np.asarray(a, float)[old], np.asarray(b, float)[cur]])

    tests = ArcTests(max_gap_s=MAX_STEP_S, lli_break=True, half_cycle_break=True)
    brk = arc_breaks(
        np.array([prev.t_s, now.t_s]), pair(prev.phase_cyc, now.phase_cyc), pair(prev.lli, now.lli),
        pair(prev.doppler_hz, now.doppler_hz), pair(prev.cn0_dbhz, now.cn0_dbhz),
        np.asarray(now.wavelength_m, float)[cur], tests,
    )  # fmt: skip
    lam = np.asarray(now.wavelength_m, float)[cur, signal]
    with np.errstate(invalid="ignore"):
        d = lam * (now.phase_cyc[cur, signal] - prev.phase_cyc[old, signal])
        d = d + (now.tx_clk_m[cur] - prev.tx_clk_m[old])
        var = now.var_m2[cur] + prev.var_m2[old]
    sp, sn = prev.tx_pos_m[old], now.tx_pos_m[cur]
    ok = (brk[1, :, signal] == CONTINUES) & np.isfinite(d) & np.isfinite(var) & (var > 0)
    ok &= np.isfinite(sp).all(axis=1) & np.isfinite(sn).all(axis=1)
    if not ok.any():
        return None
    systems = [now.tx_ids[i][0] for i in cur[ok]]
    fit = robust_displacement(d[ok], var[ok], sp[ok], sn[ok], np.asarray(rx_prev_m, float), systems)
    if fit is None:
        return None
    d_pos, cov, m = fit
    cov = cov + np.eye(3) * FLOOR_M**2
    try:
        t = float(d_pos @ np.linalg.solve(cov, d_pos))
    except np.linalg.LinAlgError:
        return None
    return Displacement(d_pos, cov, dt, m, t <= chi2_ppf(1.0 - STANDING_ALPHA, 3))


class TdcpTracker:
    """Keeps the previous epoch's phase inputs; :meth:`step` gives the displacement to the
    new one (or None) and remembers the new one."""

    def __init__(self) -> None:
        self.last: PhaseEpoch | None = None

    def step(self, epoch: PhaseEpoch, rx_prev_m: FloatArray, signal: int) -> Displacement | None:
        prev, self.last = self.last, epoch
        if prev is None or not np.isfinite(rx_prev_m).all():
            return None
        return displacement(prev, epoch, rx_prev_m, signal)


def tdcp_prediction(
    x_prev: FloatArray,
    P_prev: FloatArray,
    pos: slice,
    vel: slice | None,
    disp: Displacement,
    acc_m_s2: float,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The previous posterior carried by a TDCP displacement (docs/algorithms.md §45).

    ``p = p⁻ + Δr``, ``v = Δr / dt`` (the mean velocity of the step; its difference from the
    velocity at the epoch, ``a dt/2``, as a variance ``(acc_m_s2 dt/2)²``). As a linear map
    ``x = T x⁻ + G Δr`` with ``T`` identity but ``T[vel, vel] = 0``, ``G = [I; I/dt]``:
    ``P = T P⁻ Tᵀ + G C Gᵀ``; other states held.

    Returns
    -------
    x : ndarray, shape (n,)
    P : ndarray, shape (n, n)
    T : ndarray, shape (n, n)
        The transition (for a smoother).
    """
    n = int(np.shape(x_prev)[0])
    T = np.eye(n)
    G = np.zeros((n, 3))
    G[pos] = np.eye(3)
    if vel is not None:
        T[vel, vel] = 0.0
        G[vel] = np.eye(3) / disp.dt_s
    x = T @ np.asarray(x_prev, float) + G @ disp.d_pos_m
    P = T @ np.asarray(P_prev, float) @ T.T + G @ disp.cov_m2 @ G.T
    if vel is not None:
        P[vel, vel] += np.eye(3) * (0.5 * acc_m_s2 * disp.dt_s) ** 2
    return x, 0.5 * (P + P.T), T


__all__ = [
    "FLOOR_M", "MAX_STEP_S", "MIN_REDUNDANCY", "REJECT_K", "ROW_FLOOR_M", "STANDING_ALPHA", "Displacement",
    "PhaseEpoch", "TdcpTracker", "displacement", "robust_displacement", "tdcp_prediction",
]  # fmt: skip
