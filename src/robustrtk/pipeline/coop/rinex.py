"""Cooperative positioning of N receivers on RINEX input (Zhou et al. 2018; algorithms.md §21):
each node's band-1 pseudoranges from its file and the broadcast ephemerides
(:class:`RinexNode`, a :class:`~robustrtk.pipeline.coop.loops.NodeSource`), the measured
ranges of the :class:`~robustrtk.pipeline.coop.types.RangeLink` series, and the
peer-to-peer loop (:func:`robustrtk.pipeline.coop.loops.peer_to_peer`) in :func:`solve_coop`.

A node's filter starts at the first epoch at which a least-squares solution of its rows
(pseudoranges and ranges to peers with a usable broadcast, traditional range variance)
exists, from the file's approximate position (else 100 m above a peer's broadcast, else the
Earth's centre).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from robustrtk.core import BoolArray, FloatArray, InputError, ObsBatch
from robustrtk.estimation.coop import (
    LocationTimeModel,
    LsqResult,
    NodeFilter,
    PeerBroadcast,
    RangeObservation,
    gauss_newton,
    make_node_filter,
    node_layout,
    peer_range_model,
)
from robustrtk.estimation.state import GaussianState, StateLayout
from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.io.rinex_nav import NavData
from robustrtk.measurement.base_propagation import propagate_base_epoch
from robustrtk.measurement.coop import NodeRows, PseudorangeModel, node_pseudoranges
from robustrtk.measurement.undifferenced import EpochGeometry, epoch_geometry
from robustrtk.pipeline.base_buffer import pair_base_epochs
from robustrtk.pipeline.base_position import first_fix_position
from robustrtk.pipeline.config import COOP_PRESET, Config
from robustrtk.pipeline.coop.loops import LoopNode, NodeStart, PeerNetwork, n_unknowns, peer_to_peer
from robustrtk.pipeline.coop.types import (
    CoopNode,
    CoopResult,
    PathLike,
    RangeLink,
    coop_systems,
    reset_settings,
)
from robustrtk.pipeline.gnss import align_base
from robustrtk.pipeline.gnss_inputs import nav_source
from robustrtk.pipeline.spp_common import select_band1


@dataclass
class RinexNode:
    """One receiver's rows from its file (band 1) and the broadcast ephemerides.

    Attributes
    ----------
    b1 : ObsBatch
        The band-1 observations on the common epochs.
    visible : ndarray of bool, shape (T, N), or None
        Satellites of ``b1`` the node may use per epoch.
    systems : tuple of str
        Systems whose clocks the state holds, in state order.
    layout : StateLayout
    eph : EphemerisSource
    cfg : Config
    """

    b1: ObsBatch
    visible: BoolArray | None
    systems: tuple[str, ...]
    layout: StateLayout
    eph: EphemerisSource
    cfg: Config
    _geom: dict[int, tuple[EpochGeometry, BoolArray]] = field(default_factory=dict, repr=False)

    def geometry(self, k: int) -> tuple[EpochGeometry, BoolArray]:
        """Epoch ``k``'s geometry and the satellites the node may use (kept for the epoch)."""
        got = self._geom.get(k)
        if got is None:
            self._geom.clear()
            g = epoch_geometry(self.b1, k, self.eph)
            idx = np.flatnonzero(np.isfinite(self.b1.code_m[k, :, 0]))
            use = np.ones(idx.size, bool) if self.visible is None else self.visible[k, idx]
            got = self._geom[k] = (g, use)
        return got

    def pseudoranges(self, k: int, t_s: float, guess_ecef_m: FloatArray) -> PseudorangeModel:
        g, use = self.geometry(k)
        cfg = self.cfg
        clk = {s: self.layout.slice("clk").start + i for i, s in enumerate(self.systems)}
        return node_pseudoranges(
            t_s,
            g,
            use,
            guess_ecef_m,
            self.eph.nav,
            clk,
            pos_start=0,
            n_state=self.layout.size,
            **code_row_settings(cfg),
        )

    def _rows(
        self,
        k: int,
        t_s: float,
        guess_ecef_m: FloatArray,
        ranges: list[RangeObservation],
        broadcasts: dict[str, PeerBroadcast],
    ) -> tuple[PseudorangeModel, NodeRows, int]:
        pr = self.pseudoranges(k, t_s, guess_ecef_m)
        rm = peer_range_model(
            ranges, broadcasts, "traditional", self.cfg.coop.filter, {}, n_state=self.layout.size, dt_s=1.0
        )
        return pr, NodeRows(pr, rm), int(rm.z.size)

    def start(
        self, k: int, t_s: float, ranges: list[RangeObservation], broadcasts: dict[str, PeerBroadcast]
    ) -> NodeStart | None:
        """Weighted least squares of the epoch's rows (three Gauss–Newton passes, rows rebuilt
        at each), its covariance plus ``init_floor_m²`` on the position. When that fails and
        the node's own rows are fewer than its unknowns, a ranged peer that has broadcast
        starts it, as the zhou2018 study's nodes start: one range above the peer (radially),
        position σ = range + floor, its clocks set from its own rows but free; the epoch's rows
        then update that prior as any later epoch's. (Own rows plus one range of a few metres
        are exactly as many as the unknowns; the range's sphere need not meet the
        pseudoranges' solution curve, and Gauss–Newton then does not converge.)"""
        start = _approx(self.b1)
        if start is None and broadcasts:
            start = next(iter(broadcasts.values())).pos_ecef_m + np.array([0.0, 0.0, 100.0])
        if start is None:
            start = np.zeros(3)
        got = self._least_squares(k, t_s, start, ranges, broadcasts)
        if got is None:
            return self._start_at_peer(k, t_s, ranges, broadcasts)
        x, res = got
        c = self.cfg.coop
        P = np.array(res.state.P, copy=True)
        for i in range(self.layout.size):
            if P[i, i] <= 0.0:
                P[i, i] = (c.sigma_clk_m_s * 30.0) ** 2  # a clock no row saw: free
        P[:3, :3] += np.eye(3) * c.init_floor_m**2
        state = GaussianState(x, P, t_s, self.layout)
        pr, _, nr = self._rows(k, t_s, x[:3], ranges, broadcasts)
        return NodeStart(state, True, int(pr.z.size), nr)

    def _start_at_peer(
        self, k: int, t_s: float, ranges: list[RangeObservation], broadcasts: dict[str, PeerBroadcast]
    ) -> NodeStart | None:
        """The start one range above a ranged peer's broadcast (:meth:`start`), or None."""
        for obs in ranges:
            peer = broadcasts.get(obs.peer)
            if peer is None or not np.isfinite(obs.range_m) or obs.range_m < 0.0:
                continue
            p = np.asarray(peer.pos_ecef_m, float)
            x: FloatArray = np.zeros(self.layout.size)
            x[:3] = p + obs.range_m * p / np.linalg.norm(p)
            pr = self.pseudoranges(k, t_s, x[:3])
            clocks = sorted(set(pr.clk_index.tolist()))
            if pr.z.size >= n_unknowns(pr, 0)[1] or pr.z.size < len(clocks) or not clocks:
                return None  # determined alone (its least squares failed), or no clock to solve
            res = gauss_newton(pr, x, cols=np.asarray(clocks, dtype=np.int64), t_s=t_s, layout=self.layout)
            if not res.ok:
                return None
            c = self.cfg.coop
            # a prior only (the clocks free): the epoch's rows update it once, as any epoch's
            P = np.eye(self.layout.size) * (c.sigma_clk_m_s * 30.0) ** 2
            P[:3, :3] = np.eye(3) * (obs.range_m + c.init_floor_m) ** 2
            state = GaussianState(res.state.x, P, t_s, self.layout)
            return NodeStart(state, False, int(pr.z.size), 0, update=True)
        return None

    def _least_squares(
        self,
        k: int,
        t_s: float,
        start: FloatArray,
        ranges: list[RangeObservation],
        broadcasts: dict[str, PeerBroadcast],
    ) -> tuple[FloatArray, LsqResult] | None:
        """Three Gauss–Newton passes from ``start`` (ECEF m), rows rebuilt at each: the state
        and the last pass, or None (too few rows, no convergence, off the Earth's surface)."""
        x: FloatArray = np.zeros(self.layout.size)
        x[:3] = start
        res = None
        for _ in range(3):
            pr, rows, nr = self._rows(k, t_s, x[:3], ranges, broadcasts)
            m, n_unk = n_unknowns(pr, nr)
            if m < n_unk or pr.z.size == 0:
                return None
            H = rows.jacobian(x)
            cols = np.flatnonzero(np.any(H != 0.0, axis=0))
            res = gauss_newton(rows, x, cols=cols, t_s=t_s, layout=self.layout)
            if not res.ok:
                return None
            x = res.state.x
        if res is None or not 6.2e6 < float(np.linalg.norm(x[:3])) < 6.6e6:
            return None
        return x, res


