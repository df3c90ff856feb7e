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
and ``T`` Saastamoinen. Variances ``sigma^2 / sin^2(el)`` (times the C/N0 factor of
:func:`robustrtk.pipeline.spp._variance` when ``kalman_use_cn0``).

Dynamics: white acceleration, with separate horizontal and vertical spectral densities
(a road vehicle accelerates far less vertically); clocks driven by the common drift plus
their own white noise; ``ifb`` and ``N`` random walks. A carrier-phase arc ends (its ``N``
is dropped and a new one starts from the phase minus the predicted range) when the phase
was absent at the previous epoch, when the robust update rejected it at the previous
epoch, or — with ``lli_reset`` — when the loss-of-lock bit is set; without ``lli_reset``
a loss-of-lock flag only adds ``slip_var_m2`` to ``N`` (phones set it far more often than
the phase actually slips). All rows go through one robust update (``cfg.robust``).

The forward filter records its transitions, so a Rauch–Tung–Striebel pass
(:mod:`robustrtk.estimation.smoother`) can smooth the whole track when ``cfg.smoother``.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable
from dataclasses import dataclass, replace

import numpy as np

from robustrtk.core import CLIGHT, FloatArray, ObsBatch
from robustrtk.estimation.models import LinearMeasurement
from robustrtk.estimation.robust import make_policy
from robustrtk.estimation.smoother import FilterStep, rts_smooth
from robustrtk.estimation.state import GaussianState, StateLayout
from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.geometry.frames import ecef2enu_rotation, ecef2geodetic
from robustrtk.geometry.los import OMEGA_E_RAD_S, geometric_range
from robustrtk.io.rinex_nav import NavData
from robustrtk.measurement.corrections import F_L1_HZ, iono_klobuchar, tropo_saastamoinen
from robustrtk.pipeline.spp import (
    BAND1_PREFERENCE,
    SppConfig,
    SppEpoch,
    _EpochGeometry,
    _lsq_fde,
    _make_filter,
    _none_epoch,
    _variance,
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


def choose_signals(
    batch: ObsBatch, nav: NavData, dual_frequency: bool, systems: str | None = None
) -> Signals:
    """Per system, the first band-1 column with code (:data:`BAND1_PREFERENCE`) and, when
    ``dual_frequency``, the first second-band column with code (:data:`BAND2_PREFERENCE`).

    A batch reduced by :func:`robustrtk.pipeline.spp.select_band1` (``signals == ("1",)``)
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


def _lsq_geometry(sig: Signals, i: int, sats: _Sats) -> _EpochGeometry:
    """Band-1 code of the epoch in the form the least-squares SPP takes."""
    code1 = sig.code_m[i, sats.idx, 0]
    sel = np.isfinite(code1) & np.isfinite(sats.tgd_m[:, 0])
    j = sats.idx[sel]
    wl = sig.wavelength_m[j, 0]
    return _EpochGeometry(
        ids=tuple(sig.ids[q] for q in j),
        sys=tuple(sig.sys[q] for q in j),
        code_m=code1[sel],
        cn0_dbhz=sig.cn0_dbhz[i, j, 0],
        rate_m_s=-wl * sig.doppler_hz[i, j, 0],
        freq_hz=np.where(np.isfinite(wl), CLIGHT / np.where(np.isfinite(wl), wl, 1.0), F_L1_HZ),
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


class _Filter:
    """Forward pass of the Kalman SPP (one instance per call)."""

    def __init__(self, sig: Signals, eph: EphemerisSource, cfg: SppConfig) -> None:
        self.sig, self.eph, self.nav, self.cfg = sig, eph, eph.nav, cfg
        self.systems = list(sig.systems)
        ns = len(self.systems)
        self.band2_systems = sorted({sig.sys[j] for j in range(len(sig.ids)) if sig.band[j][1]})
        blocks: list[tuple[str, int]] = [("pos", 3), ("vel", 3), ("clk", ns), ("drift", 1)]
        if cfg.use_phase:
            blocks.append(("pclk", ns))
        if self.band2_systems:
            blocks.append(("ifb", len(self.band2_systems)))
        self.fixed = StateLayout(blocks=tuple(blocks))
        self.kf = _make_filter(cfg.filter)
        self.policy = make_policy(cfg.robust)
        self.mask_rad = np.deg2rad(cfg.elev_mask_deg)
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

    # --------------------------------------------------------------- dynamics
    def fixed_transition(self, x: FloatArray, dt: float) -> tuple[FloatArray, FloatArray]:
        """``F``, ``Q`` of the fixed blocks over ``dt`` (horizontal/vertical acceleration in
        the local frame at the current position)."""
        cfg, L = self.cfg, self.fixed
        n = L.n_fixed
        a = abs(dt)
        F = np.eye(n)
        Q = np.zeros((n, n))
        p, v, d = L.slice("pos"), L.slice("vel"), L.slice("drift").start
        F[p, v] = np.eye(3) * dt
        lat, lon, _ = ecef2geodetic(x[p])
        rot = ecef2enu_rotation(float(lat), float(lon))
        qa = rot.T @ np.diag([cfg.sigma_acc_m_s2**2] * 2 + [cfg.sigma_acc_up_m_s2**2]) @ rot
        Q[p, p] = qa * a**3 / 3
        Q[p, v] = Q[v, p] = qa * dt**2 / 2
        Q[v, v] = qa * a
        clocks = list(range(L.slice("clk").start, L.slice("clk").stop))
        q_own = [cfg.q_clk_m2_s] * len(clocks)
        if L.has("pclk"):
            pc = list(range(L.slice("pclk").start, L.slice("pclk").stop))
            clocks += pc
            q_own += [cfg.q_phase_clk_m2_s] * len(pc)
        ci = np.array(clocks)
        qd = cfg.q_drift_m2_s3
        F[ci, d] = dt
        Q[np.ix_(ci, ci)] = qd * a**3 / 3 + np.diag(q_own) * a
        Q[ci, d] = Q[d, ci] = qd * dt**2 / 2
        Q[d, d] = qd * a
        if L.has("ifb"):
            f = L.slice("ifb")
            Q[f, f] = np.eye(f.stop - f.start) * cfg.q_ifb_m2_s * a
        return F, Q

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
        cfg, sig, nav = self.cfg, self.sig, self.nav
        rows = _Rows([], [], [], [], [], [], [])
        new_amb: dict[AmbKey, float] = {}
        suspect: list[AmbKey] = []
        if sats.idx.size == 0:
            return rows, new_amb, suspect
        L = self.fixed
        p, v, d = L.slice("pos"), L.slice("vel"), L.slice("drift").start
        pos, vel = x[p], x[v]
        lat, lon, h = ecef2geodetic(pos)
        rot = ecef2enu_rotation(float(lat), float(lon))
        enu = (sats.pos_m - pos) @ rot.T
        el = np.arcsin(np.clip(enu[:, 2] / np.linalg.norm(enu, axis=1), -1.0, 1.0))
        az = np.mod(np.arctan2(enu[:, 0], enu[:, 1]), 2 * np.pi)
        rng, u = geometric_range(sats.pos_m, pos)
        trop = np.zeros(el.size)
        if cfg.tropo and -1000.0 < float(h) < 1.0e4:
            trop = tropo_saastamoinen(float(lat), float(h), el)
        iono1 = np.zeros(el.size)
        if cfg.iono and nav.ion_gps_alpha is not None and nav.ion_gps_beta is not None:
            iono1 = iono_klobuchar(t, float(lat), float(lon), az, el, nav.ion_gps_alpha, nav.ion_gps_beta)
        sp, sv = sats.pos_m, sats.vel_m_s
        sag_rate = (
            OMEGA_E_RAD_S
            / CLIGHT
            * (sv[:, 1] * pos[0] + sp[:, 1] * vel[0] - sv[:, 0] * pos[1] - sp[:, 0] * vel[1])
        )
        use_cn0 = cfg.kalman_use_cn0
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
                if cn0 < cfg.min_cn0_dbhz:
                    continue

                def var(sigma: float, q: int = q, cn0: float = cn0) -> float:
                    return float(_variance(cfg, el[q : q + 1], np.array([cn0]), sigma, use_cn0)[0])

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
                    self._add(rows, z - h0, Hr, var(cfg.code_sigma_m), f"{tx}:P{band}", "P", s, None)
                dop = sig.doppler_hz[i, j, b]
                if cfg.use_doppler and not doppler_done and np.isfinite(dop) and np.isfinite(lam):
                    doppler_done = True
                    Hr = np.zeros(n)
                    Hr[v] = -u[q]
                    Hr[d] = 1.0
                    z = -lam * dop + sats.drift_m_s[q]
                    h0 = float(u[q] @ (sv[q] - vel)) - sag_rate[q] + x[d]
                    self._add(rows, z - h0, Hr, var(cfg.doppler_sigma_m_s), f"{tx}:D{band}", "D", s, None)
                phase = sig.phase_cyc[i, j, b]
                if cfg.use_phase and np.isfinite(phase) and np.isfinite(lam) and np.isfinite(iono):
                    z = lam * phase + sats.clk_m[q] + iono - trop[q]
                    h0 = rng[q] + x[self.pclk_index(s)]
                    sb = (tx, b)
                    lli = sig.lli[i, j, b]
                    lost = bool(np.isfinite(lli) and int(lli) & 1)
                    cont = (
                        sb in self.arc
                        and self.last_seen.get(sb) == i - 1
                        and sb not in self.restart
                        and not (lost and cfg.lli_reset)
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
                    self._add(rows, z - h0, Hr, var(cfg.phase_sigma_m), f"{tx}:L{band}", "L", s, key)
        self.restart.clear()
        return rows, new_amb, suspect

    @staticmethod
    def _add(
        rows: _Rows, d: float, H: FloatArray, var: float, label: str, kind: str, s: str, amb: AmbKey | None
    ) -> None:
        rows.d.append(float(d))
        rows.H.append(H)
        rows.var.append(float(var))
        rows.labels.append(label)
        rows.kind.append(kind)
        rows.system.append(s)
        rows.amb.append(amb)


def _transition(
    old: StateLayout,
    new: StateLayout,
    F_fixed: FloatArray,
    Q_fixed: FloatArray,
    q_amb: float,
    dt: float,
    new_amb: dict[AmbKey, float],
    amb_var0: float,
    extra_var: dict[Hashable, float],
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``(F, u, Q)`` mapping the old state onto the new layout (kept arcs random-walk,
    dropped arcs vanish, new arcs start at their value in ``u`` with variance ``amb_var0``)."""
    nf = old.n_fixed
    n0, n1 = old.size, new.size
    F = np.zeros((n1, n0))
    Q = np.zeros((n1, n1))
    u = np.zeros(n1)
    F[:nf, :nf] = F_fixed
    Q[:nf, :nf] = Q_fixed
    old_pos = {k: nf + a for a, k in enumerate(old.amb_keys)}
    for a, key in enumerate(new.amb_keys):
        r = nf + a
        if key in old_pos:
            F[r, old_pos[key]] = 1.0
            Q[r, r] = q_amb * abs(dt) + extra_var.get(key, 0.0)
        else:
            u[r] = new_amb[key]  # type: ignore[index]
            Q[r, r] = amb_var0
    return F, u, Q


def _reset_rows(F: FloatArray, u: FloatArray, Q: FloatArray, index: int, value: float, var: float) -> None:
    """Make state ``index`` restart at ``value`` with variance ``var`` (in place)."""
    F[index, :] = 0.0
    u[index] = value
    Q[index, :] = 0.0
    Q[:, index] = 0.0
    Q[index, index] = var


def _prior(
    x_old: FloatArray, P_old: FloatArray, F: FloatArray, u: FloatArray, Q: FloatArray
) -> tuple[FloatArray, FloatArray]:
    P = F @ P_old @ F.T + Q
    return F @ x_old + u, 0.5 * (P + P.T)


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


def run_kalman(
    batch: ObsBatch,
    eph: EphemerisSource,
    cfg: SppConfig,
    progress: Callable[[int, int], None] | None = None,
    systems: str | None = None,
) -> list[SppEpoch]:
    """Kalman SPP of a batch (see the module docstring); the implementation behind
    :func:`robustrtk.pipeline.spp.solve_spp_kalman`."""
    sig = choose_signals(batch, eph.nav, cfg.dual_frequency, systems)
    flt = _Filter(sig, eph, cfg)
    nf = flt.fixed.n_fixed
    T = len(batch)
    out: list[SppEpoch] = []
    steps: list[FilterStep | None] = []
    state: GaussianState | None = None
    disagree = 0
    for i in range(T):
        t = float(batch.t_s[i])
        sats = _sat_states(sig, i, t, eph)
        x0 = None if state is None else state.x[:3]
        lsq, _, _ = _lsq_fde(t, _lsq_geometry(sig, i, sats), flt.nav, cfg, x0)
        if state is not None and lsq is not None:
            far = float(np.linalg.norm(lsq.pos - state.x[:3])) > cfg.reinit_m
            disagree = disagree + 1 if far else 0
            if disagree >= cfg.reinit_epochs:
                state, disagree = None, 0
        first = state is None
        F_fixed: FloatArray
        Q_fixed: FloatArray
        P_old: FloatArray
        if state is None:
            if lsq is None:
                out.append(_none_epoch(t))
                steps.append(None)
                if progress is not None:
                    progress(i + 1, T)
                continue
            state = flt.initial_state(t, lsq.pos, lsq.cov[:3, :3], lsq.clk)
            flt.last_seen.clear()
            flt.restart.clear()
            F_fixed, Q_fixed = np.eye(nf), state.P.copy()
            x_old, P_old = state.x, np.zeros((nf, nf))
        else:
            F_fixed, Q_fixed = flt.fixed_transition(state.x, t - state.t_s)
            x_old, P_old = state.x, state.P
        x_lin = F_fixed @ state.x[:nf]
        rows, new_amb, suspect = flt.build_rows(i, t, sats, x_lin, nf)
        in_rows = set(rows.amb)
        kept = tuple(k for k in state.layout.amb_keys if k in in_rows)
        layout = replace(flt.fixed, amb_keys=kept + tuple(new_amb))
        F, u, Q = _transition(
            state.layout,
            layout,
            F_fixed,
            Q_fixed,
            cfg.q_amb_m2_s,
            t - state.t_s,
            new_amb,
            cfg.amb_var0_m2,
            {k: cfg.slip_var_m2 for k in suspect},
        )
        x_prior, P_prior = _prior(x_old, P_old, F, u, Q)
        m = len(rows.d)
        H, d = _design(rows, layout, x_prior, x_lin) if m else (np.zeros((0, layout.size)), np.zeros(0))
        # clock jumps: restart a clock whose median innovation is beyond clock_reset_m
        resets = 0
        for kind in ("P", "L") if cfg.use_phase else ("P",):
            for s in flt.systems:
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
                if abs(med) > cfg.clock_reset_m:
                    c = flt.clk_index(s) if kind == "P" else flt.pclk_index(s)
                    _reset_rows(F, u, Q, c, float(x_prior[c]) + med, 1e4)
                    resets += 1
        if resets:
            x_prior, P_prior = _prior(x_old, P_old, F, u, Q)
            H, d = _design(rows, layout, x_prior, x_lin)
        prior = GaussianState(x=x_prior, P=P_prior, t_s=t, layout=layout)
        if m:
            meas = LinearMeasurement(H=H, z=d + H @ x_prior, R=np.diag(rows.var), labels=tuple(rows.labels))
            res = flt.kf.update(prior, meas, flt.policy)
            post = res.state
            used = np.isfinite(res.factors)
            rejected = tuple(lab for lab, ok in zip(rows.labels, used, strict=True) if not ok)
            for r, key in enumerate(rows.amb):
                if key is not None and not used[r]:
                    flt.restart.add((key[0], key[1]))
            kinds = np.array(rows.kind)
            n_code = int(np.sum(used & (kinds == "P")))
            n_pos = int(np.sum(used & (kinds != "D")))
        else:
            post, rejected, n_code, n_pos = prior, (), 0, 0
        steps.append(FilterStep(None if first else F, x_prior, P_prior, post.x, post.P))
        state = post
        out.append(_epoch(post.x, post.P, flt, t, n_code, rejected, n_pos >= 4))
        if progress is not None:
            progress(i + 1, T)
    if cfg.smoother:
        out = _smoothed(out, steps, flt)
    return out


def _epoch(
    x: FloatArray, P: FloatArray, flt: _Filter, t: float, n_used: int, rejected: tuple[str, ...], ok: bool
) -> SppEpoch:
    clk = {s: float(x[flt.clk_index(s)]) for s in flt.systems}
    return SppEpoch(
        t,
        x[0:3].copy(),
        clk,
        P[0:3, 0:3].copy(),
        n_used,
        "single" if ok else "none",
        rejected,
        ok,
        x[3:6].copy(),
    )


def _smoothed(out: list[SppEpoch], steps: list[FilterStep | None], flt: _Filter) -> list[SppEpoch]:
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
            res[k] = _epoch(x, P, flt, e.t_s, e.n_used, e.excluded, e.chi2_ok)
    return res


__all__ = ["BAND2_PREFERENCE", "Signals", "choose_signals", "run_kalman"]
