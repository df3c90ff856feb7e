"""GNSS pipelines on RINEX input: SPP and code DGNSS (double differences).

DGNSS runs the DD engine (:func:`robustrtk.pipeline.loop.run_dd`, mode ``dpl``) in ECEF
with the Sagnac term and an elevation mask, on the codes of each satellite and frequency
slot (L1+L2 by default; :func:`robustrtk.measurement.signals.signal_rows`), one DD group
per system and slot (rover and base may use different tracking modes of a band). Between
receivers ``r`` (rover) and ``b`` (base) and satellites
``i`` and reference ``k`` of the same system::

    P_rb^ik = rho_r^i - rho_r^k - rho_b^i + rho_b^k + e

so satellite clocks, group delays and most of the atmosphere cancel.

The inputs of a GNSS solve (reading, time window, checks) are in
:mod:`robustrtk.pipeline.gnss_inputs`, the base position in
:mod:`robustrtk.pipeline.base_position`; the names of theirs that the command line and
the RTK pipeline call through this module are importable from here.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from robustrtk.core import BoolArray, FloatArray, InputError, ObsBatch, Solution
from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.geometry.receivers import PositionSource
from robustrtk.io.rinex_nav import NavData
from robustrtk.measurement.signals import RowSource, parse_slots, signal_rows
from robustrtk.pipeline.base_position import (
    check_base_position,
    first_fix_position,
    own_solution_track,
    resolve_base_position,
)
from robustrtk.pipeline.config import Config, preset
from robustrtk.pipeline.gnss_inputs import (
    PathLike,
    base_read_bounds,
    check_has_epochs,
    check_nav_coverage,
    data_code_sigma,
    load_checked,
    load_obs,
    nav_source,
)
from robustrtk.pipeline.results import EpochInputs, RunResult
from robustrtk.pipeline.spp import SppEpoch, select_band1, solve_spp, solve_spp_kalman


@dataclass
class DgnssResult:
    """DGNSS output: solutions (status ``"dgnss"``), the engine's result, and facts."""

    solutions: list[Solution]
    run: RunResult
    info: dict[str, object] = field(default_factory=dict)


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
    diagnostics: list[Any] | None = None,
) -> list[SppEpoch]:
    """SPP of a RINEX file: least squares with FDE when ``cfg.estimator.filter`` is
    ``lsq`` (the default ``preset("spp")``), else the Kalman SPP with that filter; the
    batch smoother with ``cfg.spp.fgo``, which appends its
    :class:`robustrtk.pipeline.spp_fgo.FgoDiagnostics` to ``diagnostics`` when given."""
    cfg = cfg or preset("spp")
    batch = load_obs(rover_obs, systems)
    eph = nav_source(nav)
    if cfg.spp.fgo:  # the batch smoother (algorithms.md §36)
        from robustrtk.pipeline.spp_fgo import solve_spp_fgo

        return solve_spp_fgo(batch, eph, cfg, progress, systems=systems, diagnostics=diagnostics)
    if cfg.estimator.filter != "lsq":
        # the Kalman SPP picks its own signals (second band, carrier phase)
        return solve_spp_kalman(batch, eph, cfg, progress, systems=systems)
    return solve_spp(select_band1(batch, systems), eph, cfg, progress)


