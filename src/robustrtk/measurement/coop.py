"""Measurement models of cooperative positioning (Zhou et al. 2018, algorithms.md §21).

A cooperating node ``m`` has the state ``x_m = [p_m (3, ECEF m), b_m,1 .. b_m,c (m)]`` —
its position and one receiver clock per satellite system (optionally a velocity block,
which no measurement here touches). Its rows are

* its own pseudoranges (eq. 10), corrected for the satellite clock and the atmosphere::

      z_i = P_i + c dt_i − I_i − T_i = |p_m − s_i| + sagnac_i(p_m) + b_m,sys(i) + e_i

  with :func:`zhou_code_variance` (eq. 25 scaled to metres) as ``var(e_i)``;
* the range to each peer ``n`` (eq. 11)::

      r_nm = |p_m − p̂_n| + e_nm,    var(e_nm) = σ̂²_nm  (eq. 24, inflated by the peer's
      uncertainty, see :mod:`robustrtk.estimation.coop`)

  with ``p̂_n`` the position the peer broadcast.

Both models evaluate ``h`` on a batch of states ``(..., n)`` (sigma points, particles) and
give the Jacobian for the EKF; they work on any state vector in which the node's position
starts at ``pos_start`` and its clocks sit at ``clk_index`` — a single node's state or the
joint state of the centralised filter (:class:`InterNodeRangeModel` is the range between
two position blocks of one joint state). Rows stack with
:class:`robustrtk.measurement.dd.StackedModel`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
import numpy.typing as npt

from robustrtk.core import CLIGHT, FloatArray
from robustrtk.geometry.los import OMEGA_E_RAD_S
from robustrtk.io.rinex_nav import NavData
from robustrtk.measurement.undifferenced import ELEV_FLOOR_RAD, EpochGeometry, atmosphere


def zhou_code_variance(
    elev_rad: npt.ArrayLike,
    cn0_dbhz: npt.ArrayLike | None,
    *,
    sigma0_m: float = 3.0,
    cn0_ref_dbhz: float = 45.0,
    elev_floor_rad: float = ELEV_FLOOR_RAD,
) -> FloatArray:
    """Pseudorange variance of Zhou et al. eq. 25 (Tay & Marais), scaled to metres.

    Eq. 25 reads ``σ² = 10^(−0.1 C/N0) / sin²(θ)`` without a unit. With the scale
    ``K = σ0² · 10^(0.1 C/N0_ref)`` (m²) chosen so that a satellite at the zenith with
    ``C/N0 = C/N0_ref`` has the standard deviation ``σ0``::

        σ_i² = K · 10^(−0.1 C/N0_i) / sin²(max(θ_i, θ_floor))
             = σ0² · 10^(0.1 (C/N0_ref − C/N0_i)) / sin²(max(θ_i, θ_floor))   [m²]

    (algorithms.md §21.2). Unlike
    :func:`robustrtk.measurement.undifferenced.elevation_cn0_variance` there is no clamp:
    a C/N0 above the reference lowers the variance, as eq. 25 does.

    Parameters
    ----------
    elev_rad : array_like, shape (m,)
        Elevation θ (rad), floored at ``elev_floor_rad``.
    cn0_dbhz : array_like, shape (m,), or None
        Measured C/N0 (dB-Hz); None or NaN entries count as ``cn0_ref_dbhz`` (files
        without S1 observations).
    sigma0_m : float
        Zenith standard deviation at the reference C/N0 (m).
    cn0_ref_dbhz : float
        Reference C/N0 (dB-Hz).
    elev_floor_rad : float

    Returns
    -------
    ndarray, shape (m,)
        Variances (m²).
    """
    el = np.maximum(np.asarray(elev_rad, float), elev_floor_rad)
    if cn0_dbhz is None:
        c = np.full(el.shape, cn0_ref_dbhz)
    else:
        c = np.nan_to_num(np.asarray(cn0_dbhz, float), nan=cn0_ref_dbhz)
    out: FloatArray = sigma0_m**2 * 10.0 ** (0.1 * (cn0_ref_dbhz - c)) / np.sin(el) ** 2
    return out


def _range_sagnac(sat_m: FloatArray, pos: FloatArray) -> FloatArray:
    """``|s − p| + ω_e (s_x p_y − s_y p_x)/c`` for ``pos`` (..., 3), ``sat_m`` (m, 3) → (..., m).

    For a batch the squared distance is expanded about a reference point ``c`` (the first
    position): ``|s' − p'|² = |s'|² − 2 s'·p' + |p'|²`` with ``s' = s − c``, ``p' = p − c``,
    one matrix product for the whole batch; ``|p'|`` is small, so the round-off stays
    below a micrometre.
    """
    if pos.ndim == 1:
        d = sat_m - pos
        rng1: FloatArray = np.sqrt(np.einsum("ij,ij->i", d, d))
        return rng1 + OMEGA_E_RAD_S * (sat_m[:, 0] * pos[1] - sat_m[:, 1] * pos[0]) / CLIGHT
    flat = pos.reshape(-1, 3)
    c = flat[0]
    sp = sat_m - c
    pp = flat - c
    r2 = (
        np.einsum("ij,ij->i", sp, sp)[None, :]
        - 2.0 * (pp @ np.ascontiguousarray(sp.T))
        + np.einsum("ij,ij->i", pp, pp)[:, None]
    )
    sag = (OMEGA_E_RAD_S / CLIGHT) * np.array([-sat_m[:, 1], sat_m[:, 0]])  # (2, m)
    rng = np.sqrt(np.maximum(r2, 0.0)) + flat[:, :2] @ sag
    out: FloatArray = rng.reshape(pos.shape[:-1] + (sat_m.shape[0],))
    return out


class _DiagonalRows:
    """What the measurement models below share: independent rows, ``R = diag(var_m2)``,
    and rows named ``<prefix>0``, ``<prefix>1``... unless ``labels`` names every row of ``z``."""

    _label_prefix: ClassVar[str] = ""
    z: FloatArray
    var_m2: FloatArray
    labels: tuple[str, ...]

    def __post_init__(self) -> None:
        m = np.shape(self.z)[0]
        if len(self.labels) != m:
            object.__setattr__(self, "labels", tuple(f"{self._label_prefix}{i}" for i in range(m)))

    @property
    def R(self) -> FloatArray:
        """``diag(var_m2)`` (m²)."""
        return np.diag(np.asarray(self.var_m2, float))


@dataclass(frozen=True)
class PseudorangeModel(_DiagonalRows):
    """A node's own corrected pseudoranges (Zhou et al. eq. 10).

    ``h(x)_i = |p − s_i| + ω_e (s_x,i p_y − s_y,i p_x)/c + x[clk_index_i]`` with
    ``p = x[pos_start : pos_start + 3]``.

    Attributes
    ----------
    z : ndarray, shape (m,)
        ``P + c dt_sat − I − T`` (m).
    sat_pos_m : ndarray, shape (m, 3)
        Satellite ECEF positions at transmission time (m).
    var_m2 : ndarray, shape (m,)
        Row variances (m²), e.g. :func:`zhou_code_variance`.
    clk_index : ndarray of int, shape (m,)
        State index of the clock each row sees.
    pos_start : int
        State index of the node's x coordinate.
    n_state : int
        Size of the state vector the model acts on.
    labels : tuple of str, length m
        Row names (``"G05:P"``); numbered ``P0, P1, ..`` when not one per row.
    """

    z: FloatArray
    sat_pos_m: FloatArray
    var_m2: FloatArray
    clk_index: npt.NDArray[np.int64]
    pos_start: int
    n_state: int
    labels: tuple[str, ...] = ()
    _label_prefix: ClassVar[str] = "P"

    def h(self, X: FloatArray) -> FloatArray:
        """Predicted pseudoranges for states ``X`` (..., n) → (..., m)."""
        Xa = np.asarray(X, float)
        pos = Xa[..., self.pos_start : self.pos_start + 3]
        return _range_sagnac(self.sat_pos_m, pos) + Xa[..., self.clk_index]

    def jacobian(self, x: FloatArray) -> FloatArray:
        """``∂h/∂x`` (m, n): ``−u_i`` (unit line of sight) plus the Sagnac term
        ``ω_e (−s_y, s_x, 0)/c`` on the position, 1 on the clock."""
        xa = np.asarray(x, float)
        pos = xa[self.pos_start : self.pos_start + 3]
        d = self.sat_pos_m - pos
        u = d / np.linalg.norm(d, axis=1)[:, None]
        m = self.z.shape[0]
        H = np.zeros((m, self.n_state))
        H[:, self.pos_start : self.pos_start + 3] = -u
        H[:, self.pos_start] -= OMEGA_E_RAD_S * self.sat_pos_m[:, 1] / CLIGHT
        H[:, self.pos_start + 1] += OMEGA_E_RAD_S * self.sat_pos_m[:, 0] / CLIGHT
        H[np.arange(m), self.clk_index] += 1.0
        return H


@dataclass(frozen=True)
class PeerRangeModel(_DiagonalRows):
    """Ranges from the node to peers at broadcast positions (Zhou et al. eq. 11).

    ``h(x)_k = |p − p̂_k|`` with ``p = x[pos_start : pos_start + 3]``.

    Attributes
    ----------
    z : ndarray, shape (k,)
        Measured inter-node ranges (m).
    peer_pos_m : ndarray, shape (k, 3)
        Broadcast ECEF positions of the peers (m).
    var_m2 : ndarray, shape (k,)
        Range variances σ̂² (m²), already inflated as the cooperation mode says (eq. 24).
    pos_start, n_state : int
        As in :class:`PseudorangeModel`.
    labels : tuple of str
        Row names (``"range:node1"``).
    """

    z: FloatArray
    peer_pos_m: FloatArray
    var_m2: FloatArray
    pos_start: int
    n_state: int
    labels: tuple[str, ...] = ()
    _label_prefix: ClassVar[str] = "range:"

    def h(self, X: FloatArray) -> FloatArray:
        """Predicted ranges for states ``X`` (..., n) → (..., k)."""
        pos = np.asarray(X, float)[..., None, self.pos_start : self.pos_start + 3]
        d = pos - self.peer_pos_m
        out: FloatArray = np.sqrt(np.einsum("...ij,...ij->...i", d, d))
        return out

    def jacobian(self, x: FloatArray) -> FloatArray:
        """``∂h/∂x`` (k, n): the unit vector from the peer to the node on the position."""
        pos = np.asarray(x, float)[self.pos_start : self.pos_start + 3]
        d = pos - self.peer_pos_m
        u = d / np.linalg.norm(d, axis=1)[:, None]
        H = np.zeros((self.z.shape[0], self.n_state))
        H[:, self.pos_start : self.pos_start + 3] = u
        return H


@dataclass(frozen=True)
class NodeRows:
    """One node's rows of one epoch: its pseudoranges, then its ranges to peers (eqs. 10–11).

    The rows of ``StackedModel((pseudoranges, ranges))`` with ``z``, ``R`` and ``labels``
    assembled once (a filter update reads them several times) and ``h``, ``jacobian`` those of
    the parts, stacked — the same numbers.

    Attributes
    ----------
    pseudoranges : PseudorangeModel
    ranges : PeerRangeModel
        On the same state (``n_state``); may have no rows.
    """

    pseudoranges: PseudorangeModel
    ranges: PeerRangeModel
    z: FloatArray = field(init=False)
    R: FloatArray = field(init=False)
    labels: tuple[str, ...] = field(init=False)

    def __post_init__(self) -> None:
        pr, rm = self.pseudoranges, self.ranges
        z = np.concatenate([np.asarray(pr.z, float), np.asarray(rm.z, float)])
        var = np.concatenate([np.asarray(pr.var_m2, float), np.asarray(rm.var_m2, float)])
        object.__setattr__(self, "z", z)
        object.__setattr__(self, "R", np.diag(var))
        object.__setattr__(self, "labels", tuple(pr.labels) + tuple(rm.labels))

    def h(self, X: FloatArray) -> FloatArray:
        """Predicted rows for states ``X`` (..., n) → (..., m)."""
        if self.ranges.z.shape[0] == 0:
            return self.pseudoranges.h(X)
        return np.concatenate([self.pseudoranges.h(X), self.ranges.h(X)], axis=-1)

    def jacobian(self, x: FloatArray) -> FloatArray:
        """``∂h/∂x`` (m, n): the parts' rows stacked."""
        if self.ranges.z.shape[0] == 0:
            return self.pseudoranges.jacobian(x)
        return np.vstack([self.pseudoranges.jacobian(x), self.ranges.jacobian(x)])