def code_row_settings(cfg: Config) -> dict[str, Any]:
    """The keywords of :func:`~robustrtk.measurement.coop.node_pseudoranges` that ``cfg``
    sets: eq. 25 variance (code σ, C/N0 reference and use), mask, atmosphere."""
    return {
        "sigma0_m": cfg.measurement.code_sigma_m,
        "cn0_ref_dbhz": cfg.spp.cn0_ref_dbhz,
        "use_cn0": cfg.spp.use_cn0,
        "elev_mask_deg": cfg.gnss.elev_mask_deg,
        "tropo": cfg.measurement.tropo,
        "iono": cfg.measurement.iono,
    }


def systems_of(b1: ObsBatch, eph: EphemerisSource, wanted: str) -> tuple[str, ...]:
    """Systems of ``wanted`` that ``b1`` has code of and the ephemerides have orbits of."""
    return tuple(s for s in sorted(set(b1.system)) if s in wanted.upper() and eph.nav.n_records(s) > 0)


def _approx(batch: ObsBatch) -> FloatArray | None:
    p = batch.approx_pos_m
    if p is None:
        return None
    a = np.asarray(p, float)
    if a.shape == (3,) and np.all(np.isfinite(a)) and 6.2e6 < float(np.linalg.norm(a)) < 6.6e6:
        return a
    return None


