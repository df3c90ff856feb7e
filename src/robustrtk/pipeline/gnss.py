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

from robustrtk.core import BoolArray, FloatArray, InputError, ObsBatch, Solution
from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.geometry.receivers import PositionSource, TrajectoryPosition
from robustrtk.io.readers import detect_format, read_navigation, read_observations
from robustrtk.io.rinex_nav import NavData
from robustrtk.io.rinex_obs import read_rinex_obs
from robustrtk.io.solution_csv import read_solution_csv
from robustrtk.io.solution_pos import read_pos
from robustrtk.measurement.signals import RowSource, parse_slots, signal_rows
from robustrtk.pipeline.config import Config, GnssConfig, preset
from robustrtk.pipeline.engine import RunResult, run_dd
from robustrtk.pipeline.results import EpochInputs
from robustrtk.pipeline.spp import SppEpoch, select_band1, solve_spp, solve_spp_kalman
from robustrtk.timeutil import WEEK_S, gpst_text, is_time_of_day, parse_gpst_instant

PathLike = str | os.PathLike[str]


@dataclass
class DgnssResult:
    """DGNSS output: solutions (status ``"dgnss"``), the engine's result, and facts."""

    solutions: list[Solution]
    run: RunResult
    info: dict[str, object] = field(default_factory=dict)


def load_obs(
    obs: ObsBatch | PathLike,
    systems: str | None,
    window: GnssConfig | None = None,
    bounds_s: tuple[float | None, float | None] | None = None,
    what: str = "rover",
) -> ObsBatch:
    """Observations of a receiver: a batch as given, or a file read by its content
    (RINEX 2/3/4, Hatanaka, gzip, or any reader registered in :mod:`robustrtk.io.readers`).
    ``systems`` (letters) keeps only those systems.

    With ``window``, only the epochs of its time window (:func:`time_window_mask`, whose
    errors name ``what``): the RINEX reader decodes those epochs alone, other inputs are
    cut after reading. ``bounds_s`` (GPST s, None for an open side) instead gives the
    reader bounds (a base read over the rover's span, :func:`base_read_bounds`); bounds
    that leave it no epoch read the file again in full, so that a later error can say why.
    A batch given as such is returned as it is."""
    if isinstance(obs, ObsBatch):
        return obs
    win = window if window is not None and window_set(window) else None
    if detect_format(obs) == "rinex_obs":
        if bounds_s is not None:
            lo, hi = bounds_s
            batch = read_rinex_obs(obs, systems=systems, t_start_s=lo, t_end_s=hi)
            return batch if len(batch) else read_rinex_obs(obs, systems=systems)
        if win is None:
            return read_rinex_obs(obs, systems=systems)
        return read_rinex_obs(obs, systems=systems, epoch_mask=lambda t: time_window_mask(t, win, what))
    batch = read_observations(obs)
    batch = batch.select_systems(systems) if systems else batch
    return batch if win is None else select_time_window(batch, win, what)


#: How far beyond the rover's first and last epochs a base is read when the rover has a
#: time window (s): more than :func:`align_base`'s matching tolerance of 0.5 s.
BASE_MARGIN_S = 1.0


def window_set(gnss: GnssConfig) -> bool:
    """Whether ``gnss`` restricts the epochs (a ``time_start``, a ``time_end`` or an
    ``interval_s``)."""
    return gnss.time_start is not None or gnss.time_end is not None or gnss.interval_s > 0.0


def base_read_bounds(rover: ObsBatch, window: GnssConfig | None) -> tuple[float | None, float | None] | None:
    """The span to read a base over: the rover's epochs ± :data:`BASE_MARGIN_S`, and
    ``window.max_age_s`` before the first (the latest base epoch may serve a rover epoch
    that old), when ``window`` sets a time window, else None (the whole file). Base epochs
    beyond it match no rover epoch."""
    if window is None or not window_set(window) or len(rover) == 0:
        return None
    before = max(BASE_MARGIN_S, window.max_age_s)
    return float(rover.t_s[0]) - before, float(rover.t_s[-1]) + BASE_MARGIN_S


def nav_source(nav: NavData | EphemerisSource | PathLike | Sequence[PathLike]) -> EphemerisSource:
    if isinstance(nav, EphemerisSource):
        return nav
    if isinstance(nav, NavData):
        return EphemerisSource(nav)
    return EphemerisSource(read_navigation(nav))


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


