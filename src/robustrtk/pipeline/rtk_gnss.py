"""Carrier-phase RTK on RINEX input: multi-constellation, multi-frequency.

The same DD engine as the pseudolite path (:mod:`robustrtk.pipeline.engine`,
:mod:`robustrtk.pipeline.rtk`) runs on rows that are (satellite, frequency slot) pairs
(:func:`robustrtk.measurement.signals.signal_rows`): each system and slot (``G:L1``,
``G:L2``, ``E:L1``, ...) is a DD group with its own reference satellite, every row has a
float DD ambiguity (cycles), and the robust policies, LAMBDA / PAR and fix-and-hold are
those of the pseudolite path. For satellites ``i``, reference ``k``, rover ``r`` and
base ``b`` on one frequency::

    λ φ_rb^ik = ρ_rb^ik + T_rb^ik + λ N_rb^ik + ε,     P_rb^ik = ρ_rb^ik + T_rb^ik + e

with Saastamoinen troposphere ``T`` per receiver; receiver and satellite clocks cancel,
and so does the ionosphere on short baselines (it is not modelled).

Cycle slips: RINEX loss-of-lock flags, the geometry-free combination of two frequencies
and Doppler-minus-phase, per receiver and row (:mod:`robustrtk.cycleslip`); under a
robust policy a slip that only a detector (not the receiver) reports is deferred: the
ambiguity is reset only if the robust filter keeps rejecting the row (a silent gross
error is down-weighted, not treated as a slip). Phases with the half-cycle flag stay
out of integer resolution, and a change of that flag on a running arc (the receiver
resolving the half cycle, or losing the polarity again) is a slip.

GLONASS (FDMA, per-satellite wavelengths) is among the default systems: its DD phase is
formed in metres with each satellite's wavelength and its ambiguities are fixed only with
``glonass_ar = on`` (``auto``, the default: when both receivers are the same make,
:func:`robustrtk.measurement.glonass.same_make`), float otherwise
(:mod:`robustrtk.measurement.glonass`, docs/algorithms.md § 34, § 37).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from robustrtk.core import FloatArray, InputError, ObsBatch, Solution
from robustrtk.cycleslip.doppler import doppler_phase_slips
from robustrtk.cycleslip.geometry_free import gf_drift_slips, gf_slips
from robustrtk.cycleslip.lli import half_cycle_flags, half_cycle_transitions
from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.geometry.receivers import PositionSource
from robustrtk.io.rinex_nav import NavData
from robustrtk.measurement.base_propagation import SystemFill
from robustrtk.measurement.glonass import fill_glonass_wavelengths, header_channels, same_make
from robustrtk.measurement.signals import RowSource, parse_slots, signal_rows
from robustrtk.pipeline.base_buffer import BaseEvents
from robustrtk.pipeline.config import Config, preset
from robustrtk.pipeline.engine import RunResult
from robustrtk.pipeline.gnss import first_fix_position, load_obs, nav_source, resolve_base_position, run_rows
from robustrtk.pipeline.gnss_inputs import data_code_sigma
from robustrtk.pipeline.results import EpochInputs

if TYPE_CHECKING:  # the per-epoch detector is imported where a stream makes one
    from robustrtk.cycleslip.online import OnlineSlipDetector

PathLike = str | os.PathLike[str]


#: Systems whose carrier phases RTK uses by default (GLONASS float unless allowed, module notes).
RTK_SYSTEMS = "GRECJ"


@dataclass
class RtkResult:
    """RTK output: solutions (status ``fixed``/``partial``/``float``), the engine's
    result (diagnostics per DD), and facts about the run."""

    solutions: list[Solution]
    run: RunResult
    info: dict[str, object] = field(default_factory=dict)


def rtk_gnss_config(**overrides: object) -> Config:
    """The GNSS RTK preset (:data:`robustrtk.pipeline.config.PRESETS`) with flat ``overrides``."""
    return preset("rtk").updated(**overrides).validate("rtk")


def detector_slips(batch: ObsBatch, cfg: Config) -> np.ndarray:
    """Undifferenced slip flags of one receiver's row batch, shape ``(T, R)``.

    ``gf``: the geometry-free combination of each satellite's first two slots (both rows
    flagged), its epoch-to-epoch jump and, with ``gf_window_s``, its change over that
    window (a drifting phase, :func:`robustrtk.cycleslip.geometry_free.gf_drift_slips`);
    ``doppler``: Doppler-minus-phase per row. LLI flags are handled by the RTK step itself.
    """
    det = cfg.slip_detectors()
    T, R = batch.phase_cyc.shape[:2]
    flags = np.zeros((T, R), dtype=bool)
    if T == 0 or R == 0:
        return flags
    phase = batch.phase_cyc[:, :, 0]
    sats = [t.split(":", 1)[0] for t in batch.tx_ids]
    if "gf" in det:
        rows_of: dict[str, list[int]] = {}
        for i, s in enumerate(sats):
            rows_of.setdefault(s, []).append(i)
        pairs = [(r[0], r[1]) for r in rows_of.values() if len(r) >= 2]
        if pairs:
            a = np.array([p[0] for p in pairs])
            b = np.array([p[1] for p in pairs])
            lam = batch.wavelength_m[:, 0]
            gf = gf_slips(
                batch.t_s,
                phase[:, a],
                phase[:, b],
                lam[a],
                lam[b],
                threshold_m=cfg.slip.gf_threshold_m,
                max_gap_s=120.0,
            )
            flags[:, a] |= gf
            flags[:, b] |= gf
            if cfg.slip.gf_window_s > 0:
                lli = batch.lli[:, :, 0]
                drift = gf_drift_slips(
                    batch.t_s, phase[:, a], phase[:, b], lam[a], lam[b], lli[:, a], lli[:, b],
                    window_s=cfg.slip.gf_window_s, threshold_m=cfg.slip.gf_window_threshold_m,
                )  # fmt: skip
                flags[:, a] |= drift
                flags[:, b] |= drift
    if "doppler" in det:
        dop = batch.doppler_hz[:, :, 0]
        dt = np.diff(batch.t_s, prepend=batch.t_s[0])
        slips = doppler_phase_slips(batch.t_s, phase, dop, threshold_cyc=cfg.slip.doppler_threshold_cyc)
        # the Doppler prediction is only meaningful over short gaps (1-2 s)
        flags |= slips & (dt[:, None] <= 2.0)
    return flags


def online_detector(cfg: Config) -> OnlineSlipDetector:
    """The per-epoch form of :func:`detector_slips` and the half-cycle jump marking
    (:class:`~robustrtk.cycleslip.online.OnlineSlipDetector`): fed a receiver's epochs in
    order, it gives each epoch's row of the whole-array flags."""
    from robustrtk.cycleslip.online import OnlineSlipDetector  # here: only streams run it

    det = cfg.slip_detectors()
    s = cfg.slip
    return OnlineSlipDetector(
        gf="gf" in det, doppler="doppler" in det, gf_threshold_m=s.gf_threshold_m, gf_max_gap_s=120.0,
        gf_window_s=s.gf_window_s, gf_window_threshold_m=s.gf_window_threshold_m,
        doppler_threshold_cyc=s.doppler_threshold_cyc,
    )  # fmt: skip