def approx_position(batch: ObsBatch) -> FloatArray | None:
    """The file's approximate position when it is near the Earth's surface, else None."""
    return _approx(batch)


def make_filter(cfg: Config, linear_idx: tuple[int, ...], seed: int) -> NodeFilter:
    """The ``[coop]`` filter of a node (``linear_idx``: the clocks, the PF's linear part)."""
    kind = cfg.coop.filter
    if kind in ("ekf", "ukf"):
        return make_node_filter(kind, alpha=cfg.estimator.ukf_alpha, beta=cfg.estimator.ukf_beta)
    if kind == "pf":
        c = cfg.coop
        return make_node_filter(
            "pf",
            n_particles=c.n_particles,
            ess_threshold=c.ess_threshold,
            roughening=c.roughening,
            seed=seed,
            linear_idx=linear_idx,
        )
    return make_node_filter("ls")


def paired_epochs(
    t_ref_s: FloatArray,
    batch: ObsBatch,
    eph: EphemerisSource | None,
    max_age_s: float,
    systems: str | None = None,
) -> ObsBatch:
    """``batch`` on the epochs ``t_ref_s`` by the base-epoch rule of
    :mod:`robustrtk.pipeline.base_buffer`: the epoch within 0.5 s as it is, else the latest
    epoch at most ``max_age_s`` older, its code and phase carried to the new tag by the
    satellites' motion seen from the file's approximate position (else its first fix)
    (:func:`robustrtk.measurement.base_propagation.propagate_base_epoch`; a position kilometres
    off changes a few seconds' range change by centimetres). Epochs with no such epoch, or
    needing propagation without a position or ephemerides, are empty (NaN). ``systems``: only
    epochs with code of these systems serve (a base's GLONASS-only epochs do not serve GPS
    nodes)."""
    t_ref = np.asarray(t_ref_s, float)
    T, N, K = t_ref.size, len(batch.tx_ids), len(batch.signals)
    code, phase = np.full((T, N, K), np.nan), np.full((T, N, K), np.nan)
    dop, cn0 = np.full((T, N, K), np.nan), np.full((T, N, K), np.nan)
    lli = np.zeros((T, N, K), np.int8)
    cols = np.array([systems is None or s in systems for s in batch.system], dtype=bool)
    usable: BoolArray | None = (
        np.asarray(np.isfinite(batch.code_m[:, cols]).any(axis=(1, 2))) if len(batch) else None
    )
    pos = approx_position(batch)
    if pos is None and eph is not None and len(batch):  # no header position: the first fix
        pos = first_fix_position(batch, eph, 10.0)
    for pr in pair_base_epochs(t_ref, batch.t_s, 0.5, max_age_s, usable):
        ep = batch.epoch(pr.i_base)
        if not pr.exact:
            if pos is None or eph is None:
                continue
            sig = int(np.argmax(np.isfinite(ep.code_m).sum(axis=0)))
            ep = propagate_base_epoch(
                ep, float(t_ref[pr.i_rover]), eph, pos, sagnac=True, troposphere=True, signal=sig
            )
        i = pr.i_rover
        code[i], phase[i], dop[i], cn0[i], lli[i] = (
            ep.code_m,
            ep.phase_cyc,
            ep.doppler_hz,
            ep.cn0_dbhz,
            ep.lli,
        )
    return replace(
        batch, t_s=t_ref.copy(), code_m=code, phase_cyc=phase, doppler_hz=dop, cn0_dbhz=cn0, lli=lli,
        code_sigma_m=None, phase_sigma_cyc=None,
    )  # fmt: skip


