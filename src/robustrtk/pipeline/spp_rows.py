"""Observation rows of the Kalman SPP: the run's bookkeeping (indices, arcs, initial state), the
linearised rows of an epoch, the zero-velocity test and the design matrix."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from robustrtk.core import CLIGHT, FloatArray, median_of
from robustrtk.estimation.state import GaussianState, StateLayout
from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.geometry.los import OMEGA_E_RAD_S, geometric_range
from robustrtk.measurement.chi2 import chi2_ppf
from robustrtk.measurement.corrections import F_L1_HZ
from robustrtk.measurement.undifferenced import (
    atmosphere,
    cn0_variance,
    elevation_cn0_variance,
)
from robustrtk.pipeline.config import Config
from robustrtk.pipeline.spp_dynamics import (
    spp_layout,
)
from robustrtk.pipeline.spp_signals import (
    PHASE_CLOCK_VAR0_M2,
    AmbKey,
    SatStates,
    Signals,
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


# ---------------------------------------------------------------------- rows
@dataclass
class SppRows:
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


class KalmanSppRun:
    """State bookkeeping of one Kalman SPP run: indices, arcs, initial state, rows.

    Parameters
    ----------
    systems : sequence of str
        Systems with a code and a phase clock in the state (sorted).
    band2_systems : sequence of str
        Systems with a second-band code bias in the state (sorted).
    eph : EphemerisSource
        The ephemerides (:meth:`set_ephemerides` when new ones arrive).
    cfg : Config
    """

    def __init__(
        self, systems: Sequence[str], band2_systems: Sequence[str], eph: EphemerisSource, cfg: Config
    ) -> None:
        self.eph, self.nav, self.cfg = eph, eph.nav, cfg
        self.systems = list(systems)
        self.band2_systems = list(band2_systems)
        self.fixed = spp_layout(len(self.systems), cfg.spp.use_phase, len(self.band2_systems))
        self.mask_rad = np.deg2rad(cfg.gnss.elev_mask_deg)
        self.arc: dict[tuple[str, int], int] = {}  # current arc number per (tx, band)
        self.last_seen: dict[tuple[str, int], int] = {}  # epoch number of the last phase
        self.restart: set[tuple[str, int]] = set()  # phases rejected: new arc next epoch
        self._cn0_memo: dict[tuple[float, float, float], float] = {}
        self._indices: tuple[StateLayout, tuple[dict[str, int], dict[str, int], dict[str, int]]] | None = None

    @classmethod
    def of(cls, sig: Signals, eph: EphemerisSource, cfg: Config) -> KalmanSppRun:
        """The run of a file's signals: its systems, and those with a second band."""
        band2 = sorted({sig.sys[j] for j in range(len(sig.ids)) if sig.band[j][1]})
        return cls(sig.systems, band2, eph, cfg)

    def set_ephemerides(self, eph: EphemerisSource) -> None:
        """New ephemerides (and the ionosphere of their navigation data) from now on."""
        self.eph, self.nav = eph, eph.nav

    def _cn0_var(self, sigma_ref: float, cn0_dbhz: float, cn0_ref_dbhz: float) -> float:
        """``float(cn0_variance(sigma_ref, cn0_dbhz, cn0_ref_dbhz))`` of one row, remembered by
        its arguments (a receiver reports C/N0 on a coarse grid: few distinct values)."""
        key = (sigma_ref, cn0_dbhz, cn0_ref_dbhz)
        out = self._cn0_memo.get(key)
        if out is None:
            out = float(cn0_variance(sigma_ref, cn0_dbhz, cn0_ref_dbhz))
            if cn0_dbhz == cn0_dbhz:  # a NaN key would never be found again
                self._cn0_memo[key] = out
        return out

    # --------------------------------------------------------------- indices
    def _i(self, block: str, k: int = 0) -> int:
        return self.fixed.slice(block).start + k

    def clk_index(self, s: str) -> int:
        return self._i("clk", self.systems.index(s))

    def pclk_index(self, s: str) -> int:
        return self._i("pclk", self.systems.index(s))

    def _row_indices(self) -> tuple[dict[str, int], dict[str, int], dict[str, int]]:
        """Code clock, phase clock and (second band) ifb state index per system (read-only;
        computed once per layout)."""
        if self._indices is not None and self._indices[0] is self.fixed:
            return self._indices[1]
        has_pclk = self.fixed.has("pclk")
        out = (
            {s: self.clk_index(s) for s in self.systems},
            {s: self.pclk_index(s) for s in self.systems} if has_pclk else {},
            {s: self.ifb_index(s) for s in self.band2_systems},
        )
        self._indices = (self.fixed, out)
        return out

    def clk_indices(self) -> dict[str, int]:
        """The code clock's state index per system (:meth:`clk_index` of each; read-only)."""
        return self._row_indices()[0]

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
        self, sig: Signals, i: int, seq: int, t: float, sats: SatStates, x: FloatArray, n: int
    ) -> tuple[SppRows, dict[AmbKey, float], list[AmbKey]]:
        """Rows at the prior ``x`` (fixed part valid; ambiguity values looked up later) of
        epoch ``i`` of ``sig``, the run's epoch number ``seq`` (an arc continues from the
        epoch numbered ``seq − 1``).

        Returns the rows (phase innovations without their ``N``), the initial value of each
        new arc's ``N`` and the keys of arcs that continue with a loss-of-lock flag.
        """
        cfg = self.cfg
        spp, meas = cfg.spp, cfg.measurement
        rows = SppRows([], [], [], [], [], [], [])
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
        # the variances of every satellite at once per σ and band (elementwise the numbers of
        # one row at a time)
        cn0_all = sig.cn0_dbhz[i, sats.idx, :]
        var_l: dict[tuple[float, int], list[float]] = {}

        def var_of(sigma: float, b: int) -> list[float]:
            """The variances of every satellite's rows of σ ``sigma`` on band ``b``
            (computed when a row first needs them)."""
            vals = var_l.get((sigma, b))
            if vals is None:
                cn0 = cn0_all[:, b] if spp.kalman_use_cn0 else None
                vals = elevation_cn0_variance(sigma, el, cn0, cn0_ref_dbhz=spp.cn0_ref_dbhz).tolist()
                var_l[sigma, b] = vals
            return vals

        clk_at, pclk_at, ifb_at = self._row_indices()
        isfinite = math.isfinite
        # the epoch's numbers as Python floats: the same IEEE operations row by row,
        # without a numpy scalar per value
        idx = sats.idx.tolist()
        el_l, trop_l, iono_l, rng_l = el.tolist(), trop.tolist(), iono1.tolist(), rng.tolist()
        clk_l, drift_l, tgd_l = sats.clk_m.tolist(), sats.drift_m_s.tolist(), sats.tgd_m.tolist()
        code_i, dop_i, phase_i = sig.code_m[i].tolist(), sig.doppler_hz[i].tolist(), sig.phase_cyc[i].tolist()
        cn0_i, lli_i, wl_l = sig.cn0_dbhz[i].tolist(), sig.lli[i].tolist(), sig.wavelength_m.tolist()
        neg_u = -u
        x_d = x[d]
        mask = self.mask_rad
        cn0_var = self._cn0_var
        for q, j in enumerate(idx):
            if el_l[q] < mask:
                continue
            s, tx = sig.sys[j], sig.ids[j]
            doppler_done = False
            for b in range(2):
                band = sig.band[j][b]
                if not band:
                    continue
                lam = wl_l[j][b]
                f = CLIGHT / lam if isfinite(lam) else (F_L1_HZ if b == 0 else np.nan)
                iono = iono_l[q] * (F_L1_HZ / f) ** 2 if isfinite(f) else np.nan
                cn0 = cn0_i[j][b]
                if cn0 < meas.snr_mask_dbhz:
                    continue
                code = code_i[j][b]
                tgd = tgd_l[q][b]
                if isfinite(code) and isfinite(tgd) and isfinite(iono):
                    Hr = np.zeros(n)
                    Hr[p] = neg_u[q]
                    Hr[clk_at[s]] = 1.0
                    h0 = rng_l[q] + x[clk_at[s]]
                    if b == 1:
                        Hr[ifb_at[s]] = 1.0
                        h0 += x[ifb_at[s]]
                    z = code + clk_l[q] - tgd - iono - trop_l[q]
                    rows.add(z - h0, Hr, var_of(meas.code_sigma_m, b)[q], f"{tx}:P{band}", "P", s, None)
                dop = dop_i[j][b]
                if spp.use_doppler and not doppler_done and isfinite(dop) and isfinite(lam):
                    doppler_done = True
                    Hr = np.zeros(n)
                    Hr[v] = neg_u[q]
                    Hr[d] = 1.0
                    z = -lam * dop + drift_l[q]
                    h0 = float(u[q] @ (sv[q] - vel)) - sag_rate[q] + x_d
                    if spp.doppler_weighting == "cn0":
                        vd = cn0_var(spp.doppler_cn0_sigma_m_s, cn0, spp.cn0_ref_dbhz)
                    else:
                        vd = var_of(spp.doppler_sigma_m_s, b)[q]
                    rows.add(z - h0, Hr, vd, f"{tx}:D{band}", "D", s, None)
                phase = phase_i[j][b]
                if spp.use_phase and isfinite(phase) and isfinite(lam) and isfinite(iono):
                    z = lam * phase + clk_l[q] + iono - trop_l[q]
                    h0 = rng_l[q] + x[pclk_at[s]]
                    sb = (tx, b)
                    lli = lli_i[j][b]
                    lost = bool(isfinite(lli) and int(lli) & 1)
                    cont = (
                        sb in self.arc
                        and self.last_seen.get(sb) == seq - 1
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
                    self.last_seen[sb] = seq
                    Hr = np.zeros(n)
                    Hr[p] = neg_u[q]
                    Hr[pclk_at[s]] = 1.0
                    rows.add(z - h0, Hr, var_of(meas.phase_sigma_m, b)[q], f"{tx}:L{band}", "L", s, key)
        self.restart.clear()
        return rows, new_amb, suspect

    def zupt_rows(self, rows: SppRows, x_lin: FloatArray, n: int) -> bool:
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
        self, rows: SppRows, d: FloatArray, x_prior: FloatArray, new_amb: Mapping[AmbKey, float]
    ) -> dict[int, tuple[float, float]]:
        """Clocks whose per-system median innovation (code; phase of continuing arcs) is
        beyond ``clock_reset_m``: state index -> (restart value, variance)."""
        out: dict[int, tuple[float, float]] = {}
        use_phase = self.cfg.spp.use_phase
        groups: dict[tuple[str, str], list[float]] = {}
        for kind, s, amb, dr in zip(rows.kind, rows.system, rows.amb, d.tolist(), strict=True):
            if kind == "P" or (kind == "L" and use_phase and amb not in new_amb):
                groups.setdefault((kind, s), []).append(dr)
        for kind in ("P", "L") if use_phase else ("P",):
            for s in self.systems:
                vals = groups.get((kind, s))
                if not vals:
                    continue
                med = median_of(np.array(vals))
                if abs(med) > self.cfg.spp.clock_reset_m:
                    c = self.clk_index(s) if kind == "P" else self.pclk_index(s)
                    out[c] = (float(x_prior[c]) + med, 1e4)
        return out


def design_rows(
    rows: SppRows, layout: StateLayout, x_prior: FloatArray, x_lin: FloatArray
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