def mark_half_cycle_jumps(batch: ObsBatch) -> ObsBatch:
    """The row batch with the loss-of-lock bit set where the half-cycle bit changes
    (:func:`robustrtk.cycleslip.lli.half_cycle_transitions`)."""
    jumps = half_cycle_transitions(batch.phase_cyc[:, :, 0], batch.lli[:, :, 0])
    if not jumps.any():
        return batch
    lli = batch.lli.copy()
    lli[:, :, 0] |= jumps.astype(np.int8)
    return replace(batch, lli=lli)


def solve_rtk(
    rover_obs: ObsBatch | PathLike,
    base_obs: ObsBatch | PathLike,
    nav_paths: NavData | EphemerisSource | PathLike | Sequence[PathLike],
    base_pos_m: FloatArray | Sequence[float] | PositionSource | PathLike | None = None,
    cfg: Config | None = None,
    *,
    freqs: str | Sequence[str] | None = None,
    systems: str | None = None,
    elev_mask_deg: float | None = None,
    rover_pos0_m: FloatArray | None = None,
    progress: Callable[[int, int], None] | None = None,
    keep_diagnostics: bool = True,
) -> RtkResult:
    """Carrier-phase RTK between a rover and a base RINEX file.

    Parameters
    ----------
    rover_obs, base_obs : ObsBatch or path
        Observations (all signals).
    nav_paths : NavData, EphemerisSource, path or sequence of paths
    base_pos_m : array_like, shape (3,), optional
        Base ECEF (m); the header position (with a warning) when None.
    cfg : Config, optional
        Default :func:`rtk_gnss_config`.
    freqs : str or sequence of str
        Frequency slots, e.g. ``"L1+L2"`` (see :mod:`robustrtk.measurement.signals`).
    systems : str, optional
        System letters (default :data:`RTK_SYSTEMS`, ``"GRECJ"``; GLONASS see the module notes).
    elev_mask_deg : float
    rover_pos0_m : ndarray, shape (3,), optional
        Initial rover position (default: SPP of the first solvable epoch).
    keep_diagnostics : bool
        False keeps no per-DD diagnostics row, only their counts (``info["row_tally"]``).

    Returns
    -------
    RtkResult
    """
    cfg = cfg or rtk_gnss_config()
    if cfg.mode != "rtk":
        raise InputError(f"mode: RTK needs mode 'rtk', got {cfg.mode!r}")
    elev_mask_deg = cfg.gnss.elev_mask_deg if elev_mask_deg is None else elev_mask_deg
    systems = cfg.gnss.systems if systems is None else systems
    freqs = cfg.gnss.freqs if freqs is None else freqs
    slots = parse_slots(freqs) if isinstance(freqs, str) else parse_slots("+".join(freqs))
    sys_sel = RTK_SYSTEMS if systems is None else systems.upper()
    eph = nav_source(nav_paths)
    rover_full = load_obs(rover_obs, None)
    base_full = load_obs(base_obs, None)
    if "R" in sys_sel and cfg.gnss.glonass_ar == "auto":
        cfg = cfg.updated(glonass_ar="on" if same_make(rover_full.meta, base_full.meta) else "off")
    base_pos = resolve_base_position(base_full, base_pos_m, cfg, eph)
    rover = signal_rows(rover_full, slots, sys_sel)
    base = signal_rows(base_full, slots, sys_sel)
    if "R" in sys_sel:  # GLONASS channels a file's header lacks: the other's, the navigation data's
        channels = {
            **eph.nav.glo_channels(),
            **header_channels(base_full.meta),
            **header_channels(rover_full.meta),
        }
        rover, base = fill_glonass_wavelengths(rover, channels), fill_glonass_wavelengths(base, channels)
    if len(rover.tx_ids) == 0:
        raise InputError(f"rover: no observations of systems {sys_sel} on {'+'.join(slots)}")
    pos0 = (
        first_fix_position(rover_full, eph, elev_mask_deg)
        if rover_pos0_m is None
        else np.asarray(rover_pos0_m, float)
    )
    cfg, code_sigmas = data_code_sigma(cfg, rover, base, eph, pos0, base_pos)
    # a half-cycle bit that changes on a running arc is a half-cycle jump: a slip (LLI)
    rover = mark_half_cycle_jumps(rover)
    base = mark_half_cycle_jumps(base)
    flags_r = detector_slips(rover, cfg)
    flags_b = detector_slips(base, cfg)
    half_r = half_cycle_flags(rover.lli[:, :, 0])
    half_b = half_cycle_flags(base.lli[:, :, 0])
    # base rows in the rover's row order
    b_index = {t: i for i, t in enumerate(base.tx_ids)}
    map_b = np.array([b_index.get(t, -1) for t in rover.tx_ids], dtype=np.int64)
    has_b = map_b >= 0

    # the base's detector slips are events: each reaches the first rover epoch after it
    # (a base epoch serving several rover epochs, or skipped, see pipeline.base_buffer)
    events_b = BaseEvents(flags_b)

    # a base epoch missing a system it regularly sends gets it from its latest earlier epoch
    fill = None
    if isinstance(base_pos, np.ndarray) and cfg.gnss.max_age_s > 0:
        fill = SystemFill(base, RowSource(eph), base_pos, cfg.gnss.max_age_s, sagnac=True, troposphere=True)

    def inputs(i: int, j: int) -> EpochInputs:
        fb = np.zeros(len(rover.tx_ids), dtype=bool)
        hb = np.zeros(len(rover.tx_ids), dtype=bool)
        fb[has_b] = events_b.since_last(j)[map_b[has_b]]
        hb[has_b] = half_b[j, map_b[has_b]]
        b = base.epoch(j) if fill is None else fill.epoch(j)
        return EpochInputs(rover.epoch(i), b, slip=flags_r[i] | fb, half_cycle=half_r[i] | hb)

    run, info = run_rows(
        rover,
        base,
        cfg,
        eph,
        base_pos,
        pos0,
        elev_mask_deg,
        progress,
        inputs,
        keep_diagnostics=keep_diagnostics,
    )
    info["code_sigma_m"] = cfg.measurement.code_sigma_m
    info["code_sigma_data_m"] = code_sigmas
    info["slots"] = slots
    info["systems"] = sys_sel
    info["glonass_ar"] = cfg.gnss.glonass_ar
    info["rover_epochs"] = len(rover_full)
    return RtkResult(run.solutions, run, info)


__all__ = [
    "RTK_SYSTEMS", "RtkResult", "detector_slips", "mark_half_cycle_jumps", "online_detector",
    "rtk_gnss_config", "solve_rtk",
]  # fmt: skip
