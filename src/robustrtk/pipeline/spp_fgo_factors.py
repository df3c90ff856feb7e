"""Factors of the batch SPP smoother: code, Doppler, TDCP rows and the motion prior.

Unknowns: per epoch ``k`` the block ``x_k = [r(3), v(3), clk(n_s), d, ifb(n_b), Δc(n_s)]``
(ECEF position and velocity, the code clock of each system, the clock drift, the second-band
code bias of each system with one, and the carrier-phase clock change from ``k − 1`` to
``k`` of each system), stacked epoch after epoch (docs/algorithms.md §36). Each row set is
stored flat (one entry per row) and linearised in vectorised form.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from robustrtk.core import CLIGHT, FloatArray
from robustrtk.estimation.fgo import Linearized
from robustrtk.estimation.state import StateLayout
from robustrtk.geometry.los import OMEGA_E_RAD_S, geometric_range
from robustrtk.pipeline.spp_dynamics import SppProcessModel


@dataclass(frozen=True)
class BlockLayout:
    """Column offsets inside one epoch's block (``size`` columns per epoch)."""

    n_systems: int
    n_band2: int

    @property
    def clk(self) -> int:
        return 6

    @property
    def drift(self) -> int:
        return 6 + self.n_systems

    @property
    def ifb(self) -> int:
        return 7 + self.n_systems

    @property
    def n_fixed(self) -> int:
        """Columns the process model moves (all but the phase-clock changes)."""
        return 7 + self.n_systems + self.n_band2

    @property
    def dpc(self) -> int:
        return self.n_fixed

    @property
    def size(self) -> int:
        return self.n_fixed + self.n_systems

    def process_layout(self) -> StateLayout:
        blocks: list[tuple[str, int]] = [("pos", 3), ("vel", 3), ("clk", self.n_systems), ("drift", 1)]
        if self.n_band2:
            blocks.append(("ifb", self.n_band2))
        return StateLayout(blocks=tuple(blocks))


def _csr(rows: np.ndarray, cols: np.ndarray, vals: np.ndarray, m: int, n: int) -> sp.csr_matrix:
    return sp.csr_matrix((vals.ravel(), (rows.ravel(), cols.ravel())), shape=(m, n))


@dataclass(frozen=True)
class CodeRows:
    """Pseudorange rows: ``z = P + c dt_i − c T_GD,b − I_b − T = ρ(r_k) + clk_s + [b=2] ifb_s``."""

    epoch: np.ndarray
    sat_pos_m: FloatArray  # (m, 3)
    z_m: FloatArray
    sigma_m: FloatArray
    clk_col: np.ndarray  # column inside the block
    ifb_col: np.ndarray  # -1 for band 1
    block: int
    n: int

    def linearize(self, x: FloatArray) -> Linearized:
        X = x.reshape(-1, self.block)
        rng, u = geometric_range(self.sat_pos_m, X[self.epoch, 0:3])
        h = rng + X[self.epoch, self.clk_col]
        two = self.ifb_col >= 0
        h[two] += X[self.epoch[two], self.ifb_col[two]]
        m = self.z_m.size
        base = self.epoch * self.block
        r_i = np.repeat(np.arange(m), 4)
        c_i = np.column_stack([base, base + 1, base + 2, base + self.clk_col]).ravel()
        v_i = np.column_stack([-u, np.ones(m)]).ravel()
        J = _csr(r_i, c_i, v_i, m, self.n)
        if two.any():
            J = J + _csr(
                np.flatnonzero(two), base[two] + self.ifb_col[two], np.ones(int(two.sum())), m, self.n
            )
        return Linearized(self.z_m - h, self.sigma_m, J.tocsr())


@dataclass(frozen=True)
class DopplerRows:
    """Range-rate rows: ``z = −λ D + c ḋt_i = u·(v_i − v_k) − Sagnac rate + d_k``."""

    epoch: np.ndarray
    sat_pos_m: FloatArray
    sat_vel_m_s: FloatArray
    z_m_s: FloatArray
    sigma_m_s: FloatArray
    block: int
    drift_col: int
    n: int

    def linearize(self, x: FloatArray) -> Linearized:
        X = x.reshape(-1, self.block)
        p, v = X[self.epoch, 0:3], X[self.epoch, 3:6]
        _, u = geometric_range(self.sat_pos_m, p)
        sp_, sv = self.sat_pos_m, self.sat_vel_m_s
        sag = (
            OMEGA_E_RAD_S
            / CLIGHT
            * (sv[:, 1] * p[:, 0] + sp_[:, 1] * v[:, 0] - sv[:, 0] * p[:, 1] - sp_[:, 0] * v[:, 1])
        )
        h = np.sum(u * (sv - v), axis=1) - sag + X[self.epoch, self.drift_col]
        m = self.z_m_s.size
        base = self.epoch * self.block
        r_i = np.repeat(np.arange(m), 4)
        c_i = np.column_stack([base + 3, base + 4, base + 5, base + self.drift_col]).ravel()
        v_i = np.column_stack([-u, np.ones(m)]).ravel()
        return Linearized(self.z_m_s - h, self.sigma_m_s, _csr(r_i, c_i, v_i, m, self.n))


