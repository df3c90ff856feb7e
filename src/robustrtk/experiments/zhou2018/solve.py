"""Peer-to-peer solution of one simulated two-node session (Zhou et al. 2018; algorithms.md
§21, §25).

Both nodes run the same filter kind on their own corrected pseudoranges
(:class:`robustrtk.measurement.coop.PseudorangeModel`, state ``[p (3), b_GPS, b_BDS]``)
and, unless the cooperation is ``off``, on the range to the other node at the position that
node last broadcast — the cooperative pipeline's loop,
:func:`robustrtk.pipeline.coop.loops.peer_to_peer`, with the simulated rows as each node's
source (:class:`SimNode`). Each epoch node 1 is processed first (with node 2's broadcast of
the previous epoch), then node 2 (with node 1's broadcast of this epoch). The settings are
the ``[coop]`` section of a :class:`~robustrtk.pipeline.config.Config`
(:data:`~robustrtk.pipeline.config.ZHOU2018_PRESET`).

A node's filter starts at the first epoch at which its own pseudoranges are at least
``3 + clocks seen``: weighted least squares from the Earth's centre, its covariance plus
``init_floor_m²`` on the position, and a free clock for a system not yet seen; a
cooperating node with fewer rows starts one range above the peer's broadcast, its clocks
from its rows, position σ = range + floor (that epoch unsolved). An epoch is *solved* when
its rows are at least the unknowns they touch and the correction succeeded; otherwise its
position is NaN.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robustrtk.core import FloatArray
from robustrtk.estimation.coop import (
    LocationTimeModel,
    PeerBroadcast,
    RangeObservation,
    gauss_newton,
    node_layout,
)
from robustrtk.estimation.state import GaussianState
from robustrtk.measurement.coop import PseudorangeModel
from robustrtk.pipeline.config import ZHOU2018_PRESET, Config
from robustrtk.pipeline.coop.loops import LoopNode, NodeStart, PeerNetwork, peer_to_peer
from robustrtk.pipeline.coop.rinex import make_filter
from robustrtk.pipeline.coop.types import NodeEpoch, reset_settings
from robustrtk.sim.coop import SYSTEMS, CoopNodeData, CoopSim

NAMES = ("node1", "node2")
#: State indices of the GPS and BeiDou clocks in ``[p, b_G, b_C]``.
CLOCK_INDEX = {"G": 3, "C": 4}
N_STATE = 3 + len(SYSTEMS)


@dataclass(frozen=True)
class PairSolution:
    """Per-epoch output of :func:`solve_pair`.

    Attributes
    ----------
    pos_m : ndarray, shape (2, T, 3)
        Each node's position (ECEF m; NaN where not solved).
    trace_p_m2 : ndarray, shape (2, T)
        Trace of each node's position covariance (m²).
    range_sigma_m : ndarray, shape (2, T)
        σ̂ of the range row each node used (m; NaN: no range row).
    ess : ndarray, shape (2, T)
        Particle-filter effective sample size (NaN for the others).
    bc_x, bc_p : ndarray, shape (T, 4) and (T, 4, 4)
        Node 1's broadcasts ``[p, b_GPS]`` and covariance (NaN: none that epoch).
    epochs : dict
        Each node's :class:`~robustrtk.pipeline.coop.types.NodeEpoch` list (what a later
        solution replays).
    """

    pos_m: FloatArray
    trace_p_m2: FloatArray
    range_sigma_m: FloatArray
    ess: FloatArray
    bc_x: FloatArray
    bc_p: FloatArray
    epochs: dict[str, list[NodeEpoch]]

    @classmethod
    def of(cls, epochs: dict[str, list[NodeEpoch]]) -> PairSolution:
        """The arrays of the two nodes' epochs."""
        eps = [epochs[n] for n in NAMES]
        pos = np.array([[e.pos_ecef_m for e in ep] for ep in eps], float)
        trp = np.array([[e.trace_p_m2 for e in ep] for ep in eps], float)
        rsig = np.array([[e.range_sigma_m for e in ep] for ep in eps], float)
        ess = np.array([[e.ess for e in ep] for ep in eps], float)
        T = len(eps[0])
        bcx = np.full((T, 4), np.nan)
        bcp = np.full((T, 4, 4), np.nan)
        for k, e in enumerate(eps[0]):
            if e.broadcast is not None:
                bcx[k], bcp[k] = e.broadcast.x, e.broadcast.P
        return cls(pos, trp, rsig, ess, bcx, bcp, epochs)


def _unknowns(pr: PseudorangeModel) -> int:
    return 3 + len(set(pr.clk_index.tolist()))