def common_epochs(
    nodes: Sequence[CoopNode],
    eph: EphemerisSource | None = None,
    max_age_s: float = 0.0,
    timeline: str | None = None,
    systems: str | None = None,
) -> list[ObsBatch]:
    """Every node's batch on the epochs of node ``timeline`` (default the first): paired
    within 0.5 s or, with ``max_age_s > 0``, with the node's latest epoch at most that old,
    carried to the timeline's tag (:func:`paired_epochs`, the base-epoch rule of
    :mod:`robustrtk.pipeline.base_buffer`)."""
    if not nodes:
        raise InputError("cooperative positioning needs at least one node")
    names = [nd.name for nd in nodes]
    if timeline is not None and timeline not in names:
        raise InputError(f"timeline node {timeline!r} is not among {', '.join(names)}")
    ref_node = nodes[names.index(timeline)] if timeline is not None else nodes[0]
    ref = ref_node.batch
    out = []
    for nd in nodes:
        if nd is ref_node:
            out.append(ref)
            continue
        if max_age_s > 0:
            al = paired_epochs(ref.t_s, nd.batch, eph, max_age_s, systems)
            if not np.isfinite(al.code_m).any():
                raise InputError(
                    f"node {nd.name}: no epoch within {max_age_s:g} s before node {ref_node.name}'s epochs"
                )
            out.append(al)
            continue
        al = align_base(ref, nd.batch)
        if len(al) != len(ref):
            raise InputError(f"node {nd.name}: epochs do not match node {ref_node.name}'s (within 0.5 s)")
        out.append(al)
    return out


def aligned_visible(nd: CoopNode, aligned: ObsBatch) -> BoolArray | None:
    """The node's visibility mask on the aligned epochs (None: all visible)."""
    if nd.visible is None:
        return None
    if nd.visible.shape[0] == len(aligned):
        return nd.visible
    # re-index to the aligned epochs (nearest original epoch)
    j = np.array([int(np.argmin(np.abs(nd.batch.t_s - t))) for t in aligned.t_s])
    return nd.visible[j]