@dataclass(frozen=True)
class TdcpRows:
    """Time-differenced phase rows between epochs ``k − 1`` and ``k``
    (:mod:`robustrtk.measurement.tdcp`): ``δ = ρ(S_k, r_k) − ρ(S_k−1, r_k−1) + Δc_s,k``."""

    epoch: np.ndarray  # k (the later epoch)
    sat_prev_m: FloatArray
    sat_now_m: FloatArray
    delta_m: FloatArray
    sigma_m: FloatArray
    dpc_col: np.ndarray
    block: int
    n: int

    def linearize(self, x: FloatArray) -> Linearized:
        X = x.reshape(-1, self.block)
        k = self.epoch
        r1, u1 = geometric_range(self.sat_now_m, X[k, 0:3])
        r0, u0 = geometric_range(self.sat_prev_m, X[k - 1, 0:3])
        h = r1 - r0 + X[k, self.dpc_col]
        m = self.delta_m.size
        b1, b0 = k * self.block, (k - 1) * self.block
        r_i = np.repeat(np.arange(m), 7)
        c_i = np.column_stack([b1, b1 + 1, b1 + 2, b0, b0 + 1, b0 + 2, b1 + self.dpc_col]).ravel()
        v_i = np.column_stack([-u1, u0, np.ones(m)]).ravel()
        return Linearized(self.delta_m - h, self.sigma_m, _csr(r_i, c_i, v_i, m, self.n))


class MotionRows:
    """The Kalman SPP's process model between consecutive epochs as a factor:
    ``W (x_k − F x_k−1) ~ N(0, I)`` over the moved columns, ``W = L⁻¹``, ``Q = L Lᵀ``
    (:class:`robustrtk.pipeline.spp_dynamics.SppProcessModel`). A pair whose code clock
    jumped (``clock_jump``) has the clock rows released (variance ``1e8`` m² added)."""

    def __init__(
        self, model: SppProcessModel, lay: BlockLayout, t_s: FloatArray, clock_jump: np.ndarray, n: int
    ) -> None:
        T = len(t_s)
        nf, blk = lay.n_fixed, lay.size
        pl = lay.process_layout()
        cache: dict[tuple[float, bool], tuple[FloatArray, FloatArray]] = {}
        rows, cols, vals = [], [], []
        for k in range(1, T):
            key = (round(float(t_s[k] - t_s[k - 1]), 6), bool(clock_jump[k]))
            if key not in cache:
                F, Q = model.transition(pl, key[0])
                if key[1]:
                    c = slice(lay.clk, lay.clk + lay.n_systems)
                    Q[c, c] += np.eye(lay.n_systems) * 1e8
                L = np.linalg.cholesky(Q + np.eye(nf) * 1e-12)
                W = np.linalg.inv(L)
                cache[key] = (W, -W @ F)
            W, WF = cache[key]
            r0 = (k - 1) * nf
            rr = r0 + np.repeat(np.arange(nf), nf)
            cc = np.tile(np.arange(nf), nf)
            rows += [rr, rr]
            cols += [k * blk + cc, (k - 1) * blk + cc]
            vals += [W.ravel(), WF.ravel()]
        m = (T - 1) * nf
        self.J = (
            _csr(np.concatenate(rows), np.concatenate(cols), np.concatenate(vals), m, n)
            if T > 1
            else sp.csr_matrix((0, n))
        )
        self.sigma = np.ones(m)

    def linearize(self, x: FloatArray) -> Linearized:
        return Linearized(-(self.J @ x), self.sigma, self.J)


@dataclass(frozen=True)
class PriorRows:
    """Weak priors ``x_c = value ± σ`` on single columns (start of the track, phase-clock
    changes without TDCP rows): they make the normal matrix regular, nothing more."""

    cols: np.ndarray
    value: FloatArray
    sigma: FloatArray
    n: int

    def linearize(self, x: FloatArray) -> Linearized:
        m = self.cols.size
        J = _csr(np.arange(m), self.cols, np.ones(m), m, self.n)
        return Linearized(self.value - x[self.cols], self.sigma, J)


__all__ = ["BlockLayout", "CodeRows", "DopplerRows", "MotionRows", "PriorRows", "TdcpRows"]