@dataclass(frozen=True)
class SimNode:
    """One simulated node's rows (a :class:`~robustrtk.pipeline.coop.loops.NodeSource`)."""

    node: CoopNodeData
    peer: str
    init_floor_m: float

    def pseudoranges(self, k: int, t_s: float, guess_ecef_m: FloatArray) -> PseudorangeModel:
        """The corrected pseudoranges seen at epoch ``k`` (they do not depend on the guess)."""
        node = self.node
        seen = np.flatnonzero(np.isfinite(node.code_m[k]))
        return PseudorangeModel(
            z=node.code_m[k, seen],
            sat_pos_m=node.sat_pos_m[k, seen],
            var_m2=node.var_m2[k, seen],
            clk_index=np.array([CLOCK_INDEX[node.sat_ids[i][0]] for i in seen], dtype=np.int64),
            pos_start=0,
            n_state=N_STATE,
            labels=tuple(f"{node.sat_ids[i]}:P" for i in seen),
        )

    def start(
        self, k: int, t_s: float, ranges: list[RangeObservation], broadcasts: dict[str, PeerBroadcast]
    ) -> NodeStart | None:
        """Least squares of the epoch's pseudoranges (module notes)."""
        pr = self.pseudoranges(k, t_s, np.zeros(3))
        peer = broadcasts.get(self.peer)
        range_m = ranges[0].range_m
        lay = node_layout(len(SYSTEMS))
        x = np.zeros(lay.size)
        clocks = sorted(set(pr.clk_index.tolist()))
        if pr.z.size >= _unknowns(pr):
            cols = np.r_[0, 1, 2, clocks].astype(np.int64)
            floor2 = self.init_floor_m**2
        elif peer is not None and pr.z.size >= len(clocks) > 0:
            # within range_m of the peer: start one range above it, position σ = range + floor
            x[:3] = peer.pos_ecef_m + range_m * peer.pos_ecef_m / np.linalg.norm(peer.pos_ecef_m)
            cols = np.asarray(clocks, dtype=np.int64)
            floor2 = (range_m + self.init_floor_m) ** 2
        else:
            return None
        res = gauss_newton(pr, x, cols=cols, max_iter=20, t_s=t_s, layout=lay)
        if not res.ok or not 6.2e6 < float(np.linalg.norm(res.state.x[:3])) < 6.6e6:
            return None
        P = np.array(res.state.P, copy=True)
        for i in range(lay.size):
            if P[i, i] <= 0.0:
                P[i, i] = 1e8  # a clock no row saw: free
        P[:3, :3] += np.eye(3) * floor2
        return NodeStart(GaussianState(res.state.x, P, t_s, lay), pr.z.size >= _unknowns(pr), int(pr.z.size))


def solve_pair(
    sim: CoopSim,
    kind: str,
    cooperation: str,
    cfg: Config = ZHOU2018_PRESET,
    seed: int = 0,
    *,
    mutual: bool = False,
    node1: PairSolution | None = None,
) -> PairSolution:
    """Solve both nodes of ``sim`` (module notes).

    Parameters
    ----------
    sim : CoopSim
    kind : {"ls", "ekf", "ukf", "pf"}
        The filter (over ``cfg``'s ``coop_filter``).
    cooperation : {"off", "traditional", "improved"}
        Over ``cfg``'s ``cooperation``.
    cfg : Config
        The ``[coop]`` section (process noise, particle filter, reset, ``init_floor_m``) and
        ``ukf_alpha``, ``ukf_beta``.
    seed : int
        Particle-filter seed (node ``i`` uses ``seed + i``).
    mutual : bool
        Node 1 also uses the range to node 2 (peer to peer both ways); default: node 1
        solves alone and only node 2 cooperates, as in the paper's study.
    node1 : PairSolution, optional
        Without ``mutual``: replay node 1's epochs and broadcasts of this earlier solution
        of the same ``sim``, ``kind`` and ``seed`` (node 1 does not depend on the mode).
    """
    cfg = cfg.updated(coop_filter=kind, cooperation=cooperation).validate("zhou2018")
    c = cfg.coop
    rng_var = sim.range_sigma_m**2
    nodes = []
    for i, name in enumerate(NAMES):
        src = SimNode(sim.nodes[i], NAMES[1 - i], c.init_floor_m)
        filt = make_filter(cfg, (3, 4), seed + i)
        replay = node1.epochs[name] if i == 0 and node1 is not None and not mutual else None
        nodes.append(LoopNode(name, src, filt, N_STATE, cooperates=i == 1 or mutual, replay=replay))

    def ranges_at(name: str, k: int, t: float) -> list[RangeObservation]:
        other = NAMES[1] if name == NAMES[0] else NAMES[0]
        return [RangeObservation(other, float(sim.range_m[k]), rng_var)]

    process = LocationTimeModel(sigma_pos_m_s=c.sigma_pos_m_s, sigma_clk_m_s=c.sigma_clk_m_s)
    network = PeerNetwork(nodes, ranges_at, process, kind, cooperation, reset_settings(cfg))
    epochs = peer_to_peer(sim.t_s, network)
    return PairSolution.of(epochs)


__all__ = ["CLOCK_INDEX", "NAMES", "PairSolution", "SimNode", "solve_pair"]
