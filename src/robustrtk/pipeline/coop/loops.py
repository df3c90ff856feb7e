"""The peer-to-peer epoch loop of cooperative positioning (Zhou et al. 2018; algorithms.md §21).

Each node runs its own filter (:mod:`robustrtk.estimation.coop`: EKF, UKF, particle filter
or least squares) on its own pseudoranges and on the ranges to its peers, with the positions
and covariances the peers broadcast; there is no central node. Epoch by epoch the nodes are
processed in the order given, each using the latest broadcast of every peer (the same
epoch's for peers processed before it, the previous epoch's otherwise), not older than
``max_age_s``. A node broadcasts its Gaussian summary ``[p, b₁]``, ``P`` after every solved
epoch.

Where a node's rows come from is its :class:`NodeSource`: RINEX files and broadcast
ephemerides (:mod:`robustrtk.pipeline.coop.rinex`) or simulated rows
(:mod:`robustrtk.experiments.zhou2018.solve`); the source also starts the node's filter.
A node may be replayed instead of solved: its epochs (and broadcasts) of an earlier run
are fed to the others as they were.

A node's epoch is *solved* when its rows of that epoch (own pseudoranges and ranges to
peers with a usable broadcast) are at least as many as the unknowns they touch
(``3 + clocks seen``) and the correction succeeded; an unsolved epoch has a NaN position.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import numpy.typing as npt

from robustrtk.core import FloatArray
from robustrtk.estimation.coop import (
    Belief,
    LocationTimeModel,
    NodeFilter,
    PeerBroadcast,
    PeerWindow,
    RangeObservation,
    ResetSettings,
    peer_range_model,
)
from robustrtk.estimation.state import GaussianState
from robustrtk.measurement.coop import NodeRows, PseudorangeModel
from robustrtk.pipeline.coop.types import NodeEpoch
from robustrtk.pipeline.loop import EpochLoop


@dataclass(frozen=True)
class NodeStart:
    """A node's filter started: the state and what its first epoch reports (``update``: the
    state is a prior only, which the epoch's rows then update like any later epoch's)."""

    state: GaussianState
    solved: bool
    n_sats: int
    n_ranges: int = 0
    update: bool = False


class NodeSource(Protocol):
    """Where one node's rows come from, epoch by epoch."""

    def pseudoranges(self, k: int, t_s: float, guess_ecef_m: FloatArray) -> PseudorangeModel:
        """The node's own pseudorange rows of epoch ``k`` (``guess_ecef_m``: the predicted
        position, for the corrections that depend on it)."""
        ...

    def start(
        self, k: int, t_s: float, ranges: list[RangeObservation], broadcasts: dict[str, PeerBroadcast]
    ) -> NodeStart | None:
        """The filter's start at epoch ``k`` (None: not yet determined)."""
        ...


@dataclass
class LoopNode:
    """One node of :func:`peer_to_peer`.

    Attributes
    ----------
    name : str
    source : NodeSource
    filt : NodeFilter
    n_state : int
        Size of the node's state ``[p, clocks]``.
    cooperates : bool
        Uses the ranges to its peers (False: its own rows only).
    replay : sequence of NodeEpoch, optional
        The node's epochs of an earlier run: fed to the others as they were, not solved.
    """

    name: str
    source: NodeSource
    filt: NodeFilter
    n_state: int
    cooperates: bool = True
    replay: Sequence[NodeEpoch] | None = None
    belief: Belief | None = None
    last_t: float = float("nan")


def n_unknowns(pr: PseudorangeModel, extra_rows: int) -> tuple[int, int]:
    """Rows (own plus ``extra_rows``) and the unknowns they touch, ``3 + clocks seen``."""
    return int(pr.z.size) + extra_rows, 3 + len(set(pr.clk_index.tolist()))


def peer_to_peer(t_s: npt.ArrayLike, network: PeerNetwork) -> dict[str, list[NodeEpoch]]:
    """Run every node of ``network`` over the epochs ``t_s`` (GPST s, shape (T,)) through
    the one epoch loop (module notes).

    Returns
    -------
    dict
        Per node, one :class:`NodeEpoch` per epoch (with the broadcast it made).
    """
    loop = EpochLoop(network)
    epochs: dict[str, list[NodeEpoch]] = {nd.name: [] for nd in network.nodes}
    for k, t in enumerate(np.asarray(t_s, float).tolist()):
        for name, ep in loop.step((k, t)).items():
            epochs[name].append(ep)
    return epochs


