"""The epoch loops of cooperative positioning of N receivers (Zhou et al. 2018;
algorithms.md §21).

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

Inter-node ranges are :class:`~robustrtk.pipeline.coop.types.RangeLink` series
(:mod:`robustrtk.pipeline.coop.links`).

A node's epoch is *solved* when its rows of that epoch (own pseudoranges and ranges to
peers with a usable broadcast) are at least as many as the unknowns they touch
(``3 + clocks seen``) and the correction succeeded; an unsolved epoch is reported with
status ``none``. A filter starts at the first epoch at which a least-squares solution of
the node's rows (traditional range variance) exists.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from robustrtk.core import BoolArray, FloatArray, InputError, ObsBatch
from robustrtk.estimation.coop import (
    Belief,
    LocationTimeModel,
    NodeFilter,
    PeerBroadcast,
    PeerWindow,
    RangeObservation,
    gauss_newton,
    make_node_filter,
    node_layout,
    peer_range_model,
)
from robustrtk.estimation.state import GaussianState, StateLayout
from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.io.rinex_nav import NavData
from robustrtk.measurement.coop import InterNodeRangeModel, PseudorangeModel, node_pseudoranges
from robustrtk.measurement.dd import StackedModel
from robustrtk.measurement.undifferenced import EpochGeometry, epoch_geometry
from robustrtk.pipeline.coop.types import CoopNode, CoopResult, CoopSettings, NodeEpoch, PathLike, RangeLink
from robustrtk.pipeline.gnss import align_base, nav_source
from robustrtk.pipeline.spp_common import select_band1


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
    for k in range(T):
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
    for k in range(T):
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


__all__ = ["JointLocationTime", "solve_coop", "solve_coop_central"]
