"""Peer-to-peer solution of one simulated two-node session (Zhou et al. 2018; algorithms.md
§21, §25).

Both nodes run the same filter kind (:func:`robustrtk.estimation.coop.make_node_filter`) on
their own corrected pseudoranges (:class:`robustrtk.measurement.coop.PseudorangeModel`,
state ``[p (3), b_GPS, b_BDS]``) and, unless the cooperation is ``off``, on the range to the
other node at the position that node last broadcast
(:func:`robustrtk.estimation.coop.peer_range_model`: the σ² of the range as measured for
``traditional``, eq. 24 with the reset covariance of eq. 29 / 30 for ``improved``). Each
epoch node 1 is processed first (with node 2's broadcast of the previous epoch), then
node 2 (with node 1's broadcast of this epoch); a node broadcasts its Gaussian summary after
every solved epoch. This is the loop of :func:`robustrtk.pipeline.coop.solve_coop` on
simulated rows instead of RINEX files.

A node's filter starts at the first epoch at which its own pseudoranges are at least
at least ``3 + clocks seen``: weighted least squares from the peer's broadcast position (or
the Earth's centre), its covariance plus ``init_floor_m²`` on the position, and a free
clock for a system not yet seen. An epoch is *solved* when its rows are at least the
unknowns they touch and the correction succeeded; otherwise its position is NaN.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from robustrtk.core import FloatArray
from robustrtk.estimation.coop import (
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
from robustrtk.estimation.state import GaussianState
from robustrtk.measurement.coop import PseudorangeModel
from robustrtk.measurement.dd import StackedModel
from robustrtk.sim.coop import SYSTEMS, CoopNodeData, CoopSim

NAMES = ("node1", "node2")
#: State indices of the GPS and BeiDou clocks in ``[p, b_G, b_C]``.
CLOCK_INDEX = {"G": 3, "C": 4}
N_STATE = 3 + len(SYSTEMS)
UP_100M = np.array([0.0, 0.0, 100.0])


@dataclass(frozen=True)
class SolveSettings:
    """Filter settings shared by both nodes.

    Attributes
    ----------
    sigma_pos_m_s, sigma_clk_m_s : float
        Eq. 8 process noise σ_ẋ (per axis) and σ_ḃ (m/s).
    ukf_alpha, ukf_beta : float
    n_particles : int
    ess_threshold, roughening : float
    init_floor_m : float
    reset : ResetSettings
        σ_set, σ_wset of the improved algorithm (None: short-window estimates).
    """

    sigma_pos_m_s: float = 0.01
    sigma_clk_m_s: float = 10.0
    ukf_alpha: float = 1.0
    ukf_beta: float = 2.0
    n_particles: int = 2000
    ess_threshold: float = 0.5
    roughening: float = 0.2
    init_floor_m: float = 1.0
    reset: ResetSettings = field(default_factory=ResetSettings)


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
    """

    pos_m: FloatArray
    trace_p_m2: FloatArray
    range_sigma_m: FloatArray
    ess: FloatArray
    bc_x: FloatArray
    bc_p: FloatArray


def _make_filter(kind: str, cfg: SolveSettings, seed: int) -> NodeFilter:
    if kind in ("ekf", "ukf"):
        return make_node_filter(kind, alpha=cfg.ukf_alpha, beta=cfg.ukf_beta)
    if kind == "pf":
        return make_node_filter(
            "pf",
            n_particles=cfg.n_particles,
            ess_threshold=cfg.ess_threshold,
            roughening=cfg.roughening,
            seed=seed,
            linear_idx=(3, 4),
        )
    return make_node_filter("ls")


def _pseudoranges(node: CoopNodeData, k: int) -> PseudorangeModel:
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


def _unknowns(pr: PseudorangeModel) -> int:
    return 3 + len(set(pr.clk_index.tolist()))


def _init(
    pr: PseudorangeModel, peer: PeerBroadcast | None, range_m: float, t_s: float, cfg: SolveSettings
) -> GaussianState | None:
    lay = node_layout(len(SYSTEMS))
    x = np.zeros(lay.size)
    clocks = sorted(set(pr.clk_index.tolist()))
    if pr.z.size >= _unknowns(pr):
        cols = np.r_[0, 1, 2, clocks].astype(np.int64)
        floor2 = cfg.init_floor_m**2
    elif peer is not None and pr.z.size >= len(clocks) > 0:
        # within range_m of the peer: start one range above it, position σ = range + floor
        x[:3] = peer.pos_ecef_m + range_m * peer.pos_ecef_m / np.linalg.norm(peer.pos_ecef_m)
        cols = np.asarray(clocks, dtype=np.int64)
        floor2 = (range_m + cfg.init_floor_m) ** 2
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
    return GaussianState(res.state.x, P, t_s, lay)


