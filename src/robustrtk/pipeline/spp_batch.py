"""Least-squares SPP over a block of epochs at once: the arithmetic of
:func:`robustrtk.measurement.undifferenced.lsq_fde` (Gauss–Newton with one receiver clock
per system, chi-square FDE) on stacked arrays, epochs × satellites.

Every epoch of a block is solved together: satellite states of all its rows in one call
(:meth:`robustrtk.geometry.ephemeris.EphemerisSource.code_states`), then each Gauss–Newton
iteration builds the normal matrices of all epochs still iterating (``einsum`` over the
satellites) and solves them as one stack. An epoch's rows outside its active set carry zero
weight; the clock column of a system without an active row is kept out of the solution by
a unit-free diagonal entry (a diagonal element of the epoch's own normal matrix, which lies
inside its spectrum, so the condition number is that of the epoch's own matrix), with a zero
right-hand side: its increment is exactly zero. Per epoch the iteration, the elevation mask,
the exclusion order and the stopping rules are those of ``lsq_solve``/``lsq_fde``; the numbers
agree with the per-epoch path to the rounding of the sums (about 1e-9 m).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robustrtk.core import BoolArray, FloatArray, IntArray
from robustrtk.geometry.frames import ecef2enu_rotation, ecef2geodetic
from robustrtk.geometry.los import geometric_range
from robustrtk.io.rinex_nav import NavData
from robustrtk.measurement.chi2 import chi2_ppf
from robustrtk.measurement.corrections import iono_klobuchar, tropo_saastamoinen
from robustrtk.measurement.undifferenced import IONO_MODELS, TROPO_MODELS, LsqSettings, elevation_cn0_variance


@dataclass
class BlockGeometry:
    """Code rows of a block of E epochs over the S satellites of a one-signal batch.

    Attributes
    ----------
    t_s : ndarray, shape (E,)
        Receiver time tags (GPST s).
    code_m, cn0_dbhz, freq_hz, sat_clk_m : ndarray, shape (E, S)
        Pseudorange, C/N0, carrier frequency and ``c (dt - T_GD)`` (m); NaN code where absent.
    sat_pos_m : ndarray, shape (E, S, 3)
        Satellite ECEF at the transmission time.
    ok : ndarray of bool, shape (E, S)
        Rows with code and a valid ephemeris (``EpochGeometry.ok``).
    sys_col : ndarray of int, shape (S,)
        Each satellite's system as an index into ``systems``.
    systems : tuple of str
        The block's system letters, sorted (the order of the clock unknowns).
    """

    t_s: FloatArray
    code_m: FloatArray
    cn0_dbhz: FloatArray
    freq_hz: FloatArray
    sat_pos_m: FloatArray
    sat_clk_m: FloatArray
    ok: BoolArray
    sys_col: IntArray
    systems: tuple[str, ...]

    def take(self, idx: IntArray) -> BlockGeometry:
        """Epochs ``idx`` of the block."""
        return BlockGeometry(
            self.t_s[idx],
            self.code_m[idx],
            self.cn0_dbhz[idx],
            self.freq_hz[idx],
            self.sat_pos_m[idx],
            self.sat_clk_m[idx],
            self.ok[idx],
            self.sys_col,
            self.systems,
        )


@dataclass
class BlockLsq:
    """Least-squares solutions of E epochs (rows of an epoch that has none are NaN).

    Attributes
    ----------
    solved : ndarray of bool, shape (E,)
        A solution exists (``lsq_solve`` did not return None).
    pos : ndarray, shape (E, 3)
    clk : ndarray, shape (E, n_sys)
        Receiver clock per system (m); ``clk_set`` marks the systems ever solved.
    clk_set : ndarray of bool, shape (E, n_sys)
    cov : ndarray, shape (E, 3 + n_sys, 3 + n_sys)
        Inverse normal matrix (padded rows/columns of absent systems hold the inverse of
        their diagonal entry and are never read).
    v, var : ndarray, shape (E, S)
        Post-fit residuals and variances (meaningful on ``act`` rows).
    H : ndarray, shape (E, S, 3 + n_sys)
    act : ndarray of bool, shape (E, S)
        Rows used (``LsqSolution.rows``).
    n_unknowns : ndarray of int, shape (E,)
    """

    solved: BoolArray
    pos: FloatArray
    clk: FloatArray
    clk_set: BoolArray
    cov: FloatArray
    v: FloatArray
    var: FloatArray
    H: FloatArray
    act: BoolArray
    n_unknowns: IntArray

    @classmethod
    def empty(cls, n_ep: int, n_sat: int, n_sys: int) -> BlockLsq:
        """E unsolved epochs."""
        k = 3 + n_sys
        return cls(
            np.zeros(n_ep, bool),
            np.full((n_ep, 3), np.nan),
            np.zeros((n_ep, n_sys)),
            np.zeros((n_ep, n_sys), bool),
            np.full((n_ep, k, k), np.nan),
            np.full((n_ep, n_sat), np.nan),
            np.full((n_ep, n_sat), np.nan),
            np.zeros((n_ep, n_sat, k)),
            np.zeros((n_ep, n_sat), bool),
            np.zeros(n_ep, np.int64),
        )

    def put(self, idx: IntArray, other: BlockLsq) -> None:
        """Epochs ``idx`` replaced by ``other``'s (same order)."""
        for name in ("solved", "pos", "clk", "clk_set", "cov", "v", "var", "H", "act", "n_unknowns"):
            getattr(self, name)[idx] = getattr(other, name)

    def take(self, idx: IntArray) -> BlockLsq:
        """Epochs ``idx``."""
        return BlockLsq(
            *(
                getattr(self, n)[idx]
                for n in ("solved", "pos", "clk", "clk_set", "cov", "v", "var", "H", "act", "n_unknowns")
            )
        )


