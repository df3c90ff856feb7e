"""Cooperative positioning of N receivers on RINEX input (Zhou et al. 2018; algorithms.md §21).

Each node runs its own filter (:mod:`robustrtk.estimation.coop`: EKF, augmented UKF,
particle filter or least squares) on its own band-1 pseudoranges and on the ranges to its
peers, with the positions and covariances the peers broadcast; there is no central node
(:func:`solve_coop`). Epoch by epoch the nodes are processed in the order given, each using
the latest broadcast of every peer (the same epoch's for peers processed before it, the
previous epoch's otherwise), not older than ``max_broadcast_age_s``. A node broadcasts
its Gaussian summary ``[p, b₁]``, ``P`` after every solved epoch.

The centralised reference (:func:`solve_coop_central`) is one joint filter over the stacked
states of all nodes with every node's pseudoranges and every inter-node range (no
inflation: the joint covariance carries the correlation).

Inter-node ranges (:class:`RangeLink`) come from our own DD carrier-phase RTK between the
two files (:func:`rtk_range_link`: fixed base at a surveyed position, else moving base; per
epoch, or one session value for static nodes), from a constant, or from a file
(:func:`read_range_file`).

A node's epoch is *solved* when its rows of that epoch (own pseudoranges and ranges to
peers with a usable broadcast) are at least as many as the unknowns they touch
(``3 + clocks seen``) and the correction succeeded; an unsolved epoch is reported with
status ``none``. A filter starts at the first epoch at which a least-squares solution of
the node's rows (traditional range variance) exists.

Test scenarios: :func:`windowsill_mask` (one azimuth sector of the sky, a seeded centre,
at most ``max_sats`` satellites) and :func:`inject_code_bias` (a seeded code error on some
satellites for a stretch of epochs).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np
import numpy.typing as npt

from robustrtk import jit
from robustrtk.core import BoolArray, FloatArray, InputError, ObsBatch, Solution
from robustrtk.estimation.coop import (
    COOPERATION,
    FILTER_KINDS,
    Belief,
    LocationTimeModel,
    NodeFilter,
    PeerBroadcast,
    PeerWindow,
    RangeObservation,
    ResetSettings,
    gauss_newton,
    make_node_filter,
    node_layout,
    peer_range_model,
)
from robustrtk.estimation.state import GaussianState, StateLayout
from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.geometry.frames import ecef2enu_rotation, ecef2geodetic
from robustrtk.geometry.receivers import PositionSource
from robustrtk.io.rinex_nav import NavData
from robustrtk.measurement.coop import InterNodeRangeModel, PseudorangeModel, node_pseudoranges
from robustrtk.measurement.dd import StackedModel
from robustrtk.measurement.undifferenced import EpochGeometry, epoch_geometry
from robustrtk.pipeline.gnss import align_base, load_obs, nav_source, own_solution_track
from robustrtk.pipeline.rtk_gnss import rtk_gnss_config, solve_rtk
from robustrtk.pipeline.spp_common import select_band1

PathLike = str | os.PathLike[str]


# ---------------------------------------------------------------------- inputs
@dataclass(frozen=True)
class CoopSettings:
    """Settings of a cooperative run.

    Attributes
    ----------
    filter : {"ekf", "ukf", "pf", "ls"}
    cooperation : {"improved", "traditional", "off"}
    sigma_pos_m_s, sigma_clk_m_s : float
        Eq. 8 process noise σ_ẋ (per axis) and σ_ḃ (m/s).
    code_sigma_m, cn0_ref_dbhz, use_cn0 :
        Eq. 25 variance (:func:`robustrtk.measurement.coop.zhou_code_variance`).
    elev_mask_deg : float
    tropo, iono : str
    ukf_alpha, ukf_beta : float
    n_particles, ess_threshold, roughening, seed :
        Particle filter (node ``i`` uses the seed ``seed + i``).
    reset : ResetSettings
        σ_set, σ_wset (None: short-window estimates) and the window.
    max_broadcast_age_s : float
        Older peer broadcasts are not used.
    init_floor_m : float
        Floor of the initial position σ taken from the least-squares start (m).
    systems : str
        System letters used for the code (default GPS, Galileo, BeiDou, QZSS).
    """

    filter: str = "ekf"
    cooperation: str = "improved"
    sigma_pos_m_s: float = 0.01
    sigma_clk_m_s: float = 100.0
    code_sigma_m: float = 3.0
    cn0_ref_dbhz: float = 45.0
    use_cn0: bool = True
    elev_mask_deg: float = 10.0
    tropo: str = "saastamoinen"
    iono: str = "klobuchar"
    ukf_alpha: float = 1.0
    ukf_beta: float = 2.0
    n_particles: int = 10_000
    ess_threshold: float = 0.5
    roughening: float = 0.2
    seed: int = 0
    reset: ResetSettings = field(default_factory=ResetSettings)
    max_broadcast_age_s: float = 60.0
    init_floor_m: float = 1.0
    systems: str = "GECJ"

    def __post_init__(self) -> None:
        if self.filter not in FILTER_KINDS:
            raise InputError(f"filter: expected one of {', '.join(FILTER_KINDS)}, got {self.filter!r}")
        if self.cooperation not in COOPERATION:
            raise InputError(
                f"cooperation: expected one of {', '.join(COOPERATION)}, got {self.cooperation!r}"
            )


@dataclass(frozen=True)
class CoopNode:
    """One receiver.

    Attributes
    ----------
    name : str
    batch : ObsBatch
        Observations (any signals; band 1 is selected), on the common epochs.
    visible : ndarray of bool, shape (T, N), or None
        Satellites the receiver may use per epoch (an occlusion); None: all.
    """

    name: str
    batch: ObsBatch
    visible: BoolArray | None = None


@dataclass(frozen=True)
class RangeLink:
    """A measured range between nodes ``a`` and ``b`` (names), per epoch or constant.

    Attributes
    ----------
    a, b : str
    t_s : ndarray, shape (K,)
        Epochs of the series (GPST s); empty for a constant range.
    range_m, var_m2 : ndarray, shape (K,) (shape (1,) when constant)
    tol_s : float
        Largest distance to a series epoch.
    """

    a: str
    b: str
    t_s: FloatArray
    range_m: FloatArray
    var_m2: FloatArray
    tol_s: float = 0.6

    @classmethod
    def constant(cls, a: str, b: str, range_m: float, sigma_m: float) -> RangeLink:
        return cls(a, b, np.zeros(0), np.array([float(range_m)]), np.array([float(sigma_m) ** 2]))

    def at(self, t_s: float) -> tuple[float, float]:
        """``(range, variance)`` at ``t_s``; NaN when the series has no epoch near it."""
        if self.t_s.size == 0:
            return float(self.range_m[0]), float(self.var_m2[0])
        j = int(np.argmin(np.abs(self.t_s - t_s)))
        if abs(float(self.t_s[j]) - t_s) > self.tol_s:
            return float("nan"), float("nan")
        return float(self.range_m[j]), float(self.var_m2[j])


@dataclass(frozen=True)
class NodeEpoch:
    """One node's output of one epoch (and its diagnostics).

    Attributes
    ----------
    t_s : float
    pos_ecef_m : ndarray, shape (3,)
        NaN when unsolved.
    cov_m2 : ndarray, shape (3, 3)
    solved : bool
    n_sats, n_ranges : int
        Own pseudorange rows and range rows used.
    range_residual_m : float
        Innovation of the first range row (m), NaN without one.
    range_sigma_m : float
        σ̂ of the first range row (m), NaN without one.
    trace_p_m2 : float
        ``tr`` of the position covariance (m²).
    ess : float
        Particle filter effective sample size (NaN for other filters).
    """

    t_s: float
    pos_ecef_m: FloatArray
    cov_m2: FloatArray
    solved: bool
    n_sats: int
    n_ranges: int
    range_residual_m: float = float("nan")
    range_sigma_m: float = float("nan")
    trace_p_m2: float = float("nan")
    ess: float = float("nan")

    def to_solution(self) -> Solution:
        return Solution(
            t_s=self.t_s,
            pos_m=self.pos_ecef_m if self.solved else np.full(3, np.nan),
            cov_m2=self.cov_m2,
            status="single" if self.solved else "none",
            n_used=self.n_sats + self.n_ranges,
        )


@dataclass
class CoopResult:
    """Per node, one :class:`NodeEpoch` per common epoch."""

    nodes: tuple[str, ...]
    epochs: dict[str, list[NodeEpoch]]
    settings: CoopSettings
    info: dict[str, object] = field(default_factory=dict)

    def solutions(self, node: str) -> list[Solution]:
        return [e.to_solution() for e in self.epochs[node]]

    def positions(self, node: str) -> FloatArray:
        """``(T, 3)`` positions, NaN where unsolved."""
        return np.array([e.pos_ecef_m if e.solved else np.full(3, np.nan) for e in self.epochs[node]])

    def solved_fraction(self, node: str) -> float:
        ep = self.epochs[node]
        return float(np.mean([e.solved for e in ep])) if ep else 0.0


# ---------------------------------------------------------------------- scenarios
def _az_el(sat_pos_m: FloatArray, rx_m: FloatArray) -> tuple[FloatArray, FloatArray]:
    lat, lon, _ = ecef2geodetic(rx_m)
    rot = ecef2enu_rotation(float(lat), float(lon))
    enu = (sat_pos_m - rx_m) @ rot.T
    el = np.arcsin(np.clip(enu[:, 2] / np.linalg.norm(enu, axis=1), -1.0, 1.0))
    az = np.mod(np.arctan2(enu[:, 0], enu[:, 1]), 2 * np.pi)
    return az, el


def windowsill_mask(
    batch: ObsBatch,
    eph: EphemerisSource,
    pos_ecef_m: FloatArray,
    *,
    max_sats: int,
    seed: int = 0,
    width_deg: float = 180.0,
    center_az_deg: float | None = None,
    elev_mask_deg: float = 10.0,
) -> tuple[BoolArray, float]:
    """A windowsill occlusion: only one azimuth sector of the sky is visible.

    The sector is ``width_deg`` wide (180°: the half-sky in front of a window, the wall
    hides the rest) centred on ``center_az_deg``, drawn uniformly in [0°, 360°) from
    ``numpy.random.default_rng(seed)`` when None. Per epoch the satellites of the sector
    above ``elev_mask_deg`` are visible, at most ``max_sats`` of them — the highest first
    (the window frame cuts the rest). Azimuths and elevations are seen from ``pos_ecef_m``.

    Returns
    -------
    visible : ndarray of bool, shape (T, N)
    center_az_deg : float
        The sector's centre (deg), drawn or given.
    """
    if center_az_deg is None:
        center_az_deg = float(np.random.default_rng(seed).uniform(0.0, 360.0))
    b1 = batch if len(batch.signals) == 1 else select_band1(batch)
    T, N = b1.code_m.shape[:2]
    vis = np.zeros((T, len(batch.tx_ids)), bool)
    col = {t: i for i, t in enumerate(batch.tx_ids)}
    half = np.deg2rad(width_deg) / 2
    c = np.deg2rad(center_az_deg)
    for k in range(T):
        g = epoch_geometry(b1, k, eph)
        if not g.ids:
            continue
        az, el = _az_el(g.sat_pos_m, np.asarray(pos_ecef_m, float))
        daz = np.abs((az - c + np.pi) % (2 * np.pi) - np.pi)
        ok = g.ok & (daz <= half) & (el >= np.deg2rad(elev_mask_deg))
        cand = np.flatnonzero(ok)
        keep = cand[np.argsort(-el[cand], kind="stable")][:max_sats]
        for j in keep:
            vis[k, col[g.ids[j]]] = True
    return vis, float(center_az_deg)


def inject_code_bias(
    batch: ObsBatch,
    bias_m: float,
    n_sats: int,
    epochs: slice,
    seed: int = 0,
) -> tuple[ObsBatch, tuple[str, ...]]:
    """``bias_m`` added to every code of ``n_sats`` satellites over ``epochs``.

    The satellites are drawn (``numpy.random.default_rng(seed)``) among those with code in
    every epoch of the stretch. Returns the new batch and the satellites hit.
    """
    code = np.array(batch.code_m, copy=True)
    stretch = code[epochs]
    full = np.flatnonzero(np.all(np.isfinite(stretch).any(axis=2), axis=0))
    if full.size < n_sats:
        raise InputError(f"code bias: only {full.size} satellites have code over the stretch, {n_sats} asked")
    hit = np.sort(np.random.default_rng(seed).choice(full, n_sats, replace=False))
    rows = np.arange(len(batch))[epochs]
    code[np.ix_(rows, hit)] += bias_m
    return replace(batch, code_m=code), tuple(batch.tx_ids[i] for i in hit)


# ---------------------------------------------------------------------- ranges
def rtk_range_link(
    a_obs: ObsBatch | PathLike,
    b_obs: ObsBatch | PathLike,
    nav: NavData | EphemerisSource | PathLike | Sequence[PathLike],
    *,
    a: str = "node1",
    b: str = "node2",
    b_pos_m: FloatArray | None = None,
    session: bool = False,
    freqs: str = "L1+L2",
    elev_mask_deg: float = 15.0,
) -> tuple[RangeLink, dict[str, object]]:
    """The range between two receivers from our DD carrier-phase RTK (``a`` rover, ``b`` base).

    ``b_pos_m`` surveyed: fixed base there; None: moving base (the base at its own
    single-point solution each epoch; the baseline vector is what RTK resolves, its length is
    the range). Per epoch ``r = |p_a − p_b|``, ``var = uᵀ C u`` with ``u`` the baseline unit
    vector and ``C`` the rover covariance (fixed and float epochs; others absent).
    ``session`` (static nodes): one value, the median over the fixed epochs (all solved ones
    when none is fixed), variance ``max(median var, (1.4826 MAD)²)``.

    Returns
    -------
    RangeLink, info (fix counts, statuses)
    """
    eph = nav_source(nav)
    cfg = rtk_gnss_config(freqs=freqs, elev_mask_deg=elev_mask_deg)
    b_full = load_obs(b_obs, None)
    track: PositionSource | None = None
    if b_pos_m is None:
        cfg = cfg.updated(base_position="moving")
        track = own_solution_track(b_full, eph, elev_mask_deg)
    res = solve_rtk(a_obs, b_full, eph, None if b_pos_m is None else np.asarray(b_pos_m, float), cfg)
    t, r, v, fixed = [], [], [], []
    for s in res.solutions:
        if s.status not in ("fixed", "partial", "float") or not np.all(np.isfinite(s.pos_m)):
            continue
        pb = np.asarray(b_pos_m, float) if track is None else np.asarray(track.position(s.t_s), float)
        if not np.all(np.isfinite(pb)):
            continue
        d = np.asarray(s.pos_m, float) - pb
        rng_m = float(np.linalg.norm(d))
        u = d / rng_m
        t.append(s.t_s)
        r.append(rng_m)
        v.append(float(u @ np.asarray(s.cov_m2, float) @ u))
        fixed.append(s.status == "fixed")
    if not t:
        raise InputError("range from RTK: no epoch with an RTK solution between the two receivers")
    ta, ra, va, fa = np.array(t), np.array(r), np.array(v), np.array(fixed)
    info: dict[str, object] = {"rtk_epochs": int(ta.size), "rtk_fixed": int(fa.sum())}
    if session:
        sel = fa if fa.any() else np.ones(fa.size, bool)
        med = float(np.median(ra[sel]))
        mad = 1.4826 * float(np.median(np.abs(ra[sel] - med)))
        var = max(float(np.median(va[sel])), mad**2, 1e-8)
        info["session_range_m"] = med
        return RangeLink.constant(a, b, med, np.sqrt(var)), info
    return RangeLink(a, b, ta, ra, np.maximum(va, 1e-8)), info


def read_range_file(path: PathLike, a: str, b: str, default_sigma_m: float = 0.05) -> RangeLink:
    """A range series: lines ``gpst_s range_m [sigma_m]`` (spaces or commas; ``#`` comments).

    Raises
    ------
    InputError
        Naming the file and line of a malformed row, a non-positive range or σ, or
        non-increasing times.
    """
    p = os.fspath(path)
    try:
        with open(p, encoding="utf-8") as fh:
            lines = fh.read().splitlines()
    except OSError as exc:
        raise InputError(f"cannot read the range file ({exc.strerror or exc})", p) from None
    except UnicodeDecodeError:
        raise InputError("range file is not text (expected lines 'gpst_s range_m [sigma_m]')", p) from None
    t: list[float] = []
    r: list[float] = []
    s: list[float] = []
    for n, line in enumerate(lines, 1):
        body = line.split("#", 1)[0].replace(",", " ").split()
        if not body:
            continue
        if len(body) not in (2, 3):
            raise InputError(f"expected 'gpst_s range_m [sigma_m]', got {len(body)} fields", p, n)
        try:
            vals = [float(x) for x in body]
        except ValueError:
            raise InputError(
                f"expected numbers 'gpst_s range_m [sigma_m]', got {line.strip()!r}", p, n
            ) from None
        sig = vals[2] if len(vals) == 3 else default_sigma_m
        if not (np.isfinite(vals[0]) and vals[1] > 0 and sig > 0):
            raise InputError("range_m and sigma_m must be positive, gpst_s finite", p, n)
        if t and vals[0] <= t[-1]:
            raise InputError(f"gpst_s must increase (after {t[-1]})", p, n)
        t.append(vals[0])
        r.append(vals[1])
        s.append(sig)
    if not t:
        raise InputError("range file has no rows (expected lines 'gpst_s range_m [sigma_m]')", p)
    return RangeLink(a, b, np.array(t), np.array(r), np.array(s) ** 2)


# ---------------------------------------------------------------------- node machinery
@dataclass
class _NodeRuntime:
    name: str
    b1: ObsBatch
    visible: BoolArray | None
    systems: tuple[str, ...]
    layout: StateLayout
    filt: NodeFilter
    belief: Belief | None = None
    last_t: float = float("nan")


def _systems_of(b1: ObsBatch, eph: EphemerisSource, wanted: str) -> tuple[str, ...]:
    return tuple(s for s in sorted(set(b1.system)) if s in wanted.upper() and eph.nav.n_records(s) > 0)


def _geometry(rt: _NodeRuntime, k: int, eph: EphemerisSource) -> tuple[EpochGeometry, BoolArray]:
    g = epoch_geometry(rt.b1, k, eph)
    idx = np.flatnonzero(np.isfinite(rt.b1.code_m[k, :, 0]))
    use = np.ones(idx.size, bool)
    if rt.visible is not None:
        use = rt.visible[k, idx]
    return g, use


def _approx(batch: ObsBatch) -> FloatArray | None:
    p = batch.approx_pos_m
    if p is None:
        return None
    a = np.asarray(p, float)
    if a.shape == (3,) and np.all(np.isfinite(a)) and 6.2e6 < float(np.linalg.norm(a)) < 6.6e6:
        return a
    return None


def _n_unknowns(pr: PseudorangeModel, extra_rows: int) -> tuple[int, int]:
    return int(pr.z.size) + extra_rows, 3 + len(set(pr.clk_index.tolist()))


def _node_rows(
    rt: _NodeRuntime,
    t: float,
    g: EpochGeometry,
    use: BoolArray,
    guess: FloatArray,
    eph: EphemerisSource,
    cfg: CoopSettings,
    ranges: list[RangeObservation],
    broadcasts: dict[str, PeerBroadcast],
    windows: dict[str, PeerWindow],
    cooperation: str,
    dt_s: float,
) -> tuple[PseudorangeModel, StackedModel, int]:
    clk = {s: rt.layout.slice("clk").start + i for i, s in enumerate(rt.systems)}
    pr = node_pseudoranges(
        t,
        g,
        use,
        guess,
        eph.nav,
        clk,
        pos_start=0,
        n_state=rt.layout.size,
        sigma0_m=cfg.code_sigma_m,
        cn0_ref_dbhz=cfg.cn0_ref_dbhz,
        use_cn0=cfg.use_cn0,
        elev_mask_deg=cfg.elev_mask_deg,
        tropo=cfg.tropo,
        iono=cfg.iono,
    )
    rm = peer_range_model(
        ranges, broadcasts, cooperation, cfg.filter, windows, pos_start=0, n_state=rt.layout.size, dt_s=dt_s
    )
    return pr, StackedModel((pr, rm)), int(rm.z.size)


def _init_lsq(
    rt: _NodeRuntime,
    t: float,
    g: EpochGeometry,
    use: BoolArray,
    start: FloatArray,
    eph: EphemerisSource,
    cfg: CoopSettings,
    ranges: list[RangeObservation],
    broadcasts: dict[str, PeerBroadcast],
) -> GaussianState | None:
    x: FloatArray = np.zeros(rt.layout.size)
    x[:3] = start
    res = None
    for _ in range(3):
        pr, rows, nr = _node_rows(rt, t, g, use, x[:3], eph, cfg, ranges, broadcasts, {}, "traditional", 1.0)
        m, n_unk = _n_unknowns(pr, nr)
        if m < n_unk or pr.z.size == 0:
            return None
        H = rows.jacobian(x)
        cols = np.flatnonzero(np.any(H != 0.0, axis=0))
        res = gauss_newton(rows, x, cols=cols, t_s=t, layout=rt.layout)
        if not res.ok:
            return None
        x = res.state.x
    if res is None or not 6.2e6 < float(np.linalg.norm(x[:3])) < 6.6e6:
        return None
    P = np.array(res.state.P, copy=True)
    for i in range(rt.layout.size):
        if P[i, i] <= 0.0:
            P[i, i] = (cfg.sigma_clk_m_s * 30.0) ** 2  # a clock no row saw: free
    P[:3, :3] += np.eye(3) * cfg.init_floor_m**2
    return GaussianState(x, P, t, rt.layout)


def _make_filter(cfg: CoopSettings, layout: StateLayout, seed: int) -> NodeFilter:
    clk = layout.slice("clk")
    if cfg.filter in ("ekf", "ukf"):
        return make_node_filter(cfg.filter, alpha=cfg.ukf_alpha, beta=cfg.ukf_beta)
    if cfg.filter == "pf":
        return make_node_filter(
            "pf",
            n_particles=cfg.n_particles,
            ess_threshold=cfg.ess_threshold,
            roughening=cfg.roughening,
            seed=seed,
            linear_idx=tuple(range(clk.start, clk.stop)),
        )
    return make_node_filter("ls")


def _common_epochs(nodes: Sequence[CoopNode]) -> list[ObsBatch]:
    if not nodes:
        raise InputError("cooperative positioning needs at least one node")
    ref = nodes[0].batch
    out = [ref]
    for nd in nodes[1:]:
        al = align_base(ref, nd.batch)
        if len(al) != len(ref):
            raise InputError(f"node {nd.name}: epochs do not match node {nodes[0].name}'s (within 0.5 s)")
        out.append(al)
    return out


def _aligned_visible(nd: CoopNode, aligned: ObsBatch) -> BoolArray | None:
    if nd.visible is None:
        return None
    if nd.visible.shape[0] == len(aligned):
        return nd.visible
    # re-index to the aligned epochs (nearest original epoch)
    j = np.array([int(np.argmin(np.abs(nd.batch.t_s - t))) for t in aligned.t_s])
    return nd.visible[j]


def _band1_visible(batch: ObsBatch, b1: ObsBatch, visible: BoolArray | None) -> BoolArray | None:
    if visible is None:
        return None
    col = {t: i for i, t in enumerate(batch.tx_ids)}
    return visible[:, [col[t] for t in b1.tx_ids]]


# ---------------------------------------------------------------------- peer to peer
def solve_coop(
    nodes: Sequence[CoopNode],
    links: Sequence[RangeLink],
    nav: NavData | EphemerisSource | PathLike | Sequence[PathLike],
    cfg: CoopSettings | None = None,
) -> CoopResult:
    """Peer-to-peer cooperative positioning: every node its own filter (module notes).

    Parameters
    ----------
    nodes : sequence of CoopNode
        Epochs are those of the first node; the others are matched within 0.5 s.
    links : sequence of RangeLink
        Measured inter-node ranges (each used by both of its nodes).
    nav : navigation data or paths
    cfg : CoopSettings, optional

    Returns
    -------
    CoopResult
    """
    cfg = cfg or CoopSettings()
    eph = nav_source(nav)
    batches = _common_epochs(nodes)
    names = tuple(n.name for n in nodes)
    if len(set(names)) != len(names):
        raise InputError(f"node names must differ, got {', '.join(names)}")
    for lk in links:
        for nm in (lk.a, lk.b):
            if nm not in names:
                raise InputError(f"range link names node {nm!r}, not among {', '.join(names)}")
    proc = LocationTimeModel(sigma_pos_m_s=cfg.sigma_pos_m_s, sigma_clk_m_s=cfg.sigma_clk_m_s)
    rts: list[_NodeRuntime] = []
    for i, (nd, bt) in enumerate(zip(nodes, batches, strict=True)):
        b1 = select_band1(bt)
        systems = _systems_of(b1, eph, cfg.systems)
        if not systems:
            raise InputError(f"node {nd.name}: no code of systems {cfg.systems} with broadcast ephemerides")
        lay = node_layout(len(systems))
        vis = _band1_visible(bt, b1, _aligned_visible(nd, bt))
        rts.append(_NodeRuntime(nd.name, b1, vis, systems, lay, _make_filter(cfg, lay, cfg.seed + i)))
    broadcasts: dict[str, PeerBroadcast] = {}
    windows: dict[tuple[str, str], PeerWindow] = {
        (me, peer): PeerWindow(cfg.reset) for me in names for peer in names if me != peer
    }
    epochs: dict[str, list[NodeEpoch]] = {n: [] for n in names}
    T = len(batches[0])
    jit.begin_run(T)  # pure kernels until the compiled ones pay (algorithms.md §27)
    for k in range(T):
        if k:
            jit.end_epoch()
        t = float(batches[0].t_s[k])
        for rt in rts:
            ranges = []
            for lk in links:
                if rt.name in (lk.a, lk.b):
                    r, v = lk.at(t)
                    ranges.append(RangeObservation(lk.b if lk.a == rt.name else lk.a, r, v))
            fresh = {
                p: b for p, b in broadcasts.items() if p != rt.name and t - b.t_s <= cfg.max_broadcast_age_s
            }
            if cfg.cooperation == "off":
                fresh = {}
            my_windows = {p: windows[(rt.name, p)] for p in fresh}
            epochs[rt.name].append(_node_epoch(rt, k, t, eph, cfg, proc, ranges, fresh, my_windows))
            last = epochs[rt.name][-1]
            if last.solved and rt.belief is not None:
                bc = PeerBroadcast.of(rt.name, rt.filt.summary(rt.belief))
                broadcasts[rt.name] = bc
                for other in names:
                    if other != rt.name:
                        windows[(other, rt.name)].push(bc)
    return CoopResult(names, epochs, cfg, {"systems": {rt.name: rt.systems for rt in rts}})


def _node_epoch(
    rt: _NodeRuntime,
    k: int,
    t: float,
    eph: EphemerisSource,
    cfg: CoopSettings,
    proc: LocationTimeModel,
    ranges: list[RangeObservation],
    broadcasts: dict[str, PeerBroadcast],
    windows: dict[str, PeerWindow],
) -> NodeEpoch:
    g, use = _geometry(rt, k, eph)
    nan3 = np.full(3, np.nan)
    nan33 = np.full((3, 3), np.nan)
    if rt.belief is None:
        start = _approx(rt.b1)
        if start is None and broadcasts:
            start = next(iter(broadcasts.values())).pos_ecef_m + np.array([0.0, 0.0, 100.0])
        if start is None:
            start = np.zeros(3)
        init = _init_lsq(rt, t, g, use, start, eph, cfg, ranges, broadcasts)
        if init is None:
            return NodeEpoch(t, nan3, nan33, False, 0, 0)
        rt.belief = rt.filt.init(init)
        rt.last_t = t
        s = rt.filt.summary(rt.belief)
        pr, rows, nr = _node_rows(
            rt, t, g, use, s.x[:3], eph, cfg, ranges, broadcasts, windows, "traditional", 0.0
        )
        return NodeEpoch(
            t,
            s.x[:3].copy(),
            s.P[:3, :3].copy(),
            True,
            int(pr.z.size),
            nr,
            trace_p_m2=float(np.trace(s.P[:3, :3])),
        )
    dt = t - rt.last_t
    prior = rt.filt.predict(rt.belief, proc, t)
    guess = rt.filt.summary(prior).x[:3]
    coop = cfg.cooperation if cfg.cooperation != "off" else "traditional"
    pr, rows, nr = _node_rows(rt, t, g, use, guess, eph, cfg, ranges, broadcasts, windows, coop, dt)
    if cfg.cooperation == "off":
        nr = 0
        rows = StackedModel((pr,))
    step = rt.filt.update(prior, rows)
    m, n_unk = _n_unknowns(pr, nr)
    solved = bool(step.ok and m >= n_unk and pr.z.size > 0)
    rt.belief = step.belief if step.ok else prior
    rt.last_t = t
    s = step.summary if step.ok else rt.filt.summary(prior)
    rres = rsig = float("nan")
    if nr:
        j = pr.z.size
        rres = float(step.innovation[j]) if step.innovation.size > j else float("nan")
        rsig = float(np.sqrt(rows.R[j, j]))
    pos = s.x[:3].copy()
    return NodeEpoch(
        t,
        pos if solved else nan3,
        s.P[:3, :3].copy(),
        solved,
        int(pr.z.size),
        nr,
        rres,
        rsig,
        float(np.trace(s.P[:3, :3])),
        step.ess,
    )


# ---------------------------------------------------------------------- centralised
@dataclass(frozen=True)
class JointLocationTime:
    """Eq. 8 for the stacked states of several nodes (block-diagonal ``F``, ``W``, ``Q̃``)."""

    node_layouts: tuple[StateLayout, ...]
    model: LocationTimeModel
    name: str = "joint-location-time"

    def blocks(self) -> tuple[tuple[str, int], ...]:
        return (("x", sum(lay.size for lay in self.node_layouts)),)

    def _blocks(self, dt_s: float, which: int) -> tuple[FloatArray, FloatArray]:
        n = sum(lay.size for lay in self.node_layouts)
        A = np.zeros((n, n))
        B = np.zeros((n, n))
        i = 0
        for lay in self.node_layouts:
            if which == 0:
                a, b = self.model.transition(lay, dt_s)
            else:
                a, b = self.model.noise_input(lay, dt_s)
            A[i : i + lay.size, i : i + lay.size] = a
            B[i : i + lay.size, i : i + lay.size] = b
            i += lay.size
        return A, B

    def transition(self, layout: StateLayout, dt_s: float) -> tuple[FloatArray, FloatArray]:
        return self._blocks(dt_s, 0)

    def noise_input(self, layout: StateLayout, dt_s: float) -> tuple[FloatArray, FloatArray]:
        return self._blocks(dt_s, 1)


def solve_coop_central(
    nodes: Sequence[CoopNode],
    links: Sequence[RangeLink],
    nav: NavData | EphemerisSource | PathLike | Sequence[PathLike],
    cfg: CoopSettings | None = None,
) -> CoopResult:
    """The centralised reference: one joint filter over all nodes (module notes).

    Uses ``cfg.filter`` on the joint state ``[x_1, …, x_N]`` with every node's pseudoranges
    and every link as an :class:`~robustrtk.measurement.coop.InterNodeRangeModel` row (its
    measured variance; ``cooperation`` ``off`` drops the links). Starts at the first epoch
    where the joint least squares is determined. A node's epoch is solved when the joint
    rows are at least the joint unknowns they touch.
    """
    cfg = cfg or CoopSettings()
    eph = nav_source(nav)
    batches = _common_epochs(nodes)
    names = tuple(n.name for n in nodes)
    index = {n: i for i, n in enumerate(names)}
    b1s, systems, lays, vis = [], [], [], []
    for nd, bt in zip(nodes, batches, strict=True):
        b1 = select_band1(bt)
        b1s.append(b1)
        sy = _systems_of(b1, eph, cfg.systems)
        systems.append(sy)
        lays.append(node_layout(len(sy)))
        vis.append(_band1_visible(bt, b1, _aligned_visible(nd, bt)))
    offs = np.cumsum([0] + [lay.size for lay in lays])
    n_all = int(offs[-1])
    joint = StateLayout(blocks=(("x", n_all),))
    proc = JointLocationTime(tuple(lays), LocationTimeModel(cfg.sigma_pos_m_s, cfg.sigma_clk_m_s))
    lin = tuple(int(offs[i]) + j for i, lay in enumerate(lays) for j in range(3, lay.size))
    if cfg.filter == "pf":
        filt: NodeFilter = make_node_filter(
            "pf",
            n_particles=cfg.n_particles,
            ess_threshold=cfg.ess_threshold,
            roughening=cfg.roughening,
            seed=cfg.seed,
            linear_idx=lin,
        )
    elif cfg.filter in ("ekf", "ukf"):
        filt = make_node_filter(cfg.filter, alpha=cfg.ukf_alpha, beta=cfg.ukf_beta)
    else:
        filt = make_node_filter("ls")
    belief: Belief | None = None
    last_t = float("nan")
    epochs: dict[str, list[NodeEpoch]] = {n: [] for n in names}
    x_guess = np.zeros(n_all)
    for i, b1 in enumerate(b1s):
        a = _approx(b1)
        x_guess[offs[i] : offs[i] + 3] = a if a is not None else 0.0
    T = len(batches[0])
    jit.begin_run(T)  # pure kernels until the compiled ones pay (algorithms.md §27)
    for k in range(T):
        if k:
            jit.end_epoch()
        t = float(batches[0].t_s[k])
        guess = x_guess if belief is None else filt.summary(belief).x
        parts: list[PseudorangeModel | InterNodeRangeModel] = []
        prs: list[PseudorangeModel] = []
        for i, b1 in enumerate(b1s):
            g = epoch_geometry(b1, k, eph)
            idx = np.flatnonzero(np.isfinite(b1.code_m[k, :, 0]))
            vi = vis[i]
            use = np.ones(idx.size, bool) if vi is None else vi[k, idx]
            clk = {s: int(offs[i]) + 3 + q for q, s in enumerate(systems[i])}
            pr = node_pseudoranges(
                t,
                g,
                use,
                guess[offs[i] : offs[i] + 3],
                eph.nav,
                clk,
                pos_start=int(offs[i]),
                n_state=n_all,
                sigma0_m=cfg.code_sigma_m,
                cn0_ref_dbhz=cfg.cn0_ref_dbhz,
                use_cn0=cfg.use_cn0,
                elev_mask_deg=cfg.elev_mask_deg,
                tropo=cfg.tropo,
                iono=cfg.iono,
            )
            prs.append(pr)
            parts.append(pr)
        link_rows: list[tuple[int, int, float, float]] = []
        if cfg.cooperation != "off":
            for lk in links:
                r, v = lk.at(t)
                if np.isfinite(r) and np.isfinite(v):
                    link_rows.append((index[lk.a], index[lk.b], r, v))
        if link_rows:
            parts.append(
                InterNodeRangeModel(
                    z=np.array([q[2] for q in link_rows]),
                    var_m2=np.array([q[3] for q in link_rows]),
                    pos_a=np.array([int(offs[q[0]]) for q in link_rows], dtype=np.int64),
                    pos_b=np.array([int(offs[q[1]]) for q in link_rows], dtype=np.int64),
                    n_state=n_all,
                    labels=tuple(f"range:{names[q[0]]}-{names[q[1]]}" for q in link_rows),
                )
            )
        rows = StackedModel(tuple(parts))
        solved_nodes = _joint_solved(prs, link_rows, len(names))
        step_ok = False
        if belief is None:
            if any(solved_nodes):
                H = rows.jacobian(guess)
                cols = np.flatnonzero(np.any(H != 0.0, axis=0))
                res = gauss_newton(rows, guess, cols=cols, t_s=t, layout=joint)
                if res.ok:
                    res2 = gauss_newton(rows, res.state.x, cols=cols, t_s=t, layout=joint)
                    P = np.array(res2.state.P, copy=True)
                    for q in range(n_all):
                        if P[q, q] <= 0.0:
                            P[q, q] = (cfg.sigma_clk_m_s * 30.0) ** 2 if q in lin else 1e6
                    for i in range(len(names)):
                        s0 = int(offs[i])
                        P[s0 : s0 + 3, s0 : s0 + 3] += np.eye(3) * cfg.init_floor_m**2
                    belief = filt.init(GaussianState(res2.state.x, P, t, joint))
                    step_ok = True
        else:
            prior = filt.predict(belief, proc, t)
            step = filt.update(prior, rows)
            belief = step.belief if step.ok else prior
            step_ok = step.ok
        last_t = t
        s = filt.summary(belief) if belief is not None else None
        for i, nm in enumerate(names):
            solved = bool(step_ok and solved_nodes[i] and s is not None)
            if s is None:
                epochs[nm].append(NodeEpoch(t, np.full(3, np.nan), np.full((3, 3), np.nan), False, 0, 0))
                continue
            sl = slice(int(offs[i]), int(offs[i]) + 3)
            pos = s.x[sl].copy()
            nr = sum(1 for q in link_rows if i in (q[0], q[1]))
            epochs[nm].append(
                NodeEpoch(
                    t,
                    pos if solved else np.full(3, np.nan),
                    s.P[sl, sl].copy(),
                    solved,
                    int(prs[i].z.size),
                    nr,
                    trace_p_m2=float(np.trace(s.P[sl, sl])),
                )
            )
    del last_t
    return CoopResult(
        names, epochs, cfg, {"central": True, "systems": dict(zip(names, systems, strict=True))}
    )


def _joint_solved(
    prs: list[PseudorangeModel], links: list[tuple[int, int, float, float]], n: int
) -> list[bool]:
    """Node by node: own rows plus ranges to nodes that are themselves determined cover its
    unknowns (iterated, so a node solved only through a solved peer counts)."""
    own = [_n_unknowns(p, 0) for p in prs]
    solved = [m >= u and p.z.size > 0 for (m, u), p in zip(own, prs, strict=True)]
    changed = True
    while changed:
        changed = False
        for i in range(n):
            if solved[i] or prs[i].z.size == 0:
                continue
            extra = sum(1 for a, b, _, _ in links if (a == i and solved[b]) or (b == i and solved[a]))
            m, u = own[i]
            if m + extra >= u:
                solved[i] = True
                changed = True
    return solved


# ---------------------------------------------------------------------- evaluation helpers
def horizontal_errors(pos_ecef_m: npt.ArrayLike, truth_ecef_m: npt.ArrayLike) -> FloatArray:
    """Horizontal error (m) of each row of ``pos_ecef_m`` against ``truth_ecef_m`` (NaN kept)."""
    p = np.asarray(pos_ecef_m, float).reshape(-1, 3)
    tr = np.asarray(truth_ecef_m, float)
    lat, lon, _ = ecef2geodetic(tr)
    enu = (p - tr) @ ecef2enu_rotation(float(lat), float(lon)).T
    out: FloatArray = np.hypot(enu[:, 0], enu[:, 1])
    return out


def load_node(name: str, obs: ObsBatch | PathLike, visible: BoolArray | None = None) -> CoopNode:
    """A :class:`CoopNode` from a file (all systems) or a batch."""
    return CoopNode(name, load_obs(obs, None), visible)


__all__ = [
    "CoopNode",
    "CoopResult",
    "CoopSettings",
    "JointLocationTime",
    "NodeEpoch",
    "RangeLink",
    "horizontal_errors",
    "inject_code_bias",
    "load_node",
    "read_range_file",
    "rtk_range_link",
    "solve_coop",
    "solve_coop_central",
    "windowsill_mask",
]