def resolve_base_position(
    base: ObsBatch,
    base_pos_m: FloatArray | Sequence[float] | PositionSource | PathLike | None,
    cfg: Config | None = None,
    eph: EphemerisSource | None = None,
) -> FloatArray | PositionSource:
    """Where the base is, by ``cfg.receivers.base_position``.

    ``fixed``: the given ECEF position (checked), else the file header's with a warning.
    ``trajectory``: a :class:`~robustrtk.geometry.receivers.PositionSource`, or the path of a
    trajectory file (RTKLIB ``.pos`` or our solution CSV) interpolated per epoch.
    ``moving``: the base's own least-squares SPP solution at each of its epochs (RTKLIB's
    moving-base mode; needs ``eph``); epochs it cannot solve have no base position.
    """
    kind = "fixed" if cfg is None else cfg.receivers.base_position
    if kind == "moving":
        if base_pos_m is not None:
            raise InputError("base position: moving base takes its position from its own solution; give none")
        if eph is None:
            raise InputError("base position: a moving base needs navigation data")
        return own_solution_track(base, eph, 15.0 if cfg is None else cfg.gnss.elev_mask_deg)
    if kind == "trajectory":
        if isinstance(base_pos_m, (str, os.PathLike)):
            return trajectory_file(base_pos_m)
        if base_pos_m is None or not hasattr(base_pos_m, "position"):
            raise InputError("base position: trajectory mode expects a trajectory file (.pos or .csv)")
        return base_pos_m
    if hasattr(base_pos_m, "position"):
        return base_pos_m  # type: ignore[return-value]
    if base_pos_m is None:
        if base.approx_pos_m is None or not np.all(np.isfinite(base.approx_pos_m)):
            raise InputError("base position: none given and none in the base file header")
        warnings.warn(
            "base position taken from the RINEX header (APPROX POSITION XYZ); header "
            "positions may be wrong by metres: pass the surveyed position",
            stacklevel=3,
        )
        return np.asarray(base.approx_pos_m, float)
    if isinstance(base_pos_m, (str, os.PathLike)):
        raise InputError(f"base position: a file ({os.fspath(base_pos_m)}) needs base_position = trajectory")
    pos = np.asarray(base_pos_m, float).reshape(-1)
    if pos.shape != (3,) or not np.all(np.isfinite(pos)):
        raise InputError(f"base position: expected three finite ECEF numbers, got {base_pos_m!r}")
    return pos


def trajectory_file(path: PathLike) -> TrajectoryPosition:
    """A base trajectory from an RTKLIB ``.pos`` or a solution CSV (positions per epoch)."""
    p = os.fspath(path)
    table = read_solution_csv(p) if p.lower().endswith(".csv") else read_pos(p)
    ok = np.all(np.isfinite(table.pos_m), axis=1)
    if not ok.any():
        raise InputError("trajectory: no epoch with a position", p)
    return TrajectoryPosition(table.t_s[ok], table.pos_m[ok])


def own_solution_track(base: ObsBatch, eph: EphemerisSource, elev_mask_deg: float) -> TrajectoryPosition:
    """The base's least-squares SPP at each of its epochs (moving base), as a trajectory.

    Only the base's own epoch tags carry a position (``max_gap_s = 0``: no interpolation),
    so a rover epoch is solved against the base position of the same instant.
    """
    cfg = preset("spp").updated(elev_mask_deg=elev_mask_deg)
    sols = solve_spp(select_band1(base), eph, cfg)
    t = np.array([s.t_s for s in sols], float)
    pos = np.array([s.pos_ecef_m if s.status == "single" else np.full(3, np.nan) for s in sols], float)
    if not np.isfinite(pos).any():
        raise InputError("moving base: the base has no epoch with a single-point solution")
    return TrajectoryPosition(t, pos.reshape(-1, 3), max_gap_s=0.0, tol_s=0.6)


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


#: How far a time tag may sit from a window bound or an interval's grid and still count
#: as on it (s): RINEX tags of a receiver that steers its clock loosely are milliseconds off.
EPOCH_TOL_S = 0.025