def solve_pair(
    sim: CoopSim,
    kind: str,
    cooperation: str,
    cfg: SolveSettings,
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
    cooperation : {"off", "traditional", "improved"}
    cfg : SolveSettings
    seed : int
        Particle-filter seed (node ``i`` uses ``seed + i``).
    mutual : bool
        Node 1 also uses the range to node 2 (peer to peer both ways); default: node 1
        solves alone and only node 2 cooperates, as in the paper's study.
    node1 : PairSolution, optional
        Without ``mutual``: reuse node 1's epochs and broadcasts of this earlier solution
        of the same ``sim``, ``kind`` and ``seed`` (node 1 does not depend on the mode).
    """
    T = sim.t_s.size
    proc = LocationTimeModel(sigma_pos_m_s=cfg.sigma_pos_m_s, sigma_clk_m_s=cfg.sigma_clk_m_s)
    filters = [_make_filter(kind, cfg, seed + i) for i in range(2)]
    beliefs: list[Belief | None] = [None, None]
    last_t = [np.nan, np.nan]
    broadcasts: dict[str, PeerBroadcast] = {}
    windows = {me: PeerWindow(cfg.reset) for me in NAMES}  # window of the *other* node's broadcasts
    pos = np.full((2, T, 3), np.nan)
    trp = np.full((2, T), np.nan)
    rsig = np.full((2, T), np.nan)
    ess = np.full((2, T), np.nan)
    bcx = np.full((T, 4), np.nan)
    bcp = np.full((T, 4, 4), np.nan)
    rng_var = sim.range_sigma_m**2
    for k in range(T):
        t = float(sim.t_s[k])
        for i in range(2):
            me, peer = NAMES[i], NAMES[1 - i]
            if i == 0 and node1 is not None and not mutual:
                pos[0, k], trp[0, k], rsig[0, k], ess[0, k] = (
                    node1.pos_m[0, k],
                    node1.trace_p_m2[0, k],
                    np.nan,
                    node1.ess[0, k],
                )
                bcx[k], bcp[k] = node1.bc_x[k], node1.bc_p[k]
                if np.all(np.isfinite(bcx[k])):
                    bc = PeerBroadcast(me, t, bcx[k], bcp[k])
                    broadcasts[me] = bc
                    windows[peer].push(bc)
                continue
            pr = _pseudoranges(sim.nodes[i], k)
            coop_here = cooperation != "off" and (i == 1 or mutual)
            fresh = {peer: broadcasts[peer]} if coop_here and peer in broadcasts else {}
            obs = [RangeObservation(peer, float(sim.range_m[k]), rng_var)]
            filt = filters[i]
            b = beliefs[i]
            if b is None:
                init = _init(pr, fresh.get(peer), float(sim.range_m[k]), t, cfg)
                if init is None:
                    continue
                beliefs[i] = filt.init(init)
                last_t[i] = t
                s = filt.summary(beliefs[i])  # type: ignore[arg-type]
                ok = pr.z.size >= _unknowns(pr)
                step_ess = float("nan")
                sig = float("nan")
            else:
                dt = t - last_t[i]
                prior = filt.predict(b, proc, t)
                rm = peer_range_model(
                    obs,
                    fresh,
                    cooperation if fresh else "off",
                    kind,
                    {peer: windows[me]},
                    n_state=N_STATE,
                    dt_s=dt,
                )
                step = filt.update(prior, StackedModel((pr, rm)))
                n_range = int(rm.z.size)
                ok = step.ok and pr.z.size + n_range >= _unknowns(pr) and pr.z.size > 0
                beliefs[i] = step.belief if step.ok else prior
                last_t[i] = t
                s = step.summary if step.ok else filt.summary(prior)
                step_ess = step.ess
                sig = float(np.sqrt(rm.var_m2[0])) if n_range else float("nan")
            trp[i, k] = float(np.trace(s.P[:3, :3]))
            rsig[i, k] = sig
            ess[i, k] = step_ess
            if ok:
                pos[i, k] = s.x[:3]
                bc = PeerBroadcast.of(me, s)
                broadcasts[me] = bc
                windows[peer].push(bc)
                if i == 0:
                    bcx[k], bcp[k] = bc.x, bc.P
    return PairSolution(pos, trp, rsig, ess, bcx, bcp)


__all__ = ["CLOCK_INDEX", "NAMES", "PairSolution", "SolveSettings", "solve_pair"]
