"""The centralised reference of cooperative positioning (algorithms.md §21): one joint
filter over the stacked states of all nodes with every node's pseudoranges and every
inter-node range (no inflation: the joint covariance carries the correlation)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from robustrtk.core import FloatArray, ObsBatch
from robustrtk.estimation.coop import Belief, LocationTimeModel, gauss_newton, node_layout
from robustrtk.estimation.state import GaussianState, StateLayout
from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.io.rinex_nav import NavData
from robustrtk.measurement.coop import InterNodeRangeModel, PseudorangeModel, node_pseudoranges
from robustrtk.measurement.dd import StackedModel
from robustrtk.measurement.undifferenced import epoch_geometry
from robustrtk.pipeline.config import COOP_PRESET, Config
from robustrtk.pipeline.coop.loops import n_unknowns
from robustrtk.pipeline.coop.rinex import (
    aligned_visible,
    approx_position,
    band1_visible,
    code_row_settings,
    common_epochs,
    make_filter,
    systems_of,
)
from robustrtk.pipeline.coop.types import CoopNode, CoopResult, NodeEpoch, PathLike, RangeLink, coop_systems
from robustrtk.pipeline.gnss_inputs import nav_source
from robustrtk.pipeline.loop import EpochLoop
from robustrtk.pipeline.spp_common import select_band1


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
    cfg: Config | None = None,
    timeline: str | None = None,
) -> CoopResult:
    """The centralised reference: one joint filter over all nodes (module notes), on the epochs
    of node ``timeline`` (default the first; :func:`~robustrtk.pipeline.coop.rinex.common_epochs`).

    Uses ``cfg.coop.filter`` on the joint state ``[x_1, …, x_N]`` with every node's pseudoranges
    and every link as an :class:`~robustrtk.measurement.coop.InterNodeRangeModel` row (its
    measured variance; ``cooperation`` ``off`` drops the links). Starts at the first epoch
    where the joint least squares is determined. A node's epoch is solved when the joint
    rows are at least the joint unknowns they touch.
    """
    cfg = cfg or COOP_PRESET
    eph = nav_source(nav)
    batches = common_epochs(nodes, eph, cfg.gnss.max_age_s, timeline, coop_systems(cfg))
    joint = JointFilter(nodes, links, eph, cfg, batches)
    loop = EpochLoop(joint)
    names = joint.names
    epochs: dict[str, list[NodeEpoch]] = {n: [] for n in names}
    for k in range(len(batches[0])):
        for nm, ep in zip(names, loop.step(k), strict=True):
            epochs[nm].append(ep)
    return CoopResult(
        names, epochs, cfg, {"central": True, "systems": dict(zip(names, joint.systems, strict=True))}
    )


class JointFilter:
    """The per-epoch work of :func:`solve_coop_central` (a :class:`~robustrtk.pipeline.loop.
    Stage`): ``step(k)`` starts or updates the joint filter with epoch ``k`` of every node's
    aligned batch (``batches``, :func:`~robustrtk.pipeline.coop.rinex.common_epochs`) and
    returns each node's :class:`NodeEpoch`, in the order of ``nodes``."""

    def __init__(
        self,
        nodes: Sequence[CoopNode],
        links: Sequence[RangeLink],
        eph: EphemerisSource,
        cfg: Config,
        batches: Sequence[ObsBatch],
    ) -> None:
        self.links, self.eph, self.cfg, self.batches = links, eph, cfg, batches
        self.names = tuple(n.name for n in nodes)
        self.index = {n: i for i, n in enumerate(self.names)}
        b1s, systems, lays, vis = [], [], [], []
        for nd, bt in zip(nodes, batches, strict=True):
            b1 = select_band1(bt)
            b1s.append(b1)
            sy = systems_of(b1, eph, coop_systems(cfg))
            systems.append(sy)
            lays.append(node_layout(len(sy)))
            vis.append(band1_visible(bt, b1, aligned_visible(nd, bt)))
        self.b1s, self.systems, self.vis = b1s, systems, vis
        self.offs = offs = np.cumsum([0] + [lay.size for lay in lays])
        self.n_all = n_all = int(offs[-1])
        self.joint = StateLayout(blocks=(("x", n_all),))
        self.proc = JointLocationTime(
            tuple(lays), LocationTimeModel(cfg.coop.sigma_pos_m_s, cfg.coop.sigma_clk_m_s)
        )
        self.lin = tuple(int(offs[i]) + j for i, lay in enumerate(lays) for j in range(3, lay.size))
        self.filt = make_filter(cfg, self.lin, cfg.coop.seed)
        self.belief: Belief | None = None
        self.x_guess = np.zeros(n_all)
        for i, b1 in enumerate(b1s):
            a = approx_position(b1)
            self.x_guess[offs[i] : offs[i] + 3] = a if a is not None else 0.0

    def step(self, k: int) -> list[NodeEpoch]:
        """Epoch ``k`` of every node (module notes)."""
        cfg, eph, offs, n_all, filt, names = self.cfg, self.eph, self.offs, self.n_all, self.filt, self.names
        lin, joint, belief = self.lin, self.joint, self.belief
        t = float(self.batches[0].t_s[k])
        guess = self.x_guess if belief is None else filt.summary(belief).x
        parts: list[PseudorangeModel | InterNodeRangeModel] = []
        prs: list[PseudorangeModel] = []
        for i, b1 in enumerate(self.b1s):
            g = epoch_geometry(b1, k, eph)
            idx = np.flatnonzero(np.isfinite(b1.code_m[k, :, 0]))
            vi = self.vis[i]
            use = np.ones(idx.size, bool) if vi is None else vi[k, idx]
            clk = {s: int(offs[i]) + 3 + q for q, s in enumerate(self.systems[i])}
            pr = node_pseudoranges(
                t,
                g,
                use,
                guess[offs[i] : offs[i] + 3],
                eph.nav,
                clk,
                pos_start=int(offs[i]),
                n_state=n_all,
                **code_row_settings(cfg),
            )
            prs.append(pr)
            parts.append(pr)
        link_rows: list[tuple[int, int, float, float]] = []
        if cfg.coop.cooperation != "off":
            for lk in self.links:
                r, v = lk.at(t)
                if np.isfinite(r) and np.isfinite(v):
                    link_rows.append((self.index[lk.a], self.index[lk.b], r, v))
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
                            P[q, q] = (cfg.coop.sigma_clk_m_s * 30.0) ** 2 if q in lin else 1e6
                    for i in range(len(names)):
                        s0 = int(offs[i])
                        P[s0 : s0 + 3, s0 : s0 + 3] += np.eye(3) * cfg.coop.init_floor_m**2
                    belief = filt.init(GaussianState(res2.state.x, P, t, joint))
                    step_ok = True
        else:
            prior = filt.predict(belief, self.proc, t)
            step = filt.update(prior, rows)
            belief = step.belief if step.ok else prior
            step_ok = step.ok
        self.belief = belief
        s = filt.summary(belief) if belief is not None else None
        out: list[NodeEpoch] = []
        for i in range(len(names)):
            solved = bool(step_ok and solved_nodes[i] and s is not None)
            if s is None:
                out.append(NodeEpoch(t, np.full(3, np.nan), np.full((3, 3), np.nan), False, 0, 0))
                continue
            sl = slice(int(offs[i]), int(offs[i]) + 3)
            pos = s.x[sl].copy()
            nr = sum(1 for q in link_rows if i in (q[0], q[1]))
            out.append(
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
        return out


def _joint_solved(
    prs: list[PseudorangeModel], links: list[tuple[int, int, float, float]], n: int
) -> list[bool]:
    """Node by node: own rows plus ranges to nodes that are themselves determined cover its
    unknowns (iterated, so a node solved only through a solved peer counts)."""
    own = [n_unknowns(p, 0) for p in prs]
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


__all__ = ["JointFilter", "JointLocationTime", "solve_coop_central"]