def time_window_mask(t_s: FloatArray, gnss: GnssConfig, what: str = "rover") -> np.ndarray:
    """Which epochs ``t_s`` (GPST s) fall in the window of ``gnss`` (``time_start``,
    ``time_end``, ``interval_s``), as RTKLIB's ``-ts``/``-te``/``-ti`` select them.

    Kept: ``t_start − tol ≤ t ≤ t_end + tol`` and, with ``interval_s = Δ > 0``,
    ``|w − Δ·round(w/Δ)| ≤ tol`` for the GPS time of week ``w`` (``tol`` =
    :data:`EPOCH_TOL_S`). A bare time of day is read on the GPST date of ``time_start``
    when that is a calendar time (or seconds), else on the date of the first epoch; an end
    of day before the start moves to the next day.

    Parameters
    ----------
    t_s : ndarray, shape (T,)
    gnss : GnssConfig
    what : str
        The receiver named in the error.

    Returns
    -------
    ndarray of bool, shape (T,)

    Raises
    ------
    InputError
        An end before the start, or a window that keeps no epoch (the message gives the
        file's span).
    """
    t = np.asarray(t_s, float)
    keep = np.ones(t.shape, dtype=bool)
    if not window_set(gnss):
        return keep
    t_ref = float(t[0]) if t.size else 0.0
    lo = -np.inf if gnss.time_start is None else parse_gpst_instant(gnss.time_start, t_ref, "time_start")
    if gnss.time_start is not None and not is_time_of_day(gnss.time_start):
        t_ref = lo  # the end's day follows the start's, whatever the file read holds
    hi = np.inf if gnss.time_end is None else parse_gpst_instant(gnss.time_end, t_ref, "time_end")
    if gnss.time_end is not None and hi < lo and is_time_of_day(gnss.time_end):
        hi += 86_400.0
    if hi < lo:
        raise InputError(f"time_end: {gnss.time_end!r} is before time_start {gnss.time_start!r}")
    keep &= (t >= lo - EPOCH_TOL_S) & (t <= hi + EPOCH_TOL_S)
    if gnss.interval_s > 0.0:
        w = np.mod(t, WEEK_S)
        keep &= np.abs(w - gnss.interval_s * np.round(w / gnss.interval_s)) <= EPOCH_TOL_S
    if t.size and not keep.any():
        asked = ", ".join(
            f"{k} {v!r}"
            for k, v in (("time_start", gnss.time_start), ("time_end", gnss.time_end))
            if v is not None
        )
        if gnss.interval_s > 0.0:
            asked += (", " if asked else "") + f"interval_s {gnss.interval_s:g}"
        raise InputError(
            f"{asked}: no {what} epoch selected; the {what} epochs span "
            f"{gpst_text(float(t[0]))} to {gpst_text(float(t[-1]))} GPST"
        )
    return keep


def select_time_window(batch: ObsBatch, gnss: GnssConfig, what: str = "rover") -> ObsBatch:
    """``batch`` restricted to the epochs of :func:`time_window_mask` (the batch itself when
    no window is set)."""
    keep = time_window_mask(batch.t_s, gnss, what)
    return batch if keep.all() else batch.select_epochs(np.flatnonzero(keep))


def check_has_epochs(batch: ObsBatch, what: str) -> None:
    """:class:`InputError` when ``batch`` holds no epoch (a header-only file, say)."""
    if len(batch) == 0 or not np.isfinite(batch.code_m).any():
        where = batch.meta.get("path")
        raise InputError(
            f"{what}: no observations (header only, or no epoch of the kept systems)",
            str(where) if where is not None else None,
        )


def nav_coverage(batch: ObsBatch, eph: EphemerisSource) -> float:
    """Fraction of the epochs of ``batch`` that some broadcast ephemeris of one of its
    systems covers (time of ephemeris within that system's validity window)."""
    if len(batch) == 0:
        return 0.0
    t = np.asarray(batch.t_s, float)
    covered = np.zeros(t.shape, bool)
    tables: list[tuple[str, FloatArray]] = [
        (k, np.asarray(v.toe_s, float)) for k, v in eph.nav.kepler.items()
    ]
    if len(eph.nav.glonass):
        tables.append(("R", np.asarray(eph.nav.glonass.toe_s, float)))
    present = set(batch.system)
    for sys_letter, toe in tables:
        toe = np.sort(toe[np.isfinite(toe)])
        if toe.size == 0 or sys_letter not in present:
            continue
        age = eph.max_age_s.get(sys_letter, 7200.0)
        j = np.clip(np.searchsorted(toe, t), 1, toe.size - 1) if toe.size > 1 else np.zeros(t.size, int)
        near = np.minimum(np.abs(t - toe[j]), np.abs(t - toe[np.maximum(j - 1, 0)]))
        covered |= near <= age
    return float(covered.mean())


def check_nav_coverage(batch: ObsBatch, eph: EphemerisSource, what: str = "--nav") -> float:
    """:func:`nav_coverage`, with :class:`InputError` when it is zero (navigation data of
    another day, say); the caller reports a partial coverage."""
    frac = nav_coverage(batch, eph)
    if frac == 0.0:
        files = ", ".join(getattr(eph.nav, "files", ()) or ())
        t = np.asarray(batch.t_s, float)
        raise InputError(
            f"{what}: the navigation data{f' ({files})' if files else ''} covers none of the observation "
            f"span (GPS seconds {t.min():.0f} to {t.max():.0f}); expected broadcast ephemerides of the same "
            "hours"
        )
    return frac