def block_atmosphere(
    t_s: FloatArray,
    sat_pos_m: FloatArray,
    rx_m: FloatArray,
    nav: NavData,
    tropo: str,
    iono: str,
    freq_hz: FloatArray,
    rows: BoolArray | None = None,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """:func:`robustrtk.measurement.undifferenced.atmosphere` for E receivers at once.

    Parameters
    ----------
    t_s : ndarray, shape (E,)
    sat_pos_m : ndarray, shape (E, S, 3)
    rx_m : ndarray, shape (E, 3)
    freq_hz : ndarray, shape (E, S)
    rows : ndarray of bool, shape (E, S), optional
        The rows to compute (the others are left at ``pi/2``, 0, 0); all by default.

    Returns
    -------
    el_rad, az_rad, code_delay_m : ndarray, shape (E, S)
        Look angles and ``I + T``; ``pi/2``, 0 and 0 for a receiver away from the Earth's
        surface (outside 6200–6600 km from the centre).
    """
    if tropo not in TROPO_MODELS:
        raise ValueError(f"tropo: expected one of {', '.join(TROPO_MODELS)}, got {tropo!r}")
    if iono not in IONO_MODELS:
        raise ValueError(f"iono: expected one of {', '.join(IONO_MODELS)}, got {iono!r}")
    n_ep, n_sat = sat_pos_m.shape[:2]
    el = np.full((n_ep, n_sat), np.pi / 2)
    az = np.zeros((n_ep, n_sat))
    delay = np.zeros((n_ep, n_sat))
    r = np.sqrt(np.sum(rx_m * rx_m, axis=1))
    near = (r > 6.2e6) & (r < 6.6e6)
    if not near.any():
        return el, az, delay
    lat, lon, h = ecef2geodetic(np.where(near[:, None], rx_m, 6.4e6))
    sel = near[:, None] if rows is None else rows & near[:, None]
    ei, si = np.nonzero(np.broadcast_to(sel, (n_ep, n_sat)))
    rot = ecef2enu_rotation(lat, lon)[ei]  # (n, 3, 3)
    d = sat_pos_m[ei, si] - rx_m[ei]
    enu = np.matmul(rot, d[:, :, None])[:, :, 0]
    e_n = np.arcsin(np.clip(enu[:, 2] / np.sqrt(np.sum(enu * enu, axis=-1)), -1.0, 1.0))
    a_n = np.mod(np.arctan2(enu[:, 0], enu[:, 1]), 2 * np.pi)
    dl = np.zeros_like(e_n)
    if tropo == "saastamoinen":
        inside = (h[ei] > -1000.0) & (h[ei] < 1.0e4)
        if inside.any():
            dl[inside] += tropo_saastamoinen(lat[ei][inside], h[ei][inside], e_n[inside])
    if iono == "klobuchar" and nav.ion_gps_alpha is not None and nav.ion_gps_beta is not None:
        dl = dl + iono_klobuchar(
            t_s[ei],
            lat[ei],  # type: ignore[arg-type]  # the model is elementwise in the position too
            lon[ei],  # type: ignore[arg-type]
            a_n,
            e_n,
            nav.ion_gps_alpha,
            nav.ion_gps_beta,
            freq_hz[ei, si],
        )
    el[ei, si], az[ei, si], delay[ei, si] = e_n, a_n, dl
    return el, az, delay


def block_lsq(
    g: BlockGeometry,
    use: BoolArray,
    nav: NavData,
    settings: LsqSettings,
    x0: FloatArray,
) -> BlockLsq:
    """Weighted Gauss–Newton of every epoch of ``g`` on its ``use`` rows
    (:func:`robustrtk.measurement.undifferenced.lsq_solve` epoch by epoch).

    Parameters
    ----------
    g : BlockGeometry, E epochs
    use : ndarray of bool, shape (E, S)
    x0 : ndarray, shape (E, 3)
        Start of each epoch (zeros: the Earth's centre).
    """
    n_ep, n_sat = g.code_m.shape
    n_sys = len(g.systems)
    out = BlockLsq.empty(n_ep, n_sat, n_sys)
    pos = np.array(x0, dtype=float, copy=True)
    clk = np.zeros((n_ep, n_sys))
    clk_set = np.zeros((n_ep, n_sys), bool)
    mask = np.deg2rad(settings.elev_mask_deg)
    onehot = np.zeros((n_sat, n_sys))
    onehot[np.arange(n_sat), g.sys_col] = 1.0
    running = np.arange(n_ep)
    for it in range(settings.max_iter):
        if running.size == 0:
            break
        e = running
        p = pos[e]
        el, _, delay = block_atmosphere(
            g.t_s[e], g.sat_pos_m[e], p, nav, settings.tropo, settings.iono, g.freq_hz[e], use[e]
        )
        act = use[e] & (el >= mask)
        present = np.einsum("es,sk->ek", act.astype(float), onehot) > 0
        n_unk = 3 + present.sum(axis=1)
        enough = act.sum(axis=1) >= n_unk
        rng, u = geometric_range(g.sat_pos_m[e], p[:, None, :])
        b = np.where(clk_set[e], clk[e], 0.0)
        v = g.code_m[e] + g.sat_clk_m[e] - delay - rng - b[:, g.sys_col]
        H = np.concatenate([-u, np.broadcast_to(onehot, (e.size, n_sat, n_sys))], axis=2)
        H = np.where(act[..., None], H, 0.0)
        cn0 = g.cn0_dbhz[e] if settings.use_cn0 else None
        var = elevation_cn0_variance(settings.code_sigma_m, el, cn0, cn0_ref_dbhz=settings.cn0_ref_dbhz)
        sw = np.where(act, 1.0 / np.sqrt(var), 0.0)
        vw = np.where(act, v * sw, 0.0)
        Hw = H * sw[..., None]
        HwT = Hw.transpose(0, 2, 1)
        N = np.matmul(HwT, Hw)
        # absent systems: a diagonal element of the epoch's own matrix, zero right-hand side
        pad = np.flatnonzero(~present.reshape(-1))
        ei, si = np.divmod(pad, n_sys)
        N[ei, 3 + si, 3 + si] = N[ei, 0, 0]
        good = enough & np.all(np.isfinite(N.reshape(e.size, -1)), axis=1)
        inv = np.full_like(N, np.nan)
        good &= well_conditioned(N, good, inv)
        # epochs that fail now have no solution (lsq_solve returns None)
        failed = e[~good]
        out.solved[failed] = False
        gi = np.flatnonzero(good)
        e = e[gi]
        if e.size == 0:
            running = e
            break
        Ng = N[gi]
        rhs = np.matmul(HwT[gi], vw[gi][..., None])[..., 0]
        dx = np.linalg.solve(Ng, rhs[..., None])[..., 0]
        pos[e] = p[gi] + dx[:, :3]
        pres = present[gi]
        new_clk = b[gi] + dx[:, 3:]
        clk[e] = np.where(pres, new_clk, clk[e])
        clk_set[e] |= pres
        out.solved[e] = True
        step = np.sqrt(np.sum(dx * dx, axis=1))
        conv = step < 1e-4
        # an epoch's solution is that of its last iteration: written when it converged or
        # the iterations end (one that fails later has none, whatever was written)
        w = np.flatnonzero(conv) if it < settings.max_iter - 1 else np.arange(e.size)
        ew, gw = e[w], gi[w]
        Hg = H[gw]
        out.pos[ew] = pos[ew]
        out.clk[ew] = clk[ew]
        out.clk_set[ew] = clk_set[ew]
        out.cov[ew] = inv[gw]
        out.v[ew] = np.where(act[gw], v[gw] - np.matmul(Hg, dx[w][..., None])[..., 0], np.nan)
        out.var[ew] = var[gw]
        out.H[ew] = Hg
        out.act[ew] = act[gw]
        out.n_unknowns[ew] = n_unk[gw]
        running = e[~conv]
    return out


@dataclass
class BlockFde:
    """:func:`robustrtk.measurement.undifferenced.lsq_fde` of E epochs.

    Attributes
    ----------
    lsq : BlockLsq
        The final solutions (``lsq.solved`` False: none).
    excluded : list of list of int
        Satellite columns excluded per epoch, in order.
    chi2_ok : ndarray of bool, shape (E,)
    """

    lsq: BlockLsq
    excluded: list[list[int]]
    chi2_ok: BoolArray


def block_fde(
    g: BlockGeometry,
    nav: NavData,
    settings: LsqSettings,
    x0: FloatArray,
    chi2_cache: dict[int, float] | None = None,
) -> BlockFde:
    """Least squares with chi-square fault detection and exclusion for every epoch of ``g``
    (the rules of :func:`robustrtk.measurement.undifferenced.lsq_fde`)."""
    n_ep = g.code_m.shape[0]
    thr = {} if chi2_cache is None else chi2_cache
    use = g.ok.copy()
    if settings.snr_mask_dbhz > 0:
        use &= ~(g.cn0_dbhz < settings.snr_mask_dbhz)
    out = block_lsq(g, use, nav, settings, x0)
    far = out.solved & (np.sqrt(np.sum(np.nan_to_num(out.pos) ** 2, axis=1)) < 6.0e6)
    out.solved &= ~far
    excluded: list[list[int]] = [[] for _ in range(n_ep)]
    chi2_ok = np.zeros(n_ep, bool)
    pending = np.flatnonzero(out.solved)
    while pending.size:
        sub = out.take(pending)
        dof = sub.act.sum(axis=1) - sub.n_unknowns
        done_ok = (dof < 1) | (not settings.fde)
        test = np.sum(np.where(sub.act, sub.v**2 / sub.var, 0.0), axis=1)
        limit = np.full(dof.size, np.inf)
        for d in sorted(set(dof[dof >= 1].tolist())):  # not np.unique: it loads numpy.ma
            limit[dof == d] = _chi2(thr, 1.0 - settings.fde_alpha, int(d))
        done_ok |= test <= limit
        n_ex = np.array([len(excluded[i]) for i in pending])
        give_up = ~done_ok & ((dof < 2) | (n_ex >= settings.max_exclusions))
        chi2_ok[pending[done_ok]] = True
        more = ~done_ok & ~give_up
        if not more.any():
            break
        ep = pending[more]
        s = sub.take(np.flatnonzero(more))
        cvv = s.var - np.sum(np.matmul(s.H, s.cov) * s.H, axis=2)
        w = np.abs(s.v) / np.sqrt(np.maximum(cvv, 1e-12 * s.var))
        w = np.where(s.act, w, -np.inf)
        top = np.max(w, axis=1, keepdims=True)
        worst = np.argmax(w >= top - 1e-6 * np.abs(top), axis=1)  # ties as measurement.worst_row
        use[ep, worst] = False
        for i, j in zip(ep.tolist(), worst.tolist(), strict=True):
            excluded[i].append(j)
        nxt = block_lsq(g.take(ep), use[ep], nav, settings, s.pos)
        back = ~nxt.solved
        for i in ep[back].tolist():
            excluded[i].pop()
        keep = np.flatnonzero(~back)
        out.put(ep[keep], nxt.take(keep))
        pending = ep[keep]
    return BlockFde(out, excluded, chi2_ok)


#: Largest condition number of a normal matrix (``lsq_solve``'s test).
MAX_COND = 1e14


def well_conditioned(N: FloatArray, rows: BoolArray, inv_out: FloatArray) -> BoolArray:
    """Which matrices of the stack ``N`` (E, k, k) among ``rows`` have a 2-norm condition
    number ≤ :data:`MAX_COND`, their inverses written into ``inv_out``.

    ``cond₂(N) ≤ ‖N‖_F ‖N⁻¹‖_F``: where that bound passes, the matrix passes; the few
    others get the singular values (:func:`numpy.linalg.cond`), as the per-epoch test.
    """
    ok = np.zeros(N.shape[0], bool)
    idx = np.flatnonzero(rows)
    if idx.size == 0:
        return ok
    sub = N[idx]
    try:
        inv = np.linalg.inv(sub)
    except np.linalg.LinAlgError:
        inv = np.full_like(sub, np.nan)
        for k in range(idx.size):
            try:
                inv[k] = np.linalg.inv(sub[k])
            except np.linalg.LinAlgError:
                pass
    with np.errstate(over="ignore", invalid="ignore"):
        bound = np.sqrt(np.sum(sub * sub, axis=(1, 2)) * np.sum(inv * inv, axis=(1, 2)))
    sure = bound <= MAX_COND
    check = np.flatnonzero(~sure & np.all(np.isfinite(inv.reshape(idx.size, -1)), axis=1))
    if check.size:
        sure[check] = np.linalg.cond(sub[check]) <= MAX_COND
    ok[idx] = sure
    inv_out[idx] = inv
    return ok


def _chi2(cache: dict[int, float], q: float, dof: int) -> float:
    """``chi2_ppf(q, dof)``, remembered per degree of freedom."""
    if dof not in cache:
        cache[dof] = chi2_ppf(q, dof)
    return cache[dof]


__all__ = ["BlockFde", "BlockGeometry", "BlockLsq", "block_atmosphere", "block_fde", "block_lsq"]
