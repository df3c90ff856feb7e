"""GNSS inputs of a solve: observations read by content, the time window, the checks.

:func:`load_obs` reads a receiver's observations (RINEX 2/3/4, Hatanaka, gzip, or any
registered reader), within a time window (:func:`time_window_mask`, RTKLIB's
``-ts``/``-te``/``-ti``) or the bounds a base is read over (:func:`base_read_bounds`);
:func:`load_checked` adds the checks every GNSS solve needs (some epochs, navigation data
covering them); :func:`nav_source` turns navigation input into an ephemeris source.
"""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np

from robustrtk.core import FloatArray, InputError, ObsBatch
from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.geometry.receivers import PositionSource
from robustrtk.io.readers import detect_format, read_navigation, read_observations
from robustrtk.io.rinex_nav import NavData
from robustrtk.io.rinex_obs import read_rinex_obs
from robustrtk.measurement.code_noise import receiver_code_sigma_m
from robustrtk.measurement.signals import RowSource
from robustrtk.pipeline.config import Config, GnssConfig
from robustrtk.timeutil import WEEK_S, gpst_text, is_time_of_day, parse_gpst_instant

PathLike = str | os.PathLike[str]


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
    return nav_coverage_of(np.asarray(batch.t_s, float), set(batch.system), eph)


def nav_coverage_of(t_s: FloatArray, systems: set[str], eph: EphemerisSource) -> float:
    """:func:`nav_coverage` of epochs ``t_s`` (GPST s) of a receiver whose observations
    hold ``systems`` (letters)."""
    t = np.asarray(t_s, float)
    if t.size == 0:
        return 0.0
    covered = np.zeros(t.shape, bool)
    tables: list[tuple[str, FloatArray]] = [
        (k, np.asarray(v.toe_s, float)) for k, v in eph.nav.kepler.items()
    ]
    if len(eph.nav.glonass):
        tables.append(("R", np.asarray(eph.nav.glonass.toe_s, float)))
    present = systems
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


def data_code_sigma(
    cfg: Config,
    rover: ObsBatch,
    base: ObsBatch,
    eph: EphemerisSource,
    rover_pos_m: FloatArray,
    base_pos: FloatArray | PositionSource,
    min_ratio: float = 1.0,
) -> tuple[Config, tuple[float | None, float | None]]:
    """``cfg`` with ``code_sigma_m`` raised to what the receivers' code shows
    (:func:`robustrtk.measurement.code_noise.receiver_code_sigma_m`), and the two
    estimates (rover, base; None where the data do not tell).

    Only with ``code_sigma_from_data`` and elevation weighting; never lowered. The DD code
    variance is the sum of the two receivers', so the one σ of both is
    ``√((σ_r² + σ_b²) / 2)`` (the configured σ standing in for a receiver without an
    estimate). With ``min_ratio`` > 1 the configured σ is kept unless the data's exceeds it
    by more than that factor (DGNSS: the robust test's rejection threshold, algorithms.md
    §39)."""
    m = cfg.measurement
    if not m.code_sigma_from_data or m.weighting != "elevation":
        return cfg, (None, None)
    src = RowSource(eph)
    pos_b = base_pos if isinstance(base_pos, np.ndarray) else rover_pos_m
    s_r = receiver_code_sigma_m(rover, src, rover_pos_m)
    s_b = receiver_code_sigma_m(base, src, np.asarray(pos_b, float))
    if s_r is None and s_b is None:
        return cfg, (s_r, s_b)
    sig = float(np.sqrt(((s_r or m.code_sigma_m) ** 2 + (s_b or m.code_sigma_m) ** 2) / 2.0))
    if not sig > min_ratio * m.code_sigma_m:
        return cfg, (s_r, s_b)
    return cfg.updated(code_sigma_m=min(sig, 30.0)), (s_r, s_b)


__all__ = [
    "BASE_MARGIN_S",
    "EPOCH_TOL_S",
    "PathLike",
    "base_read_bounds",
    "data_code_sigma",
    "check_has_epochs",
    "check_nav_coverage",
    "load_checked",
    "load_obs",
    "nav_coverage",
    "nav_coverage_of",
    "nav_source",
    "select_time_window",
    "time_window_mask",
    "window_set",
]
