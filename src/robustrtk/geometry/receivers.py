"""Receivers as data: a name and where the receiver is (a base may move).

A :class:`PositionSource` answers "where was this receiver at time t": a surveyed
constant (:class:`FixedPosition`) or a trajectory sampled at epochs
(:class:`TrajectoryPosition`: a file of positions, or a receiver's own solution — the
moving-base mode, where the base's per-epoch single-point solution is its position).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from robustrtk.core import FloatArray


class PositionSource(Protocol):
    """Position of a receiver at a time (NaN where unknown)."""

    def position(self, t_s: float) -> FloatArray:
        """ECEF (or local-frame) position (m), shape (3,), at ``t_s`` (s)."""
        ...


@dataclass(frozen=True)
class FixedPosition:
    """A surveyed, constant position ``pos_m`` (3,)."""

    pos_m: FloatArray

    def position(self, t_s: float) -> FloatArray:
        return self.pos_m


@dataclass(frozen=True)
class TrajectoryPosition:
    """Positions sampled at times ``t_s`` (T,) as ``pos_m`` (T, 3), linearly interpolated.

    Outside the samples, or between two samples more than ``max_gap_s`` apart, the position
    is unknown (NaN): a base whose position is unknown gives no solution, never a wrong one.
    Rows with a NaN position are gaps.
    """

    t_s: FloatArray
    pos_m: FloatArray
    max_gap_s: float = 1.5
    tol_s: float = 0.01

    def __post_init__(self) -> None:
        t = np.asarray(self.t_s, float)
        p = np.asarray(self.pos_m, float).reshape(-1, 3)
        if t.shape != (p.shape[0],):
            raise ValueError(f"trajectory: {t.size} times for {p.shape[0]} positions")
        ok = np.isfinite(t) & np.all(np.isfinite(p), axis=1)
        order = np.argsort(t[ok], kind="stable")
        object.__setattr__(self, "t_s", t[ok][order])
        object.__setattr__(self, "pos_m", p[ok][order])

    def position(self, t_s: float) -> FloatArray:
        t, p = self.t_s, self.pos_m
        nan = np.full(3, np.nan)
        if t.size == 0:
            return nan
        j = int(np.searchsorted(t, t_s))
        if j < t.size and abs(t[j] - t_s) <= self.tol_s:
            return p[j]
        if j > 0 and abs(t[j - 1] - t_s) <= self.tol_s:
            return p[j - 1]
        if j == 0 or j == t.size or t[j] - t[j - 1] > self.max_gap_s:
            return nan
        w = (t_s - t[j - 1]) / (t[j] - t[j - 1])
        return np.asarray((1.0 - w) * p[j - 1] + w * p[j], float)


@dataclass(frozen=True)
class Receiver:
    """A receiver: its name and, when known, its position source (None: to be estimated)."""

    name: str
    position: PositionSource | None = None


def as_position_source(pos: FloatArray | PositionSource) -> PositionSource:
    """A :class:`PositionSource` from a constant position (3,) or a source."""
    if hasattr(pos, "position"):
        return pos
    return FixedPosition(np.asarray(pos, float).reshape(3))


__all__ = ["FixedPosition", "PositionSource", "Receiver", "TrajectoryPosition", "as_position_source"]
