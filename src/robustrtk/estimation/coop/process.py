"""The process model of a cooperative node (Zhou et al. 2018 eq. 8; algorithms.md §21).

:class:`LocationTimeModel` — ``x_t = x_t−1 + Δt w``, ``w ~ N(0, Q̃)``,
``Q̃ = diag(σ_ẋ², σ_ẏ², σ_ż², σ_ḃ²)`` in m²/s² — and the node's state layout
(:func:`node_layout`: ``[p (3), b_1 .. b_c]``, ECEF m and one clock per system in metres).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from robustrtk.core import FloatArray
from robustrtk.estimation.state import StateLayout


def node_layout(n_clocks: int = 1, velocity: bool = False) -> StateLayout:
    """``[pos(3), clk(n_clocks)]`` (+ ``vel(3)`` after the clocks when ``velocity``)."""
    blocks: tuple[tuple[str, int], ...] = (("pos", 3), ("clk", n_clocks))
    if velocity:
        blocks = blocks + (("vel", 3),)
    return StateLayout(blocks=blocks)


def clock_index(layout: StateLayout, systems: Sequence[str]) -> dict[str, int]:
    """State index of the clock of each system (in the order given)."""
    s = layout.slice("clk")
    if len(systems) > s.stop - s.start:
        raise ValueError(f"{len(systems)} systems but the layout has {s.stop - s.start} clocks")
    return {sys: s.start + k for k, sys in enumerate(systems)}


@dataclass(frozen=True)
class LocationTimeModel:
    """Location-time process model, Zhou et al. eq. 8::

        x_t = F x_t−1 + W w_t,   F = I,  W = Δt I,  w_t ~ N(0, Q̃),
        Q̃ = diag(σ_pos² I₃, σ_clk² I_c)   (m²/s²),   Q = W Q̃ Wᵀ = Δt² Q̃   (m²).

    With a ``vel`` block the position integrates it (``F[pos, vel] = Δt I``) and the
    velocity is driven by ``σ_acc`` (m/s²): ``Q̃_vel = σ_acc² I``, ``W_vel = Δt I``.

    Attributes
    ----------
    sigma_pos_m_s : float
        σ_ẋ = σ_ẏ = σ_ż, the position rate noise (m/s); small for a static node.
    sigma_clk_m_s : float
        σ_ḃ, the clock rate noise (m/s).
    sigma_acc_m_s2 : float
        Velocity noise (only with a ``vel`` block).
    """

    sigma_pos_m_s: float = 0.01
    sigma_clk_m_s: float = 100.0
    sigma_acc_m_s2: float = 1.0
    name: str = "location-time"

    def blocks(self) -> tuple[tuple[str, int], ...]:
        return (("pos", 3), ("clk", 1))

    def noise_input(self, layout: StateLayout, dt_s: float) -> tuple[FloatArray, FloatArray]:
        """``W`` (n, n) and ``Q̃`` (n, n, m²/s²) of eq. 8 for ``layout`` (read-only arrays,
        memoised per model, layout and interval)."""
        return _location_time(self, layout, float(dt_s))[2:]

    def transition(self, layout: StateLayout, dt_s: float) -> tuple[FloatArray, FloatArray]:
        """``F`` and ``Q = W Q̃ Wᵀ`` (m²) over ``dt_s`` (read-only, memoised)."""
        return _location_time(self, layout, float(dt_s))[:2]

    def _build(
        self, layout: StateLayout, dt_s: float
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        n = layout.size
        q = np.zeros(n)
        q[layout.slice("pos")] = self.sigma_pos_m_s**2
        q[layout.slice("clk")] = self.sigma_clk_m_s**2
        if layout.has("vel"):
            q[layout.slice("vel")] = self.sigma_acc_m_s2**2
        W = np.eye(n) * abs(dt_s)
        Qw = np.diag(q)
        F = np.eye(n)
        if layout.has("vel"):
            F[layout.slice("pos"), layout.slice("vel")] = np.eye(3) * dt_s
        out = (F, W @ Qw @ W.T, W, Qw)
        for a in out:
            a.setflags(write=False)
        return out


@functools.lru_cache(maxsize=256)
def _location_time(
    model: LocationTimeModel, layout: StateLayout, dt_s: float
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    return model._build(layout, dt_s)


__all__ = ["LocationTimeModel", "clock_index", "node_layout"]
