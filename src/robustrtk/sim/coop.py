"""Two static cooperating nodes simulated from real broadcast orbits (Zhou et al. 2018 study;
algorithms.md §25).

The satellites are those of a RINEX navigation file, propagated by the broadcast ephemerides
(:class:`robustrtk.geometry.ephemeris.EphemerisSource`) at the simulated epochs; the
receivers are placed where the scenario says (by default the paper's node 1, ECEF
(−1702129.484, 5010430.822, 3549570.165) m, and node 2 at ENU (−5.1861, −0.8038, −3.9173) m
from it, a 6.5488 m baseline). Per node and epoch the simulation gives *corrected*
pseudoranges — satellite clock, ionosphere and troposphere already removed, as a receiver's
pre-processing would leave them — in the form of eq. 10::

    z_i = |p − s_i| + ω_e (s_x,i p_y − s_y,i p_x) / c + b_sys(i) + m_i + e_i + f_i

* ``s_i`` the satellite position at transmission time, ``p`` the true node position;
* ``b_sys`` the receiver clock per system (m): a random walk ``b_k = b_k−1 + Δt σ_ḃ ν``
  started at a seeded offset, the BeiDou clock = GPS clock + a seeded inter-system bias;
* ``e_i ~ N(0, σ_i²)`` with the eq. 25 variance scaled to metres
  (:func:`robustrtk.measurement.coop.zhou_code_variance`),
  ``σ_i² = σ0² 10^(0.1 (C/N0_ref − C/N0_i)) / sin² θ_i``;
* ``C/N0_i = cn0_zenith − cn0_slope (1 − sin θ_i) − attenuation + u_i`` (dB-Hz), ``u_i`` a
  seeded per-satellite offset (``N(0, cn0_jitter²)``), ``attenuation`` 0 in the open sky
  and the window loss for node 2;
* ``m_i`` a first-order Gauss–Markov multipath error (``σ_mp``, correlation time ``τ_mp``;
  node 2 only by default — the indoor node sees reflections);
* ``f_i`` a fault: ``+bias_m`` on ``n_bias_sats`` seeded satellites of node 1 over a stretch
  of epochs (the degraded runs).

Node 2's sky is a windowsill: satellites with azimuth within ``sector_half_width_deg`` of
``sector_centre_deg`` and elevation in ``[elev_mask_deg, sector_max_elev_deg]``; of those at
most ``max_gps`` GPS and ``max_bds`` BeiDou are kept (highest elevation first, fixed for
the session), and each kept satellite is lost at an epoch with probability
``dropout_prob`` (seeded), so the count changes as in the paper's Fig. 8.

The inter-node range (the DD carrier-phase baseline of the paper) is the true distance plus
``N(0, range_sigma_m²)`` per epoch.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from robustrtk.core import FloatArray, InputError
from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.geometry.frames import ecef2geodetic, enu2ecef_vector
from robustrtk.geometry.los import azimuth_elevation, geometric_range
from robustrtk.io.rinex_nav import NavData
from robustrtk.measurement.coop import zhou_code_variance

#: The paper's node 1 (ECEF m, Zhou et al. Sec. 3.3.1).
ZHOU_NODE1_ECEF_M: tuple[float, float, float] = (-1702129.484, 5010430.822, 3549570.165)
#: Node 2 in node 1's ENU frame (m); |B| = 6.5488 m.
ZHOU_NODE2_ENU_M: tuple[float, float, float] = (-5.1861, -0.8038, -3.9173)
#: Systems simulated (GPS and BeiDou, as in the paper).
SYSTEMS: tuple[str, ...] = ("G", "C")


@dataclass(frozen=True)
class CoopNodeSpec:
    """How one node sees the sky and what its receiver adds.

    Attributes
    ----------
    attenuation_db : float
        C/N0 loss of every signal (dB).
    sector_centre_deg, sector_half_width_deg : float or None
        Windowsill azimuth sector (from north, clockwise); None: the whole sky.
    sector_max_elev_deg : float
        Highest elevation seen through the window (deg).
    max_gps, max_bds : int or None
        At most this many GPS / BeiDou satellites of the sector (None: all).
    dropout_prob : float
        Probability that a kept satellite is lost at an epoch.
    multipath_sigma_m, multipath_tau_s : float
        Gauss–Markov multipath: stationary σ (m) and correlation time (s).
    """

    attenuation_db: float = 0.0
    sector_centre_deg: float | None = None
    sector_half_width_deg: float = 90.0
    sector_max_elev_deg: float = 90.0
    max_gps: int | None = None
    max_bds: int | None = None
    dropout_prob: float = 0.0
    multipath_sigma_m: float = 0.0
    multipath_tau_s: float = 30.0


@dataclass(frozen=True)
class CoopSimSpec:
    """The two-node scenario (defaults: the paper's study on 1 Hz epochs).

    Attributes
    ----------
    t0_s : float
        First epoch (GPST s).
    n_epochs : int
    dt_s : float
    node1_ecef_m : tuple of float
    node2_enu_m : tuple of float
        Node 2 relative to node 1, ENU at node 1 (m).
    node1, node2 : CoopNodeSpec
    elev_mask_deg : float
    sigma0_m, cn0_ref_dbhz : float
        Eq. 25 scale: σ0 at the zenith and C/N0 = C/N0_ref.
    cn0_zenith_dbhz, cn0_slope_db, cn0_jitter_db : float
        C/N0 model (module notes).
    clock_rw_m_s : float
        Receiver clock random-walk rate σ_ḃ (m/s).
    isb_sigma_m : float
        σ of the seeded BeiDou–GPS inter-system bias (m).
    range_sigma_m : float
        Inter-node range noise (m).
    bias_m : float
        Code fault of node 1 in degraded runs (m).
    n_bias_sats : int
    bias_epochs : tuple of int
        ``(first, stop)`` epoch indices of the fault.
    """

    t0_s: float
    n_epochs: int = 50
    dt_s: float = 1.0
    node1_ecef_m: tuple[float, float, float] = ZHOU_NODE1_ECEF_M
    node2_enu_m: tuple[float, float, float] = ZHOU_NODE2_ENU_M
    node1: CoopNodeSpec = field(default_factory=CoopNodeSpec)
    node2: CoopNodeSpec = field(
        default_factory=lambda: CoopNodeSpec(
            attenuation_db=10.0,
            sector_centre_deg=200.0,
            sector_half_width_deg=75.0,
            sector_max_elev_deg=70.0,
            max_gps=3,
            max_bds=5,
            dropout_prob=0.1,
            multipath_sigma_m=2.0,
            multipath_tau_s=20.0,
        )
    )
    elev_mask_deg: float = 10.0
    sigma0_m: float = 1.0
    cn0_ref_dbhz: float = 45.0
    cn0_zenith_dbhz: float = 48.0
    cn0_slope_db: float = 12.0
    cn0_jitter_db: float = 2.0
    clock_rw_m_s: float = 1.0
    isb_sigma_m: float = 10.0
    range_sigma_m: float = 0.02
    bias_m: float = 20.0
    n_bias_sats: int = 2
    bias_epochs: tuple[int, int] = (20, 35)

    def __post_init__(self) -> None:
        if self.n_epochs < 2:
            raise InputError(f"n_epochs: expected at least 2, got {self.n_epochs}")
        if self.dt_s <= 0:
            raise InputError(f"dt_s: expected a positive interval, got {self.dt_s}")


@dataclass(frozen=True)
class CoopNodeData:
    """One simulated node.

    Attributes
    ----------
    truth_ecef_m : ndarray, shape (3,)
    sat_ids : tuple of str, length S
        Satellites of the navigation file considered (same columns for every epoch).
    sat_pos_m : ndarray, shape (T, S, 3)
        Satellite ECEF at transmission time (NaN: no ephemeris).
    code_m : ndarray, shape (T, S)
        Corrected pseudoranges (NaN: not seen).
    var_m2 : ndarray, shape (T, S)
        Eq. 25 variances of the rows (what a receiver would report; NaN: not seen).
    elev_rad, cn0_dbhz : ndarray, shape (T, S)
    clock_m : ndarray, shape (T, 2)
        True receiver clocks of GPS and BeiDou (m).
    fault_m : ndarray, shape (T, S)
        The injected code fault (0 where none).
    """

    truth_ecef_m: FloatArray
    sat_ids: tuple[str, ...]
    sat_pos_m: FloatArray
    code_m: FloatArray
    var_m2: FloatArray
    elev_rad: FloatArray
    cn0_dbhz: FloatArray
    clock_m: FloatArray
    fault_m: FloatArray

    @property
    def system(self) -> tuple[str, ...]:
        return tuple(s[0] for s in self.sat_ids)

    def n_seen(self, system: str) -> FloatArray:
        """Satellites of ``system`` seen at each epoch, shape (T,)."""
        col = np.array([s == system for s in self.system], bool)
        out: FloatArray = np.isfinite(self.code_m[:, col]).sum(axis=1).astype(float)
        return out


@dataclass(frozen=True)
class CoopSim:
    """Output of :func:`simulate_coop`: both nodes, the ranges, the epochs."""

    t_s: FloatArray
    nodes: tuple[CoopNodeData, CoopNodeData]
    range_m: FloatArray
    range_sigma_m: float
    true_range_m: float
    degraded: bool


def _sat_ids(nav: NavData) -> tuple[str, ...]:
    ids: set[str] = set()
    for s in SYSTEMS:
        if nav.n_records(s) > 0:
            ids.update(str(x) for x in nav.kepler[s].sat_id)
    return tuple(sorted(ids))


def _node_geometry(
    eph: EphemerisSource, t_s: FloatArray, ids: tuple[str, ...], pos_m: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    T, S = t_s.size, len(ids)
    sat = np.full((T, S, 3), np.nan)
    rng_m = np.full((T, S), np.nan)
    az = np.full((T, S), np.nan)
    el = np.full((T, S), np.nan)
    for k, t in enumerate(t_s):
        p, clk = eph.positions(float(t), ids)
        ok = np.isfinite(clk)
        # transmission time from the geometric travel time (second pass)
        r0, _ = geometric_range(np.where(ok[:, None], p, 0.0), pos_m)
        p, clk = eph.positions(float(t), ids, np.where(ok, r0, np.nan))
        ok = np.isfinite(clk)
        sat[k, ok] = p[ok]
        rng_m[k, ok], _ = geometric_range(p[ok], pos_m)
        a, e = azimuth_elevation(p[ok], pos_m)
        az[k, ok], el[k, ok] = a, e
    return sat, rng_m, az, el


def windowsill_visible(
    ids: tuple[str, ...], az_rad: FloatArray, elev_rad: FloatArray, spec: CoopNodeSpec, elev_mask_deg: float
) -> np.ndarray:
    """Satellites a node sees before dropouts, shape (T, S) of bool.

    Open sky: elevation ≥ mask. Windowsill: also within the azimuth sector and below
    ``sector_max_elev_deg``; then of the satellites in the sector at the first epoch, the
    ``max_gps`` GPS and ``max_bds`` BeiDou of highest mean elevation over the session are
    kept for every epoch at which they stay in the sector.
    """
    el_deg = np.degrees(np.nan_to_num(elev_rad, nan=-90.0))
    vis = el_deg >= elev_mask_deg
    if spec.sector_centre_deg is None:
        return vis
    daz = (np.degrees(np.nan_to_num(az_rad, nan=0.0)) - spec.sector_centre_deg + 180.0) % 360.0 - 180.0
    vis &= (np.abs(daz) <= spec.sector_half_width_deg) & (el_deg <= spec.sector_max_elev_deg)
    keep = np.zeros(len(ids), bool)
    mean_el = np.where(vis, el_deg, np.nan)
    score = np.array([np.nanmean(c) if np.any(np.isfinite(c)) else -np.inf for c in mean_el.T])
    for sys_letter, cap in (("G", spec.max_gps), ("C", spec.max_bds)):
        cols = [i for i, s in enumerate(ids) if s[0] == sys_letter and vis[0, i]]
        cols.sort(key=lambda i: -score[i])
        keep[cols if cap is None else cols[:cap]] = True
    out: np.ndarray = vis & keep[None, :]
    return out


def _cn0(elev_rad: FloatArray, spec: CoopSimSpec, node: CoopNodeSpec, rng: np.random.Generator) -> FloatArray:
    S = elev_rad.shape[1]
    jitter = rng.normal(0.0, spec.cn0_jitter_db, S)
    s = np.sin(np.clip(np.nan_to_num(elev_rad, nan=0.0), 0.0, None))
    out: FloatArray = spec.cn0_zenith_dbhz - spec.cn0_slope_db * (1.0 - s) - node.attenuation_db + jitter
    return out


def _clocks(T: int, spec: CoopSimSpec, rng: np.random.Generator) -> FloatArray:
    b0 = rng.uniform(-3e5, 3e5)
    steps = rng.normal(0.0, spec.clock_rw_m_s * spec.dt_s, T)
    steps[0] = 0.0
    gps = b0 + np.cumsum(steps)
    isb = rng.normal(0.0, spec.isb_sigma_m)
    out: FloatArray = np.stack([gps, gps + isb], axis=1)
    return out


def _gauss_markov(
    T: int, S: int, sigma_m: float, tau_s: float, dt_s: float, rng: np.random.Generator
) -> FloatArray:
    """``m_k = φ m_k−1 + √(1 − φ²) σ ν_k``, ``φ = exp(−Δt/τ)``, stationary from the start."""
    out = np.zeros((T, S))
    if sigma_m <= 0:
        return out
    phi = float(np.exp(-dt_s / tau_s))
    out[0] = rng.normal(0.0, sigma_m, S)
    q = sigma_m * np.sqrt(1.0 - phi**2)
    for k in range(1, T):
        out[k] = phi * out[k - 1] + q * rng.normal(0.0, 1.0, S)
    return out


def simulate_coop(
    nav: NavData | EphemerisSource, spec: CoopSimSpec, rng: np.random.Generator, *, degraded: bool = False
) -> CoopSim:
    """Simulate both nodes and the inter-node range (module notes).

    Parameters
    ----------
    nav : NavData or EphemerisSource
        Broadcast orbits (GPS and BeiDou records used).
    spec : CoopSimSpec
    rng : numpy.random.Generator
        All randomness (noise, clocks, C/N0 offsets, dropouts, fault satellites). The
        draws do not depend on ``degraded``, so a clean and a degraded run of one seed
        differ only by the fault.
    degraded : bool
        Add node 1's code fault.

    Raises
    ------
    InputError
        No GPS or BeiDou ephemeris valid at the epochs, or node 1 sees fewer than
        ``n_bias_sats + 4`` satellites.
    """
    eph = nav if isinstance(nav, EphemerisSource) else EphemerisSource(nav)
    ids = _sat_ids(eph.nav)
    if not ids:
        raise InputError("navigation data: no GPS or BeiDou ephemerides")
    t = spec.t0_s + spec.dt_s * np.arange(spec.n_epochs)
    p1 = np.asarray(spec.node1_ecef_m, float)
    lat, lon, _ = ecef2geodetic(p1)
    p2 = p1 + enu2ecef_vector(np.asarray(spec.node2_enu_m, float), float(lat), float(lon))
    T, S = t.size, len(ids)
    sys_col = np.array([0 if s[0] == "G" else 1 for s in ids])
    nodes: list[CoopNodeData] = []
    for j, (pos, nspec) in enumerate(((p1, spec.node1), (p2, spec.node2))):
        sat, rho, az, el = _node_geometry(eph, t, ids, pos)
        vis = windowsill_visible(ids, az, el, nspec, spec.elev_mask_deg)
        if nspec.dropout_prob > 0:
            vis &= rng.random((T, S)) >= nspec.dropout_prob
        else:
            rng.random((T, S))  # same draw count for every spec
        cn0 = _cn0(el, spec, nspec, rng)
        var = zhou_code_variance(
            np.nan_to_num(el, nan=np.pi / 2), cn0, sigma0_m=spec.sigma0_m, cn0_ref_dbhz=spec.cn0_ref_dbhz
        )
        clk = _clocks(T, spec, rng)
        noise = rng.normal(0.0, 1.0, (T, S)) * np.sqrt(var)
        mp = _gauss_markov(T, S, nspec.multipath_sigma_m, nspec.multipath_tau_s, spec.dt_s, rng)
        fault = np.zeros((T, S))
        if j == 0:
            seen0 = np.flatnonzero(vis[spec.bias_epochs[0] if spec.bias_epochs[0] < T else 0])
            if seen0.size < spec.n_bias_sats + 4:
                raise InputError(
                    f"node 1 sees {seen0.size} satellites at the fault's first epoch; "
                    f"expected at least {spec.n_bias_sats + 4}"
                )
            bad = rng.choice(seen0, size=spec.n_bias_sats, replace=False)
            if degraded:
                a, b = spec.bias_epochs
                fault[a:b, bad] = spec.bias_m
        code = rho + clk[:, sys_col] + noise + mp + fault
        code[~vis] = np.nan
        v = np.where(vis, var, np.nan)
        nodes.append(CoopNodeData(pos, ids, sat, code, v, el, np.where(vis, cn0, np.nan), clk, fault))
    true_range = float(np.linalg.norm(p2 - p1))
    ranges = true_range + rng.normal(0.0, spec.range_sigma_m, T)
    return CoopSim(t, (nodes[0], nodes[1]), ranges, spec.range_sigma_m, true_range, degraded)


__all__ = [
    "SYSTEMS",
    "ZHOU_NODE1_ECEF_M",
    "ZHOU_NODE2_ENU_M",
    "CoopNodeData",
    "CoopNodeSpec",
    "CoopSim",
    "CoopSimSpec",
    "simulate_coop",
    "windowsill_visible",
]