@dataclass(frozen=True)
class InterNodeRangeModel(_DiagonalRows):
    """Ranges between two position blocks of one joint state (the centralised filter).

    ``h(x)_k = |x[a_k : a_k + 3] − x[b_k : b_k + 3]|``.

    Attributes
    ----------
    z : ndarray, shape (k,)
    var_m2 : ndarray, shape (k,)
        Range variances (m²), not inflated: the joint state carries the correlation.
    pos_a, pos_b : ndarray of int, shape (k,)
        State indices of the two nodes' x coordinates.
    n_state : int
    labels : tuple of str
    """

    z: FloatArray
    var_m2: FloatArray
    pos_a: npt.NDArray[np.int64]
    pos_b: npt.NDArray[np.int64]
    n_state: int
    labels: tuple[str, ...] = ()
    _label_prefix: ClassVar[str] = "range:"

    def _diff(self, X: FloatArray) -> FloatArray:
        Xa = np.asarray(X, float)
        ia = self.pos_a[:, None] + np.arange(3)
        ib = self.pos_b[:, None] + np.arange(3)
        out: FloatArray = Xa[..., ia] - Xa[..., ib]
        return out

    def h(self, X: FloatArray) -> FloatArray:
        d = self._diff(X)
        out: FloatArray = np.sqrt(np.einsum("...ij,...ij->...i", d, d))
        return out

    def jacobian(self, x: FloatArray) -> FloatArray:
        d = self._diff(np.asarray(x, float))
        u = d / np.linalg.norm(d, axis=1)[:, None]
        k = self.z.shape[0]
        H = np.zeros((k, self.n_state))
        for r in range(k):
            H[r, self.pos_a[r] : self.pos_a[r] + 3] += u[r]
            H[r, self.pos_b[r] : self.pos_b[r] + 3] -= u[r]
        return H