def solve_dgnss(
    rover_obs: ObsBatch | PathLike,
    base_obs: ObsBatch | PathLike,
    nav_paths: NavData | EphemerisSource | PathLike | Sequence[PathLike],
    base_pos_m: FloatArray | Sequence[float] | PositionSource | PathLike | None = None,
    cfg: Config | None = None,
    *,
    elev_mask_deg: float | None = None,
    systems: str | None = None,
    rover_pos0_m: FloatArray | None = None,
    progress: Callable[[int, int], None] | None = None,
    freqs: str | Sequence[str] | None = None,
    keep_diagnostics: bool = True,
) -> DgnssResult:
    """Code DGNSS by double differences.

    Parameters
    ----------
    rover_obs, base_obs : ObsBatch or path
        Observations (RINEX paths are read with :func:`read_rinex_obs`).
    nav_paths : NavData, EphemerisSource, path or sequence of paths
        Broadcast navigation data.
    base_pos_m : array_like (3,), PositionSource or path, optional
        Base position by ``cfg.receivers.base_position`` (:func:`resolve_base_position`):
        ECEF (m) for ``fixed`` (None: the header's, with a warning), a source or a
        trajectory file for ``trajectory``, none for ``moving`` (its own solution).
    cfg : Config, optional
        Engine settings; default :func:`dgnss_config` (the ``dgnss`` preset).
    elev_mask_deg : float, optional
        Default ``cfg.gnss.elev_mask_deg``.
    systems : str, optional
        System letters to use (``"GEJ"``); default ``cfg.gnss.systems`` (None: all).
    rover_pos0_m : ndarray, shape (3,), optional
        Initial rover position; default the least-squares SPP of the first solvable epoch.
    freqs : str or sequence of str, optional
        Frequency slots whose codes are differenced (default ``cfg.gnss.freqs``, L1+L2: the second frequency's
        code noise and multipath are largely independent, which halves the 95 % errors on
        the shared datasets); one DD group per system and slot.
    keep_diagnostics : bool
        False keeps no per-DD diagnostics row, only their counts (``info["row_tally"]``).

    Returns
    -------
    DgnssResult
        ``solutions`` with status ``"dgnss"`` (``"none"`` where unsolved).
    """
    cfg = cfg or dgnss_config()
    if cfg.mode not in ("dgnss", "dpl"):
        raise InputError(f"mode: DGNSS needs mode 'dgnss', got {cfg.mode!r}")
    elev_mask_deg = cfg.gnss.elev_mask_deg if elev_mask_deg is None else elev_mask_deg
    systems = cfg.gnss.systems if systems is None else systems
    freqs = cfg.gnss.freqs if freqs is None else freqs
    eph = nav_source(nav_paths)
    slots = parse_slots(freqs) if isinstance(freqs, str) else parse_slots("+".join(freqs))
    rover_full = load_obs(rover_obs, systems)
    base_full = load_obs(base_obs, systems)
    base_pos = resolve_base_position(base_full, base_pos_m, cfg, eph)
    pos0 = (
        first_fix_position(rover_full, eph, elev_mask_deg)
        if rover_pos0_m is None
        else np.asarray(rover_pos0_m, float)
    )
    rover = signal_rows(rover_full, slots, systems)
    base = signal_rows(base_full, slots, systems)
    if not rover.tx_ids:
        raise InputError(f"rover: no code observations on {'+'.join(slots)}")
    # with code_sigma_from_data: the σ the receivers' code shows, where the configured one
    # would have the robust test reject rows at one σ of the data (algorithms.md §39)
    from robustrtk.estimation.registry import make_robust_policy
    from robustrtk.estimation.robust import rejection_threshold

    rb = cfg.robust
    k_rej = rejection_threshold(make_robust_policy(rb.policy, k0=rb.k0, k1=rb.k1))
    cfg, code_sigmas = data_code_sigma(cfg, rover, base, eph, pos0, base_pos, min_ratio=k_rej)
    run, info = run_rows(
        rover, base, cfg, eph, base_pos, pos0, elev_mask_deg, progress, keep_diagnostics=keep_diagnostics
    )
    info["code_sigma_m"] = cfg.measurement.code_sigma_m
    info["code_sigma_data_m"] = code_sigmas
    sols = [replace(s, status="dgnss") if s.status == "code" else s for s in run.solutions]
    return DgnssResult(sols, run, info)


def run_rows(
    rover: ObsBatch,
    base: ObsBatch,
    cfg: Config,
    eph: EphemerisSource,
    base_pos: FloatArray | PositionSource,
    pos0: FloatArray,
    elev_mask_deg: float,
    progress: Callable[[int, int], None] | None = None,
    inputs: Callable[[int, int], EpochInputs] | None = None,
    keep_diagnostics: bool = True,
) -> tuple[RunResult, dict[str, object]]:
    """The DD engine on two receivers' signal rows (ECEF, Sagnac, elevation mask), and the
    facts of the run. Base epochs keep their own tags: satellite positions are computed per
    receiver; epochs pair within 0.5 s, else with the latest base epoch at most
    ``cfg.gnss.max_age_s`` old, carried to the rover's tag
    (:mod:`robustrtk.pipeline.base_buffer`). ``keep_diagnostics``: see
    :func:`~robustrtk.pipeline.loop.run_dd`."""
    # RTK: a base epoch without carrier phases (a radio link's code-only epochs) does not serve
    wanted = base.phase_cyc if cfg.mode == "rtk" else base.code_m
    usable: BoolArray | None = np.asarray(np.isfinite(wanted[:, :, 0]).any(axis=1)) if len(base) else None
    from robustrtk.pipeline.loop import run_dd  # the DD engine: imported by the modes that run it

    run = run_dd(
        rover, base, cfg, RowSource(eph), base_pos, pos0, progress=progress, sagnac=True, frame="ecef",
        base_usable=usable,
        elev_mask_deg=elev_mask_deg, align_tol_s=0.5, row_groups=True, inputs=inputs,
        keep_diagnostics=keep_diagnostics, max_age_s=cfg.gnss.max_age_s, sigma_age_m_s=cfg.gnss.sigma_age_m_s,
    )  # fmt: skip
    info: dict[str, object] = dict(run.info)
    info["signals_rover"] = rover.meta.get("signal_by_slot")
    info["signals_base"] = base.meta.get("signal_by_slot")
    info["rover_pos0_m"] = pos0
    info["base_pos_m"] = base_pos if isinstance(base_pos, np.ndarray) else None
    info["base_position"] = cfg.receivers.base_position
    return run, info


__all__ = [
    "DgnssResult",
    "align_base",
    "base_read_bounds",
    "check_base_position",
    "check_has_epochs",
    "check_nav_coverage",
    "dgnss_config",
    "first_fix_position",
    "load_checked",
    "load_obs",
    "nav_source",
    "own_solution_track",
    "resolve_base_position",
    "run_rows",
    "solve_dgnss",
    "solve_spp_file",
]