class PeerNetwork:
    """The per-epoch work of :func:`peer_to_peer` (a :class:`~robustrtk.pipeline.loop.Stage`):
    ``step((k, t))`` runs every node over epoch ``k`` (tag ``t``, GPST s) in processing
    order, each with the latest broadcasts of its peers, and returns each node's
    :class:`NodeEpoch`.

    Parameters
    ----------
    nodes : sequence of LoopNode
        In processing order; names differ.
    ranges_at : callable
        ``ranges_at(name, k, t)``: the measured ranges from node ``name`` to its peers.
    process : LocationTimeModel
    kind : {"ekf", "ukf", "pf", "ls"}
        The filter kind (the UKF's reset adds the noise block, eq. 30).
    cooperation : {"improved", "traditional", "off"}
    reset : ResetSettings
        σ_set, σ_wset of the improved algorithm and the short window.
    max_age_s : float
        Older broadcasts are not used.
    """

    def __init__(
        self,
        nodes: Sequence[LoopNode],
        ranges_at: Callable[[str, int, float], list[RangeObservation]],
        process: LocationTimeModel,
        kind: str,
        cooperation: str,
        reset: ResetSettings,
        max_age_s: float = float("inf"),
    ) -> None:
        self.nodes, self.ranges_at, self.process = nodes, ranges_at, process
        self.kind, self.cooperation, self.max_age_s = kind, cooperation, max_age_s
        self.names = [nd.name for nd in nodes]
        self.broadcasts: dict[str, PeerBroadcast] = {}
        names = self.names
        self.windows = {(me, peer): PeerWindow(reset) for me in names for peer in names if me != peer}

    def step(self, epoch: tuple[int, float]) -> dict[str, NodeEpoch]:
        """Every node's epoch ``k`` at ``t``; each broadcast is kept for the nodes after it."""
        k, t = epoch
        broadcasts, windows = self.broadcasts, self.windows
        out: dict[str, NodeEpoch] = {}
        for nd in self.nodes:
            if nd.replay is not None:
                ep = nd.replay[k]
            else:
                fresh: dict[str, PeerBroadcast] = {}
                if nd.cooperates and self.cooperation != "off":
                    fresh = {
                        p: b for p, b in broadcasts.items() if p != nd.name and t - b.t_s <= self.max_age_s
                    }
                ranges = self.ranges_at(nd.name, k, t)
                mine = {p: windows[(nd.name, p)] for p in fresh}
                ep = _node_epoch(nd, k, t, self.process, self.kind, self.cooperation, ranges, fresh, mine)
            out[nd.name] = ep
            bc = ep.broadcast
            if bc is not None:
                broadcasts[nd.name] = bc
                for other in self.names:
                    if other != nd.name:
                        windows[(other, nd.name)].push(bc)
        return out


def _node_epoch(
    nd: LoopNode,
    k: int,
    t: float,
    process: LocationTimeModel,
    kind: str,
    cooperation: str,
    ranges: list[RangeObservation],
    broadcasts: dict[str, PeerBroadcast],
    windows: dict[str, PeerWindow],
) -> NodeEpoch:
    """One node's epoch: start its filter, or predict and correct it."""
    nan3 = np.full(3, np.nan)
    if nd.belief is None:
        start = nd.source.start(k, t, ranges, broadcasts)
        if start is None:
            return NodeEpoch(t, nan3, np.full((3, 3), np.nan), False, 0, 0)
        nd.belief = nd.filt.init(start.state)
        nd.last_t = t
        s = nd.filt.summary(nd.belief)
        if start.update:
            return _node_epoch(nd, k, t, process, kind, cooperation, ranges, broadcasts, windows)
        return NodeEpoch(
            t,
            s.x[:3].copy() if start.solved else nan3,
            s.P[:3, :3].copy(),
            start.solved,
            start.n_sats,
            start.n_ranges,
            trace_p_m2=float(np.trace(s.P[:3, :3])),
            broadcast=PeerBroadcast.of(nd.name, s) if start.solved else None,
        )
    dt = t - nd.last_t
    prior = nd.filt.predict(nd.belief, process, t)
    pr = nd.source.pseudoranges(k, t, nd.filt.summary(prior).x[:3])
    rm = peer_range_model(ranges, broadcasts, cooperation, kind, windows, n_state=nd.n_state, dt_s=dt)
    rows = NodeRows(pr, rm)
    nr = int(rm.z.size)
    step = nd.filt.update(prior, rows)
    m, n_unk = n_unknowns(pr, nr)
    solved = bool(step.ok and m >= n_unk and pr.z.size > 0)
    nd.belief = step.belief if step.ok else prior
    nd.last_t = t
    s = step.summary if step.ok else nd.filt.summary(prior)
    rres = rsig = float("nan")
    if nr:
        j = pr.z.size
        rres = float(step.innovation[j]) if step.innovation.size > j else float("nan")
        rsig = float(np.sqrt(rm.var_m2[0]))
    return NodeEpoch(
        t,
        s.x[:3].copy() if solved else nan3,
        s.P[:3, :3].copy(),
        solved,
        int(pr.z.size),
        nr,
        rres,
        rsig,
        float(np.trace(s.P[:3, :3])),
        step.ess,
        broadcast=PeerBroadcast.of(nd.name, s) if solved else None,
    )


__all__ = ["LoopNode", "NodeSource", "NodeStart", "PeerNetwork", "n_unknowns", "peer_to_peer"]