def load_checked(
    obs: ObsBatch | PathLike,
    what: str,
    systems: str | None,
    eph: EphemerisSource,
    window: GnssConfig | None = None,
    bounds_s: tuple[float | None, float | None] | None = None,
    nav_what: str = "--nav",
) -> tuple[ObsBatch, float]:
    """Observations with the checks every GNSS solve needs, and the share of them that the
    navigation data covers (the caller reports a partial coverage its own way).

    :func:`load_obs` (``window``, ``bounds_s``), then :func:`check_has_epochs` and
    :func:`check_nav_coverage` on the epochs kept (``nav_what`` names the navigation input
    in its error)."""
    batch = load_obs(obs, systems, window, bounds_s, what)
    check_has_epochs(batch, what)
    return batch, check_nav_coverage(batch, eph, nav_what)


#: Largest accepted distance (m) between a given base position and the base's own SPP.
BASE_POSITION_TOL_M = 100.0


def base_spp_position(
    base: ObsBatch, eph: EphemerisSource, elev_mask_deg: float, n: int = 5
) -> FloatArray | None:
    """Median least-squares SPP of up to ``n`` solvable base epochs among its first ones
    (None when none solves): a quick check of a given base position."""
    band1 = select_band1(base)
    spp_cfg = preset("spp").updated(elev_mask_deg=elev_mask_deg)
    found: list[FloatArray] = []
    step = max(1, len(band1) // (4 * n))
    for i in range(0, min(len(band1), 40 * n * step), step):
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
        if sol.status == "single" and np.all(np.isfinite(sol.pos_ecef_m)):
            found.append(np.asarray(sol.pos_ecef_m, float))
            if len(found) >= n:
                break
    if not found:
        return None
    # np.median's numbers (middle value, or the mean of the two middle ones) for these
    # finite rows, without the numpy.ma import that np.median costs a command's start
    s = np.sort(np.array(found), axis=0)
    k = s.shape[0] // 2
    return s[k].copy() if s.shape[0] % 2 else (s[k - 1] + s[k]) / 2.0


def check_base_position(
    base: ObsBatch,
    eph: EphemerisSource,
    pos_m: FloatArray,
    elev_mask_deg: float,
    force: bool = False,
    tol_m: float = BASE_POSITION_TOL_M,
) -> float | None:
    """Refuse a fixed base position far from the base's own single-point solution.

    Parameters
    ----------
    base : ObsBatch
        Base observations.
    eph : EphemerisSource
        Broadcast ephemerides.
    pos_m : ndarray, shape (3,)
        The given base position (ECEF m).
    elev_mask_deg : float
        Elevation mask of the check's SPP.
    force : bool
        Accept any distance (the Earth-surface check still applies).
    tol_m : float
        Largest accepted distance (m).

    Returns
    -------
    float or None
        Distance (m) to the base's SPP; None when no base epoch could be solved.

    Raises
    ------
    InputError
        Position not near the Earth's surface, or farther than ``tol_m`` without ``force``.
    """
    pos = np.asarray(pos_m, float).reshape(3)
    r = float(np.linalg.norm(pos))
    if not (6.2e6 < r < 6.5e6):
        raise InputError(
            f"--base-pos: {r / 1e3:.6g} km from the Earth's centre; expected ECEF metres of a point "
            "near the Earth's surface"
        )
    spp = base_spp_position(base, eph, elev_mask_deg)
    if spp is None:
        return None
    d = float(np.linalg.norm(spp - pos))
    if d > tol_m and not force:
        raise InputError(
            f"--base-pos: {d:.1f} m from the base's own single-point solution "
            f"({spp[0]:.1f},{spp[1]:.1f},{spp[2]:.1f}); expected within {tol_m:.0f} m "
            "(check the position and its frame, or pass --force)"
        )
    return d


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
    run, info = run_rows(
        rover, base, cfg, eph, base_pos, pos0, elev_mask_deg, progress, keep_diagnostics=keep_diagnostics
    )
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
    :func:`~robustrtk.pipeline.engine.run_dd`."""
    # RTK: a base epoch without carrier phases (a radio link's code-only epochs) does not serve
    wanted = base.phase_cyc if cfg.mode == "rtk" else base.code_m
    usable: BoolArray | None = np.asarray(np.isfinite(wanted[:, :, 0]).any(axis=1)) if len(base) else None
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
    "BASE_MARGIN_S",
    "EPOCH_TOL_S",
    "BASE_POSITION_TOL_M",
    "DgnssResult",
    "base_read_bounds",
    "base_spp_position",
    "check_base_position",
    "check_has_epochs",
    "check_nav_coverage",
    "load_checked",
    "nav_coverage",
    "dgnss_config",
    "first_fix_position",
    "resolve_base_position",
    "run_rows",
    "solve_dgnss",
    "select_time_window",
    "solve_spp_file",
    "time_window_mask",
    "window_set",
]