def node_pseudoranges(
    t_s: float,
    geom: EpochGeometry,
    use: npt.ArrayLike,
    pos_guess_m: FloatArray,
    nav: NavData,
    clock_of_system: dict[str, int],
    *,
    pos_start: int,
    n_state: int,
    sigma0_m: float = 3.0,
    cn0_ref_dbhz: float = 45.0,
    use_cn0: bool = True,
    elev_mask_deg: float = 10.0,
    tropo: str = "saastamoinen",
    iono: str = "klobuchar",
) -> PseudorangeModel:
    """The :class:`PseudorangeModel` of one node and epoch.

    Atmospheric delays and elevations are computed at ``pos_guess_m`` (the prior mean):
    ``z_i = P_i + c (dt_i − T_GD) − I_i − T_i``. Rows kept: ``use & geom.ok``, elevation at
    or above the mask, system in ``clock_of_system``.

    Parameters
    ----------
    t_s : float
        Epoch (GPST s).
    geom : EpochGeometry
        Satellite states and codes of the epoch.
    use : array_like of bool, shape (len(geom.ids),)
        Rows the caller allows (e.g. not occluded).
    pos_guess_m : ndarray, shape (3,)
        Linearisation point for the atmosphere and elevation (ECEF m).
    nav : NavData
        Klobuchar coefficients.
    clock_of_system : dict str -> int
        State index of the clock of each system letter.
    pos_start, n_state : int
        Where the node's position starts in the state, and the state size.
    sigma0_m, cn0_ref_dbhz, use_cn0 :
        :func:`zhou_code_variance` (without C/N0 every row counts as the reference).
    elev_mask_deg : float
    tropo, iono : str
        Models of :func:`robustrtk.measurement.undifferenced.atmosphere`.
    """
    ok = np.asarray(use, bool) & geom.ok
    ok &= np.array([s in clock_of_system for s in geom.sys], bool) if geom.sys else np.zeros(0, bool)
    atm = atmosphere(t_s, geom.sat_pos_m, np.asarray(pos_guess_m, float), nav, tropo, iono, geom.freq_hz)
    ok &= atm.el_rad >= np.deg2rad(elev_mask_deg)
    idx = np.flatnonzero(ok)
    z = geom.code_m[idx] + geom.sat_clk_m[idx] - atm.code_delay_m[idx]
    var = zhou_code_variance(
        atm.el_rad[idx],
        geom.cn0_dbhz[idx] if use_cn0 else None,
        sigma0_m=sigma0_m,
        cn0_ref_dbhz=cn0_ref_dbhz,
    )
    clk = np.array([clock_of_system[geom.sys[j]] for j in idx], dtype=np.int64)
    return PseudorangeModel(
        z=z,
        sat_pos_m=geom.sat_pos_m[idx],
        var_m2=var,
        clk_index=clk,
        pos_start=pos_start,
        n_state=n_state,
        labels=tuple(f"{geom.ids[j]}:P" for j in idx),
    )


__all__ = [
    "InterNodeRangeModel",
    "NodeRows",
    "PeerRangeModel",
    "PseudorangeModel",
    "node_pseudoranges",
    "zhou_code_variance",
]
