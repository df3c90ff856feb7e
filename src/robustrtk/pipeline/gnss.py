"""GNSS pipelines on RINEX input: SPP and code DGNSS (double differences).

DGNSS runs the DD engine (:func:`robustrtk.pipeline.engine.run_dd`, mode ``dpl``) in ECEF
with the Sagnac term and an elevation mask, on the codes of each satellite and frequency
slot (L1+L2 by default; :func:`robustrtk.measurement.signals.signal_rows`), one DD group
per system and slot (rover and base may use different tracking modes of a band). Between
receivers ``r`` (rover) and ``b`` (base) and satellites
``i`` and reference ``k`` of the same system::

    P_rb^ik = rho_r^i - rho_r^k - rho_b^i + rho_b^k + e

so satellite clocks, group delays and most of the atmosphere cancel.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from robustrtk.core import FloatArray, InputError, ObsBatch, Solution
from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.io.rinex_nav import NavData, read_rinex_nav
from robustrtk.io.rinex_obs import read_rinex_obs
from robustrtk.measurement.signals import RowSource, parse_slots, signal_rows
from robustrtk.pipeline.config import Config, preset
from robustrtk.pipeline.engine import RunResult, run_dd
from robustrtk.pipeline.spp import SppEpoch, select_band1, solve_spp, solve_spp_kalman

PathLike = str | os.PathLike[str]


@dataclass
class DgnssResult:
    """DGNSS output: solutions (status ``"dgnss"``), the engine's result, and facts."""

    solutions: list[Solution]
    run: RunResult
    info: dict[str, object] = field(default_factory=dict)


def load_obs(obs: ObsBatch | PathLike, systems: str | None) -> ObsBatch:
    if isinstance(obs, ObsBatch):
        return obs
    return read_rinex_obs(obs, systems=systems)


def nav_source(nav: NavData | EphemerisSource | PathLike | Sequence[PathLike]) -> EphemerisSource:
    if isinstance(nav, EphemerisSource):
        return nav
    if isinstance(nav, NavData):
        return EphemerisSource(nav)
    return EphemerisSource(read_rinex_nav(nav))


def align_base(rover: ObsBatch, base: ObsBatch, tol_s: float = 0.5) -> ObsBatch:
    """Base epochs re-tagged with the time tags of the nearest rover epochs (within ``tol_s``).

    RINEX time tags are receiver time and pseudoranges carry the same receiver clock
    offset, so ``t_tag - P / c`` is the transmission time whatever the tag offset: tags a
    few milliseconds off the second (receiver clock) need no propagation of the
    pseudoranges, only matching. Satellite positions are then computed at the rover tag;
    the residual error is the base clock offset times the satellite range rate minus the
    rover's (cancelled by the receiver clock term in the DDs to first order).

    Returns
    -------
    ObsBatch
        Base observations at the rover's matched epochs (unmatched rover epochs absent).
    """
    tb = base.t_s
    if tb.size == 0:
        return base
    j = np.clip(np.searchsorted(tb, rover.t_s), 1, tb.size - 1) if tb.size > 1 else np.zeros(len(rover), int)
    if tb.size > 1:
        j = np.where(np.abs(tb[j - 1] - rover.t_s) <= np.abs(tb[j] - rover.t_s), j - 1, j)
    ok = np.abs(rover.t_s - tb[j]) <= tol_s
    jj = j[ok]
    return replace(
        base,
        t_s=rover.t_s[ok].copy(),
        code_m=base.code_m[jj],
        phase_cyc=base.phase_cyc[jj],
        doppler_hz=base.doppler_hz[jj],
        cn0_dbhz=base.cn0_dbhz[jj],
        lli=base.lli[jj],
    )


def resolve_base_position(base: ObsBatch, base_pos_m: FloatArray | Sequence[float] | None) -> FloatArray:
    """The base ECEF position: the given one (checked), else the file header's with a warning."""
    if base_pos_m is None:
        if base.approx_pos_m is None or not np.all(np.isfinite(base.approx_pos_m)):
            raise InputError("base position: none given and none in the base file header")
        warnings.warn(
            "base position taken from the RINEX header (APPROX POSITION XYZ); header "
            "positions may be wrong by metres: pass the surveyed position",
            stacklevel=3,
        )
        return np.asarray(base.approx_pos_m, float)
    pos = np.asarray(base_pos_m, float).reshape(-1)
    if pos.shape != (3,) or not np.all(np.isfinite(pos)):
        raise InputError(f"base position: expected three finite ECEF numbers, got {base_pos_m!r}")
    return pos


def first_fix_position(rover: ObsBatch, eph: EphemerisSource, elev_mask_deg: float) -> FloatArray:
    """Least-squares SPP of the first solvable rover epoch (band-1 code): the filters' start."""
    band1 = select_band1(rover)
    spp_cfg = preset("spp").updated(elev_mask_deg=elev_mask_deg)
    for i in range(len(band1)):
        one = replace(
            band1,
            t_s=band1.t_s[i : i + 1],
            code_m=band1.code_m[i : i + 1],
            phase_cyc=band1.phase_cyc[i : i + 1],
            doppler_hz=band1.doppler_hz[i : i + 1],
            cn0_dbhz=band1.cn0_dbhz[i : i + 1],
            lli=band1.lli[i : i + 1],
        )
        sol = solve_spp(one, eph, spp_cfg)[0]
        if sol.status == "single":
            return np.asarray(sol.pos_ecef_m, float)
    raise InputError("rover: no epoch with enough satellites for an initial position")