def band1_visible(batch: ObsBatch, b1: ObsBatch, visible: BoolArray | None) -> BoolArray | None:
    """The mask of ``batch``'s satellites on the columns of its band-1 batch ``b1``."""
    if visible is None:
        return None
    col = {t: i for i, t in enumerate(batch.tx_ids)}
    return visible[:, [col[t] for t in b1.tx_ids]]


def solve_coop(
    nodes: Sequence[CoopNode],
    links: Sequence[RangeLink],
    nav: NavData | EphemerisSource | PathLike | Sequence[PathLike],
    cfg: Config | None = None,
    progress: Callable[[int, int], None] | None = None,
    timeline: str | None = None,
) -> CoopResult:
    """Peer-to-peer cooperative positioning: every node its own filter
    (:func:`~robustrtk.pipeline.coop.loops.peer_to_peer`); ``progress(done, total)`` after
    each epoch of the last node.

    Parameters
    ----------
    nodes : sequence of CoopNode
        Epochs are those of node ``timeline`` (default the first); the others are paired by
        the base-epoch rule within ``cfg.gnss.max_age_s`` (:func:`common_epochs`).
    links : sequence of RangeLink
        Measured inter-node ranges (each used by both of its nodes).
    nav : navigation data or paths
    cfg : Config, optional
        Its ``[coop]`` section and the shared leaves it reads (default
        :data:`~robustrtk.pipeline.config.COOP_PRESET`).

    Returns
    -------
    CoopResult
    """
    cfg = cfg or COOP_PRESET
    eph = nav_source(nav)
    batches = common_epochs(nodes, eph, cfg.gnss.max_age_s, timeline, coop_systems(cfg))
    names = tuple(n.name for n in nodes)
    if len(set(names)) != len(names):
        raise InputError(f"node names must differ, got {', '.join(names)}")
    for lk in links:
        for nm in (lk.a, lk.b):
            if nm not in names:
                raise InputError(f"range link names node {nm!r}, not among {', '.join(names)}")
    c = cfg.coop
    loop_nodes: list[LoopNode] = []
    systems: dict[str, tuple[str, ...]] = {}
    for i, (nd, bt) in enumerate(zip(nodes, batches, strict=True)):
        b1 = select_band1(bt)
        sy = systems_of(b1, eph, coop_systems(cfg))
        if not sy:
            raise InputError(
                f"node {nd.name}: no code of systems {coop_systems(cfg)} with broadcast ephemerides"
            )
        lay = node_layout(len(sy))
        vis = band1_visible(bt, b1, aligned_visible(nd, bt))
        clk = lay.slice("clk")
        filt = make_filter(cfg, tuple(range(clk.start, clk.stop)), c.seed + i)
        loop_nodes.append(LoopNode(nd.name, RinexNode(b1, vis, sy, lay, eph, cfg), filt, lay.size))
        systems[nd.name] = sy

    n_epochs = len(batches[0].t_s)

    def ranges_at(name: str, k: int, t: float) -> list[RangeObservation]:
        if progress is not None and name == names[-1]:
            progress(k, n_epochs)  # the last node's epoch k starts: k epochs done
        out = []
        for lk in links:
            if name in (lk.a, lk.b):
                r, v = lk.at(t)
                out.append(RangeObservation(lk.b if lk.a == name else lk.a, r, v))
        return out

    process = LocationTimeModel(sigma_pos_m_s=c.sigma_pos_m_s, sigma_clk_m_s=c.sigma_clk_m_s)
    network = PeerNetwork(
        loop_nodes, ranges_at, process, c.filter, c.cooperation, reset_settings(cfg), c.max_broadcast_age_s
    )
    epochs = peer_to_peer(batches[0].t_s, network)
    if progress is not None:
        progress(n_epochs, n_epochs)
    return CoopResult(names, epochs, cfg, {"systems": systems})


__all__ = [
    "RinexNode",
    "aligned_visible",
    "approx_position",
    "band1_visible",
    "code_row_settings",
    "common_epochs",
    "paired_epochs",
    "make_filter",
    "solve_coop",
    "systems_of",
]
