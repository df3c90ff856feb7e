"""The library as an API: one entry point per mode, a :class:`SolutionSeries` out.

``robustrtk.solve_spp``, ``solve_dgnss``, ``solve_rtk`` and ``solve_dpl`` (re-exported,
lazily, from the top package) take file paths or already-read data and return a
:class:`SolutionSeries`: times, positions, status, σ and the run's diagnostics, with
:meth:`SolutionSeries.to_pos`, :meth:`SolutionSeries.to_csv` and
:meth:`SolutionSeries.to_dataframe` (pandas optional). They wrap the pipelines the
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
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from robustrtk.core import GPS_EPOCH, FloatArray, InputError, IntArray, ObsBatch, Solution
from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.geometry.frames import ecef2enu_rotation, ecef2geodetic
from robustrtk.geometry.receivers import PositionSource
from robustrtk.io.rinex_nav import NavData
from robustrtk.io.solution_csv import write_solution_csv
from robustrtk.io.solution_pos import write_pos
from robustrtk.io.solution_table import looks_ecef
from robustrtk.pipeline.config import Config, check_applies, load_config, preset
from robustrtk.pipeline.results import DiagRow, flag_counts

if TYPE_CHECKING:  # a solve of RINEX files never reads a site file
    from robustrtk.io.site import Site

PathLike = str | os.PathLike[str]
#: Observations: a file path (RINEX 2/3/4, Hatanaka, gzip, or any registered reader) or a batch.
ObsInput = ObsBatch | PathLike
#: Navigation data: file path(s), parsed :class:`NavData`, or an :class:`EphemerisSource`.
NavInput = NavData | EphemerisSource | PathLike | Sequence[PathLike]
#: Settings: a Config, flat ``key -> value`` over the mode's preset, a TOML path, or None.
ConfigInput = Config | Mapping[str, Any] | PathLike | None
#: Base position: ECEF (m) ``(3,)``, a :class:`PositionSource`, a trajectory file, or None.
BasePosInput = FloatArray | Sequence[float] | PositionSource | PathLike | None
Progress = Callable[[int, int], None]

#: Statuses counted as a fix (integer ambiguities resolved).
FIXED_STATUSES = ("fixed", "partial")


@dataclass(frozen=True)
class RunSummary:
    """The numbers of a run, as the end-of-run summary prints them.

    Attributes
    ----------
    epochs : int
        Epochs in the series (solved or not).
    solved : int
        Epochs with a position (status other than ``none``).
    by_status : dict of str to int
        Epochs per status.
    fixed : int
        Epochs with status ``fixed`` or ``partial``.
    fix_rate : float
        ``fixed / epochs`` (NaN when there is no epoch).
    time_to_first_fix_s : float
        Seconds from the first epoch to the first fixed one (NaN when none is fixed).
    rows_downweighted : int
        DD rows whose robust factor γ was above 1 (variance inflated) but finite.
    rows_rejected : int
        DD rows with γ = ∞ (left out of the update).
    epochs_flagged : int
        Epochs with at least one down-weighted or rejected row.
    """

    epochs: int
    solved: int
    by_status: dict[str, int]
    fixed: int
    fix_rate: float
    time_to_first_fix_s: float
    rows_downweighted: int
    rows_rejected: int
    epochs_flagged: int


@dataclass(frozen=True)
class SolutionSeries:
    """T epochs of solutions as arrays, with the records and diagnostics they came from.

    Attributes
    ----------
    t_s : ndarray, shape (T,)
        Epoch times (s): GPST seconds since 1980-01-06 for GNSS, the table's clock for
        pseudolite tables.
    pos_m : ndarray, shape (T, 3)
        Positions (m) in ``frame``: ECEF for GNSS, the site's local frame for pseudolites;
        NaN rows where unsolved.
    cov_m2 : ndarray, shape (T, 3, 3)
        Position covariances (m²) in the same frame.
    status : ndarray of str, shape (T,)
        ``fixed``, ``partial``, ``float``, ``dgnss``, ``code``, ``single`` or ``none``.
    n_used : ndarray of int, shape (T,)
        Observations (DDs, or satellites for SPP) used.
    ratio : ndarray, shape (T,)
        Ratio-test value of the epoch's ambiguity search (NaN when none).
    frame : {"ecef", "local"}
    mode : str
        ``spp``, ``dgnss``, ``rtk`` or ``dpl``.
    solutions : tuple of Solution
        The per-epoch records (what the writers take).
    diagnostics : tuple of DiagRow
        One row per DD and epoch (DD modes; empty for SPP).
    info : dict
        Facts about the run (references, epochs paired, signals, base position...).
    """

    t_s: FloatArray
    pos_m: FloatArray
    cov_m2: FloatArray
    status: npt.NDArray[np.str_]
    n_used: IntArray
    ratio: FloatArray
    frame: str
    mode: str
    solutions: tuple[Solution, ...] = ()
    diagnostics: tuple[DiagRow, ...] = ()
    info: dict[str, object] = field(default_factory=dict)

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_solutions(
        cls,
        solutions: Iterable[Solution],
        mode: str,
        diagnostics: Iterable[DiagRow] = (),
        info: Mapping[str, object] | None = None,
        frame: str | None = None,
    ) -> SolutionSeries:
        """Stack :class:`Solution` records; ``frame`` by default from the positions
        (``ecef`` when they lie near the Earth's surface)."""
        sols = tuple(solutions)
        T = len(sols)
        pos = np.array([np.asarray(s.pos_m, float) for s in sols], float).reshape(T, 3)
        cov = np.array([np.asarray(s.cov_m2, float) for s in sols], float).reshape(T, 3, 3)
        if frame is None:
            ok = np.all(np.isfinite(pos), axis=1)
            frame = "ecef" if ok.any() and looks_ecef(pos[ok]) else "local"
        return cls(
            t_s=np.array([s.t_s for s in sols], float).reshape(T),
            pos_m=pos,
            cov_m2=cov,
            status=np.array([s.status for s in sols], dtype=str).reshape(T),
            n_used=np.array([s.n_used for s in sols], dtype=np.int64).reshape(T),
            ratio=np.array([s.ratio for s in sols], float).reshape(T),
            frame=frame,
            mode=mode,
            solutions=sols,
            diagnostics=tuple(diagnostics),
            info=dict(info or {}),
        )

    # ------------------------------------------------------------------ derived values
    def __len__(self) -> int:
        return int(self.t_s.shape[0])

    @property
    def sigma_m(self) -> FloatArray:
        """Standard deviations of the position components in ``frame``, shape (T, 3), m:
        ``σ_k = sqrt(C_kk)``."""
        with np.errstate(invalid="ignore"):
            return np.sqrt(np.diagonal(self.cov_m2, axis1=1, axis2=2))

    @property
    def solved(self) -> npt.NDArray[np.bool_]:
        """Epochs with a position, shape (T,)."""
        return (self.status != "none") & np.all(np.isfinite(self.pos_m), axis=1)

    def llh(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Geodetic latitude, longitude (deg) and ellipsoidal height (m), each (T,) (WGS84).

        Raises
        ------
        InputError
            The series is in a local frame (pseudolites).
        """
        self._need_ecef("llh")
        lat, lon, h = ecef2geodetic(self.pos_m)
        return np.degrees(lat), np.degrees(lon), h

    def sigma_enu_m(self) -> FloatArray:
        """σ east, north, up (m), shape (T, 3): ``C_enu = R C_ecef Rᵀ`` with ``R`` the
        ECEF→ENU rotation at each epoch's own position
        (:func:`robustrtk.geometry.frames.ecef2enu_rotation`)."""
        self._need_ecef("sigma_enu_m")
        lat, lon, _ = ecef2geodetic(np.where(np.isfinite(self.pos_m), self.pos_m, 0.0))
        rot = ecef2enu_rotation(lat, lon).reshape(-1, 3, 3)
        c = rot @ self.cov_m2 @ np.swapaxes(rot, 1, 2)
        with np.errstate(invalid="ignore"):
            return np.sqrt(np.diagonal(c, axis1=1, axis2=2))

    def fix_rate(self) -> float:
        """Fraction of all epochs with status ``fixed`` or ``partial`` (NaN for no epoch)."""
        n = len(self)
        return float(np.isin(self.status, FIXED_STATUSES).sum() / n) if n else float("nan")

    def time_to_first_fix_s(self) -> float:
        """Seconds from the first epoch to the first ``fixed``/``partial`` one (NaN when none)."""
        idx = np.flatnonzero(np.isin(self.status, FIXED_STATUSES))
        return float(self.t_s[idx[0]] - self.t_s[0]) if idx.size else float("nan")

    def summary(self) -> RunSummary:
        """Epoch counts, fix rate, time to first fix and the rows the robust filter flagged
        (for SPP, the satellites its FDE excluded: ``info["excluded_per_epoch"]``)."""
        excluded = self.info.get("excluded_per_epoch")
        tally = self.info.get("row_tally")
        return summarize(
            self.solutions,
            self.diagnostics,
            excluded if isinstance(excluded, (list, tuple)) else None,
            tally if isinstance(tally, dict) and not self.diagnostics else None,
        )

    # ------------------------------------------------------------------ output
    def to_pos(
        self,
        path: PathLike,
        *,
        frame: str = "llh",
        inputs: Sequence[str] = (),
        ref_pos_ecef_m: Sequence[float] | FloatArray | None = None,
    ) -> None:
        """Write an RTKLIB ``.pos`` (``frame`` ``llh`` or ``ecef``; GNSS series only), atomically;
        ``inputs`` and ``ref_pos_ecef_m`` become its ``% inp file`` and ``% ref pos`` lines."""
        self._need_ecef("to_pos")
        write_pos(
            self.solutions,
            path,
            frame=frame,
            inputs=inputs,
            ref_pos_ecef_m=ref_pos_ecef_m,
            pos_frame=self.frame,
        )

    def to_csv(self, path: PathLike) -> None:
        """Write the solution CSV of ``robustrtk solve --out x.csv`` (any frame), atomically."""
        write_solution_csv(self.solutions, path)

    def columns(self) -> dict[str, np.ndarray]:
        """The series as named columns of length T (what :meth:`to_dataframe` tabulates).

        ECEF series: ``gpst`` (datetime64[ns], GPS time scale), ``t_s``, ``x_ecef_m``,
        ``y_ecef_m``, ``z_ecef_m``, ``lat_deg``, ``lon_deg``, ``height_m``, ``sd_e_m``,
        ``sd_n_m``, ``sd_u_m``; local series: ``t_s``, ``x_m``, ``y_m``, ``z_m``,
        ``sd_x_m``, ``sd_y_m``, ``sd_z_m``; then ``status``, ``n_used``, ``ratio``.
        """
        cols: dict[str, np.ndarray] = {}
        if self.frame == "ecef":
            ns = np.where(np.isfinite(self.t_s), np.round(self.t_s * 1e9), 0).astype(np.int64)
            cols["gpst"] = np.datetime64(GPS_EPOCH, "ns") + ns.astype("timedelta64[ns]")
            cols["t_s"] = self.t_s
            for k, name in enumerate(("x_ecef_m", "y_ecef_m", "z_ecef_m")):
                cols[name] = self.pos_m[:, k]
            lat, lon, h = self.llh()
            cols["lat_deg"], cols["lon_deg"], cols["height_m"] = lat, lon, h
            sd = self.sigma_enu_m()
            for k, name in enumerate(("sd_e_m", "sd_n_m", "sd_u_m")):
                cols[name] = sd[:, k]
        else:
            cols["t_s"] = self.t_s
            sd = self.sigma_m
            for k, axis in enumerate("xyz"):
                cols[f"{axis}_m"] = self.pos_m[:, k]
            for k, axis in enumerate("xyz"):
                cols[f"sd_{axis}_m"] = sd[:, k]
        cols["status"] = self.status
        cols["n_used"] = self.n_used
        cols["ratio"] = self.ratio
        return cols

    def to_dataframe(self) -> Any:
        """A ``pandas.DataFrame`` of :meth:`columns`, one row per epoch.

        Raises
        ------
        ImportError
            pandas is not installed (it is optional: ``pip install pandas``).
        """
        try:
            import pandas as pd
        except ImportError:
            raise ImportError(
                "SolutionSeries.to_dataframe needs pandas, which robustrtk does not install: "
                "pip install pandas (or use SolutionSeries.columns(), a dict of numpy arrays)"
            ) from None
        return pd.DataFrame(self.columns())

    def _need_ecef(self, what: str) -> None:
        if self.frame != "ecef":
            raise InputError(f"{what}: needs ECEF (GNSS) positions; this series is in a local frame")


def summarize(
    solutions: Sequence[Solution],
    diagnostics: Iterable[DiagRow] = (),
    excluded_per_epoch: Sequence[int] | None = None,
    row_tally: Mapping[str, int] | None = None,
) -> RunSummary:
    """:class:`RunSummary` of solutions and their diagnostics rows.

    A row is *down-weighted* when its robust factor satisfies ``1 < γ < ∞`` and *rejected*
    when ``γ = ∞`` (algorithms.md §1); engine events (``kind == "event"``) are not rows.
    ``excluded_per_epoch`` (SPP: satellites excluded by FDE at each epoch) counts as
    rejected rows. ``row_tally`` (a run's ``info["row_tally"]``,
    :meth:`~robustrtk.pipeline.results.RowTally.as_dict`) gives the row and epoch counts of
    a run that kept no rows; it is added to what ``diagnostics`` counts.
    """
    by_status: dict[str, int] = {}
    for s in solutions:
        by_status[s.status] = by_status.get(s.status, 0) + 1
    n = len(solutions)
    fixed = sum(by_status.get(k, 0) for k in FIXED_STATUSES)
    first = next((s.t_s for s in solutions if s.status in FIXED_STATUSES), None)
    ttff = float(first - solutions[0].t_s) if first is not None else float("nan")
    tally: Mapping[str, int] = row_tally or {}
    down, rej, flagged = flag_counts(diagnostics)
    if excluded_per_epoch is not None:
        for sol, k in zip(solutions, excluded_per_epoch, strict=True):
            if k > 0:
                rej += int(k)
                flagged.add(sol.t_s)
    return RunSummary(
        epochs=n,
        solved=n - by_status.get("none", 0),
        by_status=dict(sorted(by_status.items())),
        fixed=fixed,
        fix_rate=fixed / n if n else float("nan"),
        time_to_first_fix_s=ttff,
        rows_downweighted=down + int(tally.get("rows_downweighted", 0)),
        rows_rejected=rej + int(tally.get("rows_rejected", 0)),
        epochs_flagged=len(flagged) + int(tally.get("epochs_flagged", 0)),
    )


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
    """:func:`robustrtk.pipeline.gnss.load_checked` as the CLI calls it (``cfg``'s time
    window, ``bounds_s``), with a partial navigation coverage as a warning."""
    from robustrtk.pipeline.gnss import load_checked

    batch, frac = load_checked(obs, what, systems, eph, None if cfg is None else cfg.gnss, bounds_s, "nav")
    if frac < 1.0:
        warnings.warn(
            f"{what}: the navigation data covers only {100 * frac:.1f} % of the epochs", stacklevel=3
        )
    return batch


def _nav(nav: NavInput) -> EphemerisSource:
    from robustrtk.pipeline.gnss import nav_source

    eph = nav_source(list(nav) if isinstance(nav, (list, tuple)) else nav)
    if sum(len(v.toe_s) for v in eph.nav.kepler.values()) + len(eph.nav.glonass) == 0:
        raise InputError("nav: no broadcast ephemeris in the navigation data (header only?)")
    return eph


def _base_pos(
    base: ObsBatch, base_pos: BasePosInput, cfg: Config, eph: EphemerisSource, force: bool
) -> BasePosInput:
    from robustrtk.pipeline.gnss import check_base_position

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
    from robustrtk.pipeline.gnss import base_read_bounds
    from robustrtk.pipeline.gnss import solve_dgnss as _dgnss

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
    from robustrtk.pipeline.gnss import base_read_bounds
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