def dgnss_config(**overrides: object) -> Config:
    """The DGNSS preset (:data:`robustrtk.pipeline.config.PRESETS`) with flat ``overrides``."""
    return preset("dgnss").updated(**overrides).validate("dgnss")


def solve_spp_file(
    rover_obs: ObsBatch | PathLike,
    nav: NavData | EphemerisSource | PathLike | Sequence[PathLike],
    cfg: Config | None = None,
    *,
    systems: str | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> list[SppEpoch]:
    """SPP of a RINEX file: least squares with FDE when ``cfg.estimator.filter`` is
    ``lsq`` (the default ``preset("spp")``), else the Kalman SPP with that filter."""
    cfg = cfg or preset("spp")
    batch = load_obs(rover_obs, systems)
    eph = nav_source(nav)
    if cfg.estimator.filter != "lsq":
        # the Kalman SPP picks its own signals (second band, carrier phase)
        return solve_spp_kalman(batch, eph, cfg, progress, systems=systems)
    return solve_spp(select_band1(batch, systems), eph, cfg, progress)


def solve_dgnss(
    rover_obs: ObsBatch | PathLike,
    base_obs: ObsBatch | PathLike,
    nav_paths: NavData | EphemerisSource | PathLike | Sequence[PathLike],
    base_pos_m: FloatArray | Sequence[float] | None = None,
    cfg: Config | None = None,
    *,
    elev_mask_deg: float = 15.0,
    systems: str | None = None,
    rover_pos0_m: FloatArray | None = None,
    progress: Callable[[int, int], None] | None = None,
    freqs: str | Sequence[str] = ("L1", "L2"),
) -> DgnssResult:
    """Code DGNSS by double differences.

    Parameters
    ----------
    rover_obs, base_obs : ObsBatch or path
        Observations (RINEX paths are read with :func:`read_rinex_obs`).
    nav_paths : NavData, EphemerisSource, path or sequence of paths
        Broadcast navigation data.
    base_pos_m : array_like, shape (3,), optional
        Base ECEF position (m). When None the base file's header position is used with a
        warning (header positions are often wrong by metres).
    cfg : Config, optional
        Engine settings; default :func:`dgnss_config` (mode ``dpl``, EKF, elevation
        weighting). ``cfg.mode`` must be ``dpl``.
    elev_mask_deg : float
    systems : str, optional
        System letters to use (``"GEJ"``); all when None.
    rover_pos0_m : ndarray, shape (3,), optional
        Initial rover position; default the least-squares SPP of the first solvable epoch.
    freqs : str or sequence of str
        Frequency slots whose codes are differenced (default L1+L2: the second frequency's
        code noise and multipath are largely independent, which halves the 95 % errors on
        the shared datasets); one DD group per system and slot.

    Returns
    -------
    DgnssResult
        ``solutions`` with status ``"dgnss"`` (``"none"`` where unsolved).
    """
    cfg = cfg or dgnss_config()
    if cfg.mode not in ("dgnss", "dpl"):
        raise InputError(f"mode: DGNSS needs mode 'dgnss', got {cfg.mode!r}")
    eph = nav_source(nav_paths)
    slots = parse_slots(freqs) if isinstance(freqs, str) else parse_slots("+".join(freqs))
    rover_full = load_obs(rover_obs, systems)
    base_full = load_obs(base_obs, systems)
    base_pos = resolve_base_position(base_full, base_pos_m)
    pos0 = (
        first_fix_position(rover_full, eph, elev_mask_deg)
        if rover_pos0_m is None
        else np.asarray(rover_pos0_m, float)
    )
    rover = signal_rows(rover_full, slots, systems)
    base = signal_rows(base_full, slots, systems)
    if not rover.tx_ids:
        raise InputError(f"rover: no code observations on {'+'.join(slots)}")
    # base epochs keep their own tags: satellite positions are computed per receiver
    run = run_dd(
        rover,
        base,
        cfg,
        RowSource(eph),
        base_pos,
        pos0,
        progress=progress,
        sagnac=True,
        frame="ecef",
        elev_mask_deg=elev_mask_deg,
        align_tol_s=0.5,
        row_groups=True,
    )
    sols = [replace(s, status="dgnss") if s.status == "code" else s for s in run.solutions]
    info: dict[str, object] = dict(run.info)
    info["signals_rover"] = rover.meta.get("signal_by_slot")
    info["signals_base"] = base.meta.get("signal_by_slot")
    info["rover_pos0_m"] = pos0
    info["base_pos_m"] = base_pos
    return DgnssResult(sols, run, info)


__all__ = [
    "DgnssResult",
    "dgnss_config",
    "first_fix_position",
    "resolve_base_position",
    "solve_dgnss",
    "solve_spp_file",
]
