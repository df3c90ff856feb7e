"""The library as an API: one entry point per mode, a :class:`SolutionSeries` out.

``robustrtk.solve_spp``, ``solve_dgnss``, ``solve_rtk`` and ``solve_dpl`` (re-exported,
lazily, from the top package) take file paths or already-read data and return a
:class:`SolutionSeries`: times, positions, status, σ and the run's diagnostics, with
:meth:`SolutionSeries.to_pos`, :meth:`SolutionSeries.to_csv` and
:meth:`SolutionSeries.to_dataframe` (pandas optional; the series and its
:class:`RunSummary` are defined in :mod:`robustrtk.pipeline.series`). They wrap the pipelines the
``robustrtk solve`` command runs — :func:`robustrtk.pipeline.gnss.solve_spp_file`,
:func:`robustrtk.pipeline.gnss.solve_dgnss`, :func:`robustrtk.pipeline.rtk_gnss.solve_rtk`
and :func:`robustrtk.pipeline.solve.solve_pseudolite` — with the same input checks (some
epochs, navigation data covering them, a base position near the base's own solution), so
a script and the command give the same solution for the same settings.

``config`` is a :class:`~robustrtk.pipeline.config.Config`, a flat mapping of settings
(``{"ratio": 2.0, "elev_mask_deg": 10}``, the keys of docs/configuration.md) applied over
the mode's preset, a TOML file path (the same as ``solve --config``), or None (the preset).

The cooperative pipeline's entry points, :func:`robustrtk.pipeline.coop.solve_coop` (peer to
peer) and :func:`robustrtk.pipeline.coop.solve_coop_central`, take nodes and range links
rather than files and live in their own module (docs/coop.md).
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from robustrtk.core import FloatArray, InputError, ObsBatch
from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.geometry.receivers import PositionSource
from robustrtk.io.rinex_nav import NavData
from robustrtk.pipeline.config import Config, check_applies, load_config, preset
from robustrtk.pipeline.series import FIXED_STATUSES, PathLike, RunSummary, SolutionSeries, summarize

if TYPE_CHECKING:  # a solve of RINEX files never reads a site file
    from robustrtk.io.site import Site

#: Observations: a file path (RINEX 2/3/4, Hatanaka, gzip, or any registered reader) or a batch.
ObsInput = ObsBatch | PathLike
#: Navigation data: file path(s), parsed :class:`NavData`, or an :class:`EphemerisSource`.
NavInput = NavData | EphemerisSource | PathLike | Sequence[PathLike]
#: Settings: a Config, flat ``key -> value`` over the mode's preset, a TOML path, or None.
ConfigInput = Config | Mapping[str, Any] | PathLike | None
#: Base position: ECEF (m) ``(3,)``, a :class:`PositionSource`, a trajectory file, or None.
BasePosInput = FloatArray | Sequence[float] | PositionSource | PathLike | None
Progress = Callable[[int, int], None]


# ---------------------------------------------------------------------- settings
def resolve_config(config: ConfigInput, mode: str, kind: str = "gnss") -> Config:
    """The :class:`Config` of ``config`` for ``mode`` (see the module notes).

    A mapping is applied over :func:`~robustrtk.pipeline.config.preset` ``(mode, kind)``
    after refusing any key that does not act in ``mode``; a TOML path is read over the same
    preset; a :class:`Config` must have ``mode``.
    """
    base = preset(mode, kind)
    if config is None:
        return base
    if isinstance(config, Config):
        if config.mode != mode:
            raise InputError(f"config: mode {config.mode!r} given to the {mode} entry point")
        return config.validate()
    if isinstance(config, (str, os.PathLike)):
        cfg = load_config(os.fspath(config), base=base)
        if cfg.mode != mode:
            raise InputError(f"mode: {cfg.mode!r} in the file, expected {mode!r}", os.fspath(config))
        return cfg
    if isinstance(config, Mapping):
        flat = {k: v for k, v in config.items() if k != "mode"}
        if config.get("mode", mode) != mode:
            raise InputError(f"mode: {config['mode']!r} given to the {mode} entry point")
        cfg = base.updated(**flat)  # unknown keys refused here
        check_applies(flat, mode, source="config")
        return cfg.validate()
    raise InputError(f"config: expected a Config, a mapping or a TOML path, got {type(config).__name__}")


# ---------------------------------------------------------------------- GNSS inputs
def _load_gnss(
    obs: ObsInput,
    what: str,
    eph: EphemerisSource,
    systems: str | None,
    cfg: Config | None = None,
    bounds_s: tuple[float | None, float | None] | None = None,
) -> ObsBatch:
    """:func:`robustrtk.pipeline.gnss_inputs.load_checked` as the CLI calls it (``cfg``'s time
    window, ``bounds_s``), with a partial navigation coverage as a warning."""
    from robustrtk.pipeline.gnss_inputs import load_checked

    batch, frac = load_checked(obs, what, systems, eph, None if cfg is None else cfg.gnss, bounds_s, "nav")
    if frac < 1.0:
        warnings.warn(
            f"{what}: the navigation data covers only {100 * frac:.1f} % of the epochs", stacklevel=3
        )
    return batch


def _nav(nav: NavInput) -> EphemerisSource:
    from robustrtk.pipeline.gnss_inputs import nav_source

    eph = nav_source(list(nav) if isinstance(nav, (list, tuple)) else nav)
    if sum(len(v.toe_s) for v in eph.nav.kepler.values()) + len(eph.nav.glonass) == 0:
        raise InputError("nav: no broadcast ephemeris in the navigation data (header only?)")
    return eph


def _base_pos(
    base: ObsBatch, base_pos: BasePosInput, cfg: Config, eph: EphemerisSource, force: bool
) -> BasePosInput:
    from robustrtk.pipeline.base_position import check_base_position

    if cfg.receivers.base_position != "fixed" or base_pos is None or hasattr(base_pos, "position"):
        return base_pos
    if isinstance(base_pos, (str, os.PathLike)):
        raise InputError(
            f"base_pos: a file ({os.fspath(base_pos)}) needs the setting base_position = 'trajectory'"
        )
    pos = np.asarray(base_pos, float).reshape(-1)
    if pos.shape != (3,) or not np.all(np.isfinite(pos)):
        raise InputError(f"base_pos: expected three finite ECEF numbers (m), got {base_pos!r}")
    check_base_position(base, eph, pos, cfg.gnss.elev_mask_deg, force=force)
    return pos


def _systems(cfg: Config) -> str | None:
    return cfg.gnss.systems.upper() if cfg.gnss.systems else None


# ---------------------------------------------------------------------- entry points
def solve_spp(
    rover: ObsInput,
    nav: NavInput,
    config: ConfigInput = None,
    *,
    progress: Progress | None = None,
) -> SolutionSeries:
    """Single point positioning of one receiver (``robustrtk solve ROVER --mode spp``).

    Least squares with fault detection and exclusion when ``filter`` is ``lsq`` (the
    preset), else the robust Kalman SPP (``{"filter": "ekf"}``); model in
    :mod:`robustrtk.pipeline.spp` (pseudorange ``P = ρ + c dt_r − c dt^s + I + T + e``).

    Parameters
    ----------
    rover : ObsBatch or path
        Observations (RINEX 2/3/4, Hatanaka, gzip, Android logs...).
    nav : path, sequence of paths, NavData or EphemerisSource
        Broadcast navigation data.
    config : Config, mapping, TOML path or None
        Settings over the ``spp`` preset.
    progress : callable (done, total), optional
        Called after each epoch.

    Returns
    -------
    SolutionSeries
        Status ``single`` (``none`` where unsolved), ECEF frame.
    """
    from robustrtk.pipeline.gnss import solve_spp_file

    cfg = resolve_config(config, "spp")
    eph = _nav(nav)
    batch = _load_gnss(rover, "rover", eph, _systems(cfg), cfg)
    epochs = solve_spp_file(batch, eph, cfg, systems=_systems(cfg), progress=progress)
    return spp_series(epochs)


def spp_series(epochs: Sequence[Any]) -> SolutionSeries:
    """A :class:`SolutionSeries` of SPP epochs (:class:`robustrtk.pipeline.spp.SppEpoch`),
    with the satellites excluded per epoch in ``info["excluded_per_epoch"]``."""
    return SolutionSeries.from_solutions(
        [e.to_solution() for e in epochs],
        "spp",
        info={"excluded_per_epoch": [len(e.excluded) for e in epochs]},
        frame="ecef",
    )


def solve_dgnss(
    rover: ObsInput,
    base: ObsInput,
    nav: NavInput,
    base_pos: BasePosInput = None,
    config: ConfigInput = None,
    *,
    force: bool = False,
    progress: Progress | None = None,
    keep_diagnostics: bool = True,
) -> SolutionSeries:
    """Code DGNSS by double differences (``robustrtk solve ROVER --base BASE --mode dgnss``).

    ``P_rb^ik = ρ_r^i − ρ_r^k − ρ_b^i + ρ_b^k + e`` per system and frequency slot
    (:mod:`robustrtk.pipeline.gnss`).

    Parameters
    ----------
    rover, base : ObsBatch or path
        Observations of the two receivers.
    nav : path, sequence of paths, NavData or EphemerisSource
    base_pos : array_like, shape (3,), PositionSource or path, optional
        Base ECEF (m); None: the base file's header position, with a warning (header
        positions may be wrong by metres). A trajectory (``.pos``/``.csv``) or source with
        ``base_position = "trajectory"``.
    config : Config, mapping, TOML path or None
        Settings over the ``dgnss`` preset.
    force : bool
        Accept a ``base_pos`` farther than 100 m from the base's own single-point solution.
    progress : callable (done, total), optional
    keep_diagnostics : bool
        False keeps no diagnostics row (a long run's rows take more memory than its
        observations, about 280 bytes each); :meth:`SolutionSeries.summary` still counts them.

    Returns
    -------
    SolutionSeries
        Status ``dgnss`` (``none`` where unsolved), ECEF frame, one diagnostics row per DD
        (none without ``keep_diagnostics``).
    """
    from robustrtk.pipeline.gnss import solve_dgnss as _dgnss
    from robustrtk.pipeline.gnss_inputs import base_read_bounds

    cfg = resolve_config(config, "dgnss")
    eph = _nav(nav)
    rover_b = _load_gnss(rover, "rover", eph, _systems(cfg), cfg)
    base_b = _load_gnss(base, "base", eph, _systems(cfg), bounds_s=base_read_bounds(rover_b, cfg.gnss))
    pos = _base_pos(base_b, base_pos, cfg, eph, force)
    res = _dgnss(rover_b, base_b, eph, pos, cfg, progress=progress, keep_diagnostics=keep_diagnostics)
    return SolutionSeries.from_solutions(res.solutions, "dgnss", res.run.diagnostics, res.info, frame="ecef")


def solve_rtk(
    rover: ObsInput,
    base: ObsInput,
    nav: NavInput,
    base_pos: BasePosInput = None,
    config: ConfigInput = None,
    *,
    force: bool = False,
    progress: Progress | None = None,
    keep_diagnostics: bool = True,
) -> SolutionSeries:
    """Carrier-phase RTK (``robustrtk solve ROVER --base BASE --mode rtk``).

    ``λ φ_rb^ik = ρ_rb^ik + T_rb^ik + λ N_rb^ik + ε`` with code DDs beside it, robust
    EKF, LAMBDA / partial ambiguity resolution and fix-and-hold
    (:mod:`robustrtk.pipeline.rtk_gnss`). Parameters as :func:`solve_dgnss`; ``config``
    over the ``rtk`` preset (``{"freqs": "L1", "systems": "GE", "ar": "lambda"}``...).

    Returns
    -------
    SolutionSeries
        Status ``fixed``, ``partial`` or ``float`` (``none`` where unsolved), ECEF frame.
    """
    from robustrtk.pipeline.gnss_inputs import base_read_bounds
    from robustrtk.pipeline.rtk_gnss import solve_rtk as _rtk

    cfg = resolve_config(config, "rtk")
    eph = _nav(nav)
    # RTK reads every system and selects its rows later (GLONASS is refused there)
    rover_b = _load_gnss(rover, "rover", eph, None, cfg)
    base_b = _load_gnss(base, "base", eph, None, bounds_s=base_read_bounds(rover_b, cfg.gnss))
    pos = _base_pos(base_b, base_pos, cfg, eph, force)
    res = _rtk(rover_b, base_b, eph, pos, cfg, progress=progress, keep_diagnostics=keep_diagnostics)
    return SolutionSeries.from_solutions(res.solutions, "rtk", res.run.diagnostics, res.info, frame="ecef")


def solve_dpl(
    obs: PathLike | Mapping[str, ObsBatch],
    site: PathLike | Site,
    config: ConfigInput = None,
    *,
    mode: str = "dpl",
    progress: Progress | None = None,
) -> SolutionSeries:
    """Differential pseudolite positioning of a rover against a base in a surveyed room.

    ``mode="dpl"``: DD code (and float phase) positioning, the robust UKF of Li et al.
    (2019) by default; ``mode="rtk"``: carrier-phase RTK with integer ambiguities
    (:func:`robustrtk.pipeline.solve.solve_pseudolite`, algorithms.md §1).

    Parameters
    ----------
    obs : path or mapping str -> ObsBatch
        A pseudolite observation table (``.csv``/``.parquet``), or the batches read from
        one (:func:`robustrtk.io.obstable.read_obs_table` with the site's wavelength).
    site : path or Site
        Site TOML: transmitters, base position, the rover's initial position.
    config : Config, mapping, TOML path or None
        Settings over the pseudolite preset of ``mode``.
    mode : {"dpl", "rtk"}
    progress : callable (done, total), optional

    Returns
    -------
    SolutionSeries
        Local frame of the site (m).
    """
    from robustrtk.pipeline.solve import solve_pseudolite

    if mode not in ("dpl", "rtk"):
        raise InputError(f"mode: pseudolite tables take dpl or rtk, got {mode!r}")
    cfg = resolve_config(config, mode, kind="pseudolite")
    res = solve_pseudolite(obs, site, cfg, progress=progress)
    return SolutionSeries.from_solutions(res.solutions, mode, res.diagnostics, res.info, frame="local")


__all__ = [
    "FIXED_STATUSES",
    "RunSummary",
    "SolutionSeries",
    "resolve_config",
    "solve_dgnss",
    "solve_dpl",
    "solve_rtk",
    "solve_spp",
    "spp_series",
    "summarize",
]
