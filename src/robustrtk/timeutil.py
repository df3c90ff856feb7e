"""Time scales and conversions.

The project time ``t_s`` is GPS time in float seconds since 1980-01-06T00:00:00 GPST.
Related scales:

* UTC = GPST - leap seconds (18 s since 2017-01-01, table below);
* Galileo system time (GST) and QZSS time are aligned with GPST (same ``t_s``);
* BeiDou time: BDT = GPST - 14 s (BDT started 2006-01-01T00:00:00 UTC, GPS week 1356);
* GLONASS time = UTC + 3 h.

Calendar conversions use the proleptic Gregorian calendar with no leap seconds inside the
scale itself (each scale counts uniform 86400-second days from its own calendar).
"""

from __future__ import annotations

import math
import re

import numpy as np
import numpy.typing as npt

#: Seconds in a week.
WEEK_S = 604_800.0
#: Seconds in a day.
DAY_S = 86_400.0
#: BDT = GPST - BDT_GPST_OFFSET_S.
BDT_GPST_OFFSET_S = 14.0
#: GPS week of the BDT origin (2006-01-01T00:00:00 BDT).
BDT_WEEK0 = 1356
#: GLONASS time = UTC + GLONASS_UTC_OFFSET_S.
GLONASS_UTC_OFFSET_S = 3.0 * 3600.0

# Days from 0001-01-01 (proleptic Gregorian ordinal 1) to 1980-01-06.
_GPS_EPOCH_ORDINAL = 722_820  # date(1980, 1, 6).toordinal()

#: Leap second table: (UTC calendar date from which it applies, GPST - UTC in s).
LEAP_SECONDS_TABLE: tuple[tuple[int, int, int, int], ...] = (
    (1981, 7, 1, 1),
    (1982, 7, 1, 2),
    (1983, 7, 1, 3),
    (1985, 7, 1, 4),
    (1988, 1, 1, 5),
    (1990, 1, 1, 6),
    (1991, 1, 1, 7),
    (1992, 7, 1, 8),
    (1993, 7, 1, 9),
    (1994, 7, 1, 10),
    (1996, 1, 1, 11),
    (1997, 7, 1, 12),
    (1999, 1, 1, 13),
    (2006, 1, 1, 14),
    (2009, 1, 1, 15),
    (2012, 7, 1, 16),
    (2015, 7, 1, 17),
    (2017, 1, 1, 18),
)


def _days_from_civil(y: int, m: int, d: int) -> int:
    """Days since 1970-01-01 of a proleptic Gregorian date (H. Hinnant's algorithm)."""
    y -= m <= 2
    era = (y if y >= 0 else y - 399) // 400
    yoe = y - era * 400
    doy = (153 * (m + (-3 if m > 2 else 9)) + 2) // 5 + d - 1
    doe = yoe * 365 + yoe // 4 - yoe // 100 + doy
    return era * 146097 + doe - 719468


