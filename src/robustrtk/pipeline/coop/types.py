"""What a cooperative run takes and gives (algorithms.md §21): the settings it reads from the
``[coop]`` section of :class:`~robustrtk.pipeline.config.Config`, the nodes
(:class:`CoopNode`), the measured inter-node ranges (:class:`RangeLink`) and, per node and
epoch, a :class:`NodeEpoch` gathered in a :class:`CoopResult`."""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np

from robustrtk.core import BoolArray, FloatArray, ObsBatch, Solution
from robustrtk.estimation.coop import PeerBroadcast, ResetSettings
from robustrtk.pipeline.config import Config
from robustrtk.pipeline.gnss_inputs import load_obs

PathLike = str | os.PathLike[str]


def reset_settings(cfg: Config) -> ResetSettings:
    """The covariance reset (eqs. 29–30) of the ``[coop]`` section."""
    c = cfg.coop
    return ResetSettings(
        c.sigma_set_m, c.sigma_wset_m_s, c.window, c.sigma_set_floor_m, c.sigma_wset_floor_m_s
    )


def coop_systems(cfg: Config) -> str:
    """System letters whose code the nodes use (``systems``; unset: GPS, Galileo, BeiDou, QZSS)."""
    return cfg.gnss.systems or "GECJ"


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
    max_gap_s : float
        Between two series epochs at most this far apart (s) and farther than ``tol_s`` from
        both, the range is interpolated (:meth:`at`); 0: never.
    """

    a: str
    b: str
    t_s: FloatArray
    range_m: FloatArray
    var_m2: FloatArray
    tol_s: float = 0.6
    max_gap_s: float = 0.0

    @classmethod
    def constant(cls, a: str, b: str, range_m: float, sigma_m: float) -> RangeLink:
        return cls(a, b, np.zeros(0), np.array([float(range_m)]), np.array([float(sigma_m) ** 2]))

    def at(self, t_s: float) -> tuple[float, float]:
        """``(range, variance)`` at ``t_s``: the series epoch within ``tol_s``, else the linear
        interpolation between the epochs before and after ``t_s`` when they are at most
        ``max_gap_s`` apart, its variance the larger of theirs plus the square of half their
        difference (the change the series shows across the gap); NaN otherwise."""
        if self.t_s.size == 0:
            return float(self.range_m[0]), float(self.var_m2[0])
        j = int(np.argmin(np.abs(self.t_s - t_s)))
        if abs(float(self.t_s[j]) - t_s) <= self.tol_s:
            return float(self.range_m[j]), float(self.var_m2[j])
        hi = int(np.searchsorted(self.t_s, t_s))
        if self.max_gap_s <= 0.0 or hi == 0 or hi == self.t_s.size:
            return float("nan"), float("nan")
        t0, t1 = float(self.t_s[hi - 1]), float(self.t_s[hi])
        if t1 - t0 > self.max_gap_s:
            return float("nan"), float("nan")
        r0, r1 = float(self.range_m[hi - 1]), float(self.range_m[hi])
        w = (t_s - t0) / (t1 - t0)
        var = max(float(self.var_m2[hi - 1]), float(self.var_m2[hi])) + (0.5 * (r1 - r0)) ** 2
        return r0 + w * (r1 - r0), var


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
    broadcast : PeerBroadcast or None
        What the node broadcast after this epoch (None: nothing, or not a peer-to-peer run).
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
    broadcast: PeerBroadcast | None = None

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
    settings: Config
    info: dict[str, object] = field(default_factory=dict)

    def solutions(self, node: str) -> list[Solution]:
        return [e.to_solution() for e in self.epochs[node]]

    def positions(self, node: str) -> FloatArray:
        """``(T, 3)`` positions, NaN where unsolved."""
        return np.array([e.pos_ecef_m if e.solved else np.full(3, np.nan) for e in self.epochs[node]])

    def solved_fraction(self, node: str) -> float:
        ep = self.epochs[node]
        return float(np.mean([e.solved for e in ep])) if ep else 0.0


def load_node(name: str, obs: ObsBatch | PathLike, visible: BoolArray | None = None) -> CoopNode:
    """A :class:`CoopNode` from a file (all systems) or a batch."""
    return CoopNode(name, load_obs(obs, None), visible)


__all__ = [
    "CoopNode",
    "CoopResult",
    "NodeEpoch",
    "PathLike",
    "RangeLink",
    "coop_systems",
    "load_node",
    "reset_settings",
]
