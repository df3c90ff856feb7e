"""The cooperation policy (Zhou et al. 2018 eqs. 24, 29, 30; algorithms.md §21).

The modes (:data:`COOPERATION`): ``off`` (no peer rows), ``traditional`` (the range
variance as measured, no inflation, no reset) and ``improved`` — the range variance inflated
by the peer's uncertainty, eq. 24, with the peer covariance reset at every update, eq. 29
(EKF, PF, LS) or eq. 30 (UKF), :func:`range_variance`; ``σ_set`` and ``σ_wset`` come from a
short window of the peer's broadcasts (:class:`PeerWindow`) unless given
(:class:`ResetSettings`). What a node broadcasts is a :class:`PeerBroadcast`.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from typing import Literal, get_args

import numpy as np

from robustrtk.core import FloatArray
from robustrtk.estimation.state import GaussianState

Cooperation = Literal["improved", "traditional", "off"]
#: Cooperation modes.
COOPERATION: tuple[str, ...] = get_args(Cooperation)


@dataclass(frozen=True)
class PeerBroadcast:
    """What a node broadcasts each epoch: its position and clock and their covariance.

    Attributes
    ----------
    node : str
    t_s : float
    x : ndarray, shape (4,)
        ``[x, y, z, b]`` (ECEF m; the first clock, m).
    P : ndarray, shape (4, 4)
        Covariance of ``x`` (m²).
    """

    node: str
    t_s: float
    x: FloatArray
    P: FloatArray

    @property
    def pos_ecef_m(self) -> FloatArray:
        return self.x[:3]

    @classmethod
    def of(cls, node: str, state: GaussianState) -> PeerBroadcast:
        """The ``[pos, first clock]`` block of a node's Gaussian summary."""
        idx = np.r_[state.layout.slice("pos"), state.layout.slice("clk").start]
        return cls(node, state.t_s, state.x[idx].copy(), state.P[np.ix_(idx, idx)].copy())


@dataclass(frozen=True)
class ResetSettings:
    """Covariance reset of the improved algorithm (eqs. 29–30).

    Attributes
    ----------
    sigma_set_m : float or None
        σ_set (m); None: the short-window estimate of :class:`PeerWindow`.
    sigma_wset_m_s : float or None
        σ_wset (m/s) of the UKF's process-noise block; None: short-window estimate.
    window : int
        Broadcasts in the short window (≥ 2).
    sigma_set_floor_m, sigma_wset_floor_m_s : float
        Floors of the window estimates (a window of identical broadcasts gives 0).
    """

    sigma_set_m: float | None = None
    sigma_wset_m_s: float | None = None
    window: int = 10
    sigma_set_floor_m: float = 0.5
    sigma_wset_floor_m_s: float = 0.01

    def __post_init__(self) -> None:
        if self.window < 2:
            raise ValueError("window must be at least 2")


class PeerWindow:
    """The last ``window`` broadcasts of one peer and the short-window σ_set, σ_wset.

    ``σ_set² = max(floor², mean_j var_j(p̂))`` — the sample variance (ddof 1) of each
    broadcast coordinate over the window, averaged over x, y, z; ``σ_wset² =
    max(floor², mean_j var_j(Δp̂ / Δt))`` of the coordinate rates between successive
    broadcasts (m²/s²). Fewer than two broadcasts (three for the rate) give the floors.
    """

    def __init__(self, settings: ResetSettings | None = None):
        self.settings = settings or ResetSettings()
        self._hist: deque[PeerBroadcast] = deque(maxlen=self.settings.window)

    def push(self, b: PeerBroadcast) -> None:
        """Add a broadcast (finite positions only)."""
        if np.all(np.isfinite(b.x[:3])):
            self._hist.append(b)

    def sigma_set2_m2(self) -> float:
        s = self.settings
        if s.sigma_set_m is not None:
            return float(s.sigma_set_m**2)
        floor = s.sigma_set_floor_m**2
        if len(self._hist) < 2:
            return floor
        p = np.array([b.x[:3] for b in self._hist])
        return float(max(floor, np.mean(np.var(p, axis=0, ddof=1))))

    def sigma_wset2_m2_s2(self) -> float:
        s = self.settings
        if s.sigma_wset_m_s is not None:
            return float(s.sigma_wset_m_s**2)
        floor = s.sigma_wset_floor_m_s**2
        if len(self._hist) < 3:
            return floor
        p = np.array([b.x[:3] for b in self._hist])
        t = np.array([b.t_s for b in self._hist])
        dt = np.diff(t)
        good = dt > 0
        if good.sum() < 2:
            return floor
        rate = np.diff(p, axis=0)[good] / dt[good, None]
        return float(max(floor, np.mean(np.var(rate, axis=0, ddof=1))))


def reset_covariance(
    sigma_set2_m2: float, kind: str, sigma_wset2_m2_s2: float = 0.0, n_state: int = 4, n_noise: int = 4
) -> FloatArray:
    """The reset peer covariance: eq. 29 ``σ_set² I₄`` (EKF, PF, LS) or, for the UKF,
    eq. 30 ``blockdiag(σ_set² I₄, σ_wset² I_n)`` (the augmented state's noise block)."""
    if kind == "ukf":
        return np.diag(np.r_[np.full(n_state, sigma_set2_m2), np.full(n_noise, sigma_wset2_m2_s2)])
    return np.eye(n_state) * sigma_set2_m2


def range_variance(
    sigma_range2_m2: float,
    broadcast: PeerBroadcast,
    cooperation: str,
    kind: str,
    window: PeerWindow | None = None,
    dt_s: float = 1.0,
) -> float:
    """Variance σ̂² of one range row to ``broadcast.node`` (m²).

    * ``traditional``: ``σ²`` (no inflation, no reset);
    * ``improved``: eq. 24 ``σ̂² = σ² + tr(P̃_n)`` with the reset covariance ``P̃_n`` of
      :func:`reset_covariance` — ``tr = 4 σ_set²`` (eq. 29) or, for the UKF (eq. 30),
      ``4 σ_set² + 4 σ_wset² Δt²`` (the noise block mapped to metres by ``W = Δt I`` of
      eq. 8, so the trace adds like units).

    ``off`` has no range rows (``ValueError``).
    """
    if cooperation == "traditional":
        return float(sigma_range2_m2)
    if cooperation != "improved":
        raise ValueError(f"cooperation {cooperation!r} has no range rows")
    win = window if window is not None else PeerWindow()
    s2 = win.sigma_set2_m2()
    w2 = win.sigma_wset2_m2_s2() * dt_s**2 if kind == "ukf" else 0.0
    Pn = reset_covariance(s2, kind, w2)
    return float(sigma_range2_m2 + np.trace(Pn))


__all__ = [
    "COOPERATION",
    "Cooperation",
    "PeerBroadcast",
    "PeerWindow",
    "ResetSettings",
    "range_variance",
    "reset_covariance",
]