def _civil_from_days(z: int) -> tuple[int, int, int]:
    """Inverse of :func:`_days_from_civil`."""
    z += 719468
    era = (z if z >= 0 else z - 146096) // 146097
    doe = z - era * 146097
    yoe = (doe - doe // 1460 + doe // 36524 - doe // 146096) // 365
    y = yoe + era * 400
    doy = doe - (365 * yoe + yoe // 4 - yoe // 100)
    mp = (5 * doy + 2) // 153
    d = doy - (153 * mp + 2) // 5 + 1
    m = mp + (3 if mp < 10 else -9)
    return y + (m <= 2), m, d


_GPS_EPOCH_DAYS_1970 = _days_from_civil(1980, 1, 6)


def gpst_from_calendar(y: int, mo: int, d: int, h: int = 0, mi: int = 0, s: float = 0.0) -> float:
    """Seconds since the GPS epoch of a calendar date read in the same (uniform) scale.

    ``t_s = 86400 * (days(y, mo, d) - days(1980, 1, 6)) + 3600 h + 60 mi + s``.
    Two-digit years are not accepted here (callers expand them).
    """
    days = _days_from_civil(int(y), int(mo), int(d)) - _GPS_EPOCH_DAYS_1970
    return days * DAY_S + int(h) * 3600.0 + int(mi) * 60.0 + float(s)


def calendar_from_gpst(t_s: float) -> tuple[int, int, int, int, int, float]:
    """Calendar date ``(y, mo, d, h, mi, s)`` of ``t_s`` in the same scale (inverse of
    :func:`gpst_from_calendar`)."""
    days = math.floor(t_s / DAY_S)
    sod = t_s - days * DAY_S
    y, mo, d = _civil_from_days(days + _GPS_EPOCH_DAYS_1970)
    h = int(sod // 3600.0)
    mi = int((sod - h * 3600.0) // 60.0)
    s = sod - h * 3600.0 - mi * 60.0
    return y, mo, d, h, mi, s


def gpst_text(t_s: float, decimals: int = 3, *, date_sep: str = "/", trim_zero_fraction: bool = True) -> str:
    """Calendar text ``yyyy/mm/dd hh:mm:ss.fff`` of ``t_s`` in its own scale (GPST).

    The time is rounded to ``decimals`` decimals of a second first (so ``59.9996`` with 3
    decimals becomes the next minute, never ``60.000``).

    Parameters
    ----------
    t_s : float
        Seconds since 1980-01-06 (GPST).
    decimals : int
        Decimals of the seconds (0-9).
    date_sep : str
        Separator of year, month and day (``"/"`` as RTKLIB, ``"-"`` ISO-like).
    trim_zero_fraction : bool
        Omit the fraction when it is zero at that resolution.

    Returns
    -------
    str
        E.g. ``"2024/06/24 08:20:00"`` or ``"2024/06/24 08:20:00.250"``.
    """
    if not 0 <= decimals <= 9:
        raise ValueError(f"decimals must be 0..9, got {decimals}")
    scale = 10**decimals
    ticks = int(round(t_s * scale))
    sec, frac = divmod(ticks, scale)
    y, mo, d, h, mi, s = calendar_from_gpst(float(sec))
    sep = date_sep
    text = f"{y:04d}{sep}{mo:02d}{sep}{d:02d} {h:02d}:{mi:02d}:{int(round(s)):02d}"
    if decimals and not (trim_zero_fraction and frac == 0):
        text += f".{frac:0{decimals}d}"
    return text


_NUMBER_TEXT = re.compile(r"^[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?$")
_CALENDAR_TEXT = re.compile(
    r"^(\d{4})[/-](\d{1,2})[/-](\d{1,2})[ T]+(\d{1,2}):(\d{1,2}):(\d{1,2}(?:\.\d*)?)$"
)
_TIME_OF_DAY_TEXT = re.compile(r"^(\d{1,2}):(\d{1,2}):(\d{1,2}(?:\.\d*)?)$")


def is_time_of_day(text: str) -> bool:
    """Whether ``text`` is a bare time of day ``hh:mm:ss[.s]`` (no date)."""
    return bool(_TIME_OF_DAY_TEXT.match(text.strip()))


def parse_gpst_instant(text: str, t_ref_s: float, what: str) -> float:
    """An instant written as text, in GPST seconds since 1980-01-06.

    Accepted: a calendar time ``yyyy/mm/dd hh:mm:ss[.s]`` (``-`` between the date's
    fields and ``T`` before the time also accepted; one or two digits in every field but the
    year, as RTKLIB's ``-ts``/``-te`` read them), a time of day ``hh:mm:ss[.s]`` on the
    GPST date of ``t_ref_s``, or a number of seconds (the project's ``t_s``).

    Parameters
    ----------
    text : str
    t_ref_s : float
        An instant of the day a bare time of day falls on (GPST s), e.g. the first epoch.
    what : str
        The setting or option named in the error.

    Raises
    ------
    InputError
        Any other text, or a field out of range (month 1-12, day 1-31, hour 0-23, minute
        and second 0-59).
    """
    from robustrtk.errors import InputError

    s = text.strip()
    if _NUMBER_TEXT.match(s):
        return float(s)
    cal = _CALENDAR_TEXT.match(s)
    tod = None if cal else _TIME_OF_DAY_TEXT.match(s)
    if cal is None and tod is None:
        raise InputError(
            f"{what}: expected 'yyyy/mm/dd hh:mm:ss', 'hh:mm:ss' (on the first epoch's date) or seconds, "
            f"got {s!r}"
        )
    if cal is not None:
        y, mo, d, hh, mi = (int(g) for g in cal.groups()[:5])
        sec = float(cal.group(6))
    else:
        assert tod is not None
        y, mo, d, _, _, _ = calendar_from_gpst(math.floor(t_ref_s))
        hh, mi, sec = int(tod.group(1)), int(tod.group(2)), float(tod.group(3))
    if not (1 <= mo <= 12 and 1 <= d <= 31 and hh <= 23 and mi <= 59 and sec < 60.0):
        raise InputError(f"{what}: a field of {s!r} is out of range (month, day, hour, minute or second)")
    return gpst_from_calendar(y, mo, d, hh, mi, sec)


def gps_week_tow(
    t_s: float | npt.ArrayLike,
) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.float64]]:
    """GPS week number and time of week (s) of ``t_s`` (vectorised).

    ``week = floor(t_s / 604800)``, ``tow = t_s - 604800 week``.
    """
    t = np.asarray(t_s, dtype=float)
    week = np.floor(t / WEEK_S)
    return week.astype(np.int64), t - week * WEEK_S


def gpst_from_week_tow(week: int | npt.ArrayLike, tow_s: float | npt.ArrayLike) -> npt.NDArray[np.float64]:
    """``t_s = 604800 week + tow`` (vectorised)."""
    return np.asarray(week, dtype=float) * WEEK_S + np.asarray(tow_s, dtype=float)


def _leap_table_gpst() -> tuple[np.ndarray, np.ndarray]:
    """Leap second table with epochs converted to GPST seconds (for GPST -> UTC lookups)."""
    t_utc = np.array([gpst_from_calendar(y, m, d) for y, m, d, _ in LEAP_SECONDS_TABLE])
    leap = np.array([n for *_, n in LEAP_SECONDS_TABLE], dtype=float)
    return t_utc, leap


_LEAP_T_UTC, _LEAP_N = _leap_table_gpst()


def leap_seconds_at_utc(t_utc_s: float | npt.ArrayLike) -> npt.NDArray[np.float64]:
    """GPST - UTC (s) at UTC instants expressed as seconds since 1980-01-06 UTC."""
    t = np.asarray(t_utc_s, dtype=float)
    idx = np.searchsorted(_LEAP_T_UTC, t, side="right")
    return np.where(idx > 0, _LEAP_N[np.maximum(idx - 1, 0)], 0.0)


def leap_seconds_at_gpst(t_s: float | npt.ArrayLike) -> npt.NDArray[np.float64]:
    """GPST - UTC (s) at GPST instants ``t_s``."""
    t = np.asarray(t_s, dtype=float)
    # A leap second applies from UTC epoch T, i.e. from GPST T + n.
    idx = np.searchsorted(_LEAP_T_UTC + _LEAP_N, t, side="right")
    return np.where(idx > 0, _LEAP_N[np.maximum(idx - 1, 0)], 0.0)


def utc2gpst(t_utc_s: float | npt.ArrayLike, leap_s: float | None = None) -> npt.NDArray[np.float64]:
    """GPST seconds of a UTC instant (UTC counted in seconds since 1980-01-06 UTC).

    ``t_gpst = t_utc + leap``; ``leap`` from the table unless given (e.g. a file header).
    """
    t = np.asarray(t_utc_s, dtype=float)
    leap = leap_seconds_at_utc(t) if leap_s is None else float(leap_s)
    return t + leap


def gpst2utc(t_s: float | npt.ArrayLike, leap_s: float | None = None) -> npt.NDArray[np.float64]:
    """UTC instant (seconds since 1980-01-06 UTC) of GPST ``t_s``: ``t_utc = t_s - leap``."""
    t = np.asarray(t_s, dtype=float)
    leap = leap_seconds_at_gpst(t) if leap_s is None else float(leap_s)
    return t - leap


def bdt2gpst(t_bdt_s: float | npt.ArrayLike) -> npt.NDArray[np.float64]:
    """GPST of a BDT instant (both in seconds since 1980-01-06 of their own scale): ``+14 s``."""
    return np.asarray(t_bdt_s, dtype=float) + BDT_GPST_OFFSET_S


def gpst2bdt(t_s: float | npt.ArrayLike) -> npt.NDArray[np.float64]:
    """BDT of GPST ``t_s``: ``-14 s``."""
    return np.asarray(t_s, dtype=float) - BDT_GPST_OFFSET_S


def glot2gpst(t_glo_s: float | npt.ArrayLike, leap_s: float | None = None) -> npt.NDArray[np.float64]:
    """GPST of a GLONASS-time instant: ``t_gpst = t_glo - 3 h + leap``."""
    return utc2gpst(np.asarray(t_glo_s, dtype=float) - GLONASS_UTC_OFFSET_S, leap_s)


def gpst2glot(t_s: float | npt.ArrayLike, leap_s: float | None = None) -> npt.NDArray[np.float64]:
    """GLONASS time of GPST ``t_s``: ``t_glo = t_s - leap + 3 h``."""
    return gpst2utc(t_s, leap_s) + GLONASS_UTC_OFFSET_S
