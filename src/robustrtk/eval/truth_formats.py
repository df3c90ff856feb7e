"""Truth trajectories in foreign formats: GSDC ground truth, NMEA GGA, ``time,lat,lon,h`` CSV.

Each reader returns the epochs (GPST seconds since 1980-01-06, the solutions' time scale)
and the ECEF positions (m) of a trajectory; :mod:`robustrtk.eval.truth` wraps them in a
:class:`~robustrtk.eval.truth.Truth`.

Time scales
-----------
* GSDC 2021 ``ground_truth.csv``: ``millisSinceGpsEpoch`` is GPS time in milliseconds since
  1980-01-06, so ``t = ms / 1000``.
* GSDC 2022/2023 ``ground_truth.csv``: ``UnixTimeMillis`` is UTC in milliseconds since
  1970-01-01, so ``t = ms / 1000 - 315964800 + leap(t)`` (leap seconds from the table in
  :mod:`robustrtk.timeutil`).
* NMEA GGA: UTC time of day ``hhmmss.ss``; the date comes from an RMC (``ddmmyy``) or ZDA
  sentence of the same file. A file with GGA sentences only has no date: its epochs are
  kept as UTC seconds of day and anchored to the solutions' day when compared
  (:attr:`Truth.utc_time_of_day`).
"""

from __future__ import annotations

import math
import os

import numpy as np

from robustrtk.core import FloatArray, InputError
from robustrtk.geometry.frames import geodetic2ecef_deg
from robustrtk.timeutil import gpst_from_calendar, utc2gpst

__all__ = [
    "GSDC_TIME_COLUMNS",
    "UNIX_TO_GPS_EPOCH_S",
    "is_gsdc_header",
    "is_llh_csv_header",
    "is_nmea_line",
    "read_gsdc_truth",
    "read_llh_csv",
    "read_nmea_gga",
]

PathLike = str | os.PathLike[str]

#: Seconds from 1970-01-01 to 1980-01-06 (UTC, no leap seconds in between counted).
UNIX_TO_GPS_EPOCH_S = 315_964_800.0

#: GSDC time columns and how they map to GPST: (column, is_unix_utc).
GSDC_TIME_COLUMNS = (("millisSinceGpsEpoch", False), ("UnixTimeMillis", True))
_GSDC_LLH = (
    ("latDeg", "lngDeg", "heightAboveWgs84EllipsoidM"),
    ("LatitudeDegrees", "LongitudeDegrees", "AltitudeMeters"),
)
_LLH_CSV_NAMES = (("time", "lat", "lon", "h"), ("time", "lat", "lon", "height"))


def _header_fields(line: str) -> list[str]:
    return [f.strip() for f in line.strip().lstrip("\ufeff").split(",")]


def is_gsdc_header(line: str) -> bool:
    """Whether ``line`` is the header of a GSDC ``ground_truth.csv`` (2021, 2022 or 2023)."""
    names = set(_header_fields(line))
    has_time = any(col in names for col, _ in GSDC_TIME_COLUMNS)
    return has_time and any(set(llh) <= names for llh in _GSDC_LLH)


def is_llh_csv_header(line: str) -> bool:
    """Whether ``line`` is a ``time,lat,lon,h`` (or ``height``) CSV header."""
    head = tuple(f.lower() for f in _header_fields(line)[:4])
    return head in _LLH_CSV_NAMES


def is_nmea_line(line: str) -> bool:
    """Whether ``line`` looks like an NMEA 0183 sentence (``$`` + talker + type)."""
    s = line.strip()
    return len(s) > 6 and s[0] == "$" and s[1:6].isalnum()


def _float(text: str, what: str, path: PathLike, ln: int) -> float:
    try:
        v = float(text)
    except ValueError:
        raise InputError(f"{what}: expected a number, got {text!r}", str(path), ln) from None
    if not math.isfinite(v):
        raise InputError(f"{what}: expected a finite number, got {text!r}", str(path), ln)
    return v


def _check_llh(lat: float, lon: float, h: float, path: PathLike, ln: int) -> None:
    if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 360.0 and abs(h) < 100_000.0):
        raise InputError(
            f"expected latitude -90..90 deg, longitude -180..360 deg, height within 100 km, "
            f"got {lat}, {lon}, {h}",
            str(path),
            ln,
        )


def _ecef(lat: list[float], lon: list[float], h: list[float]) -> FloatArray:
    return np.asarray(geodetic2ecef_deg(np.array(lat), np.array(lon), np.array(h)), dtype=float).reshape(
        -1, 3
    )


def read_gsdc_truth(path: PathLike, lines: list[str]) -> tuple[FloatArray, FloatArray]:
    """Epochs (GPST s) and ECEF positions (m) of a GSDC ``ground_truth.csv``.

    Parameters
    ----------
    path : path-like
        For messages.
    lines : list of str
        The file's lines; the first is the header (:func:`is_gsdc_header`).

    Returns
    -------
    t_s : ndarray, shape (M,)
    pos_ecef_m : ndarray, shape (M, 3)
        From latitude, longitude (deg) and ellipsoidal height (m), WGS84.

    Raises
    ------
    InputError
        A row with too few fields or a non-number (file and line named), or no rows.
    """
    names = _header_fields(lines[0])
    col_t, unix = next((names.index(c), u) for c, u in GSDC_TIME_COLUMNS if c in names)
    llh = next(cols for cols in _GSDC_LLH if set(cols) <= set(names))
    i_lat, i_lon, i_h = (names.index(c) for c in llh)
    need = max(col_t, i_lat, i_lon, i_h) + 1
    t: list[float] = []
    lat: list[float] = []
    lon: list[float] = []
    h: list[float] = []
    for ln, raw in enumerate(lines[1:], start=2):
        if not raw.strip():
            continue
        f = [c.strip() for c in raw.split(",")]
        if len(f) < need:
            raise InputError(
                f"expected at least {need} fields ({', '.join(names[:need])}), got {len(f)}", str(path), ln
            )
        t.append(_float(f[col_t], names[col_t], path, ln) / 1000.0)
        la, lo, hh = (_float(f[i], names[i], path, ln) for i in (i_lat, i_lon, i_h))
        _check_llh(la, lo, hh, path, ln)
        lat.append(la)
        lon.append(lo)
        h.append(hh)
    if not t:
        raise InputError("no ground-truth rows after the header", str(path))
    t_arr = np.array(t, dtype=float)
    if unix:
        t_arr = np.asarray(utc2gpst(t_arr - UNIX_TO_GPS_EPOCH_S), dtype=float)
    return t_arr, _ecef(lat, lon, h)


def read_llh_csv(path: PathLike, lines: list[str]) -> tuple[FloatArray, FloatArray]:
    """Epochs and ECEF positions of a ``time,lat,lon,h`` CSV (time in the solutions' scale, s;
    degrees; ellipsoidal metres)."""
    t: list[float] = []
    lat: list[float] = []
    lon: list[float] = []
    h: list[float] = []
    for ln, raw in enumerate(lines[1:], start=2):
        if not raw.strip() or raw.lstrip().startswith("#"):
            continue
        f = [c.strip() for c in raw.split(",")]
        if len(f) < 4:
            raise InputError(f"expected time,lat,lon,h, got {raw.strip()!r}", str(path), ln)
        tt, la, lo, hh = (
            _float(v, name, path, ln) for v, name in zip(f[:4], ("time", "lat", "lon", "h"), strict=True)
        )
        _check_llh(la, lo, hh, path, ln)
        t.append(tt)
        lat.append(la)
        lon.append(lo)
        h.append(hh)
    if not t:
        raise InputError("no truth rows after the header", str(path))
    return np.array(t, dtype=float), _ecef(lat, lon, h)


def _nmea_checksum_ok(sentence: str) -> bool:
    body, star, tail = sentence.partition("*")
    if not star:
        return True  # no checksum field: accepted, as most readers do
    want = 0
    for ch in body[1:]:
        want ^= ord(ch)
    return tail[:2].upper() == f"{want:02X}"


def _nmea_angle(value: str, hemi: str, deg_digits: int) -> float:
    deg = float(value[:deg_digits])
    minutes = float(value[deg_digits:])
    angle = deg + minutes / 60.0
    return -angle if hemi in ("S", "W") else angle


def _tod_s(hhmmss: str) -> float:
    return int(hhmmss[0:2]) * 3600.0 + int(hhmmss[2:4]) * 60.0 + float(hhmmss[4:])


def read_nmea_gga(
    path: PathLike, lines: list[str], min_quality: int = 1, fixed_only: bool = False
) -> tuple[FloatArray, FloatArray, bool]:
    """Epochs and ECEF positions of the GGA fixes in an NMEA 0183 log.

    The height is the GGA altitude above mean sea level plus the geoid separation (field 11),
    i.e. ellipsoidal. Sentences with a bad checksum, an empty position or a fix quality
    below ``min_quality`` (0 = invalid) are skipped; with ``fixed_only`` every quality but 4
    (RTK fixed) is. The date is taken from the nearest
    preceding RMC (``ddmmyy``) or ZDA sentence; without one, the epochs stay UTC seconds of
    day (unwrapped across midnight) and the third return value is True.

    Returns
    -------
    t_s : ndarray, shape (M,)
        GPST seconds since 1980-01-06, or UTC seconds of day when no date was found.
    pos_ecef_m : ndarray, shape (M, 3)
    time_of_day : bool

    Raises
    ------
    InputError
        No usable GGA sentence, or a GGA sentence whose fields are not numbers.
    """
    t: list[float] = []
    lat: list[float] = []
    lon: list[float] = []
    h: list[float] = []
    day_s: float | None = None
    dated: list[bool] = []
    for ln, raw in enumerate(lines, start=1):
        s = raw.strip()
        if not is_nmea_line(s) or not _nmea_checksum_ok(s):
            continue
        f = s.split("*")[0].split(",")
        kind = f[0][3:]
        try:
            if kind == "RMC" and len(f) > 9 and len(f[9]) == 6:
                d, mo, y = int(f[9][0:2]), int(f[9][2:4]), 2000 + int(f[9][4:6])
                day_s = gpst_from_calendar(y, mo, d)
            elif kind == "ZDA" and len(f) > 4 and f[2] and f[3] and f[4]:
                day_s = gpst_from_calendar(int(f[4]), int(f[3]), int(f[2]))
            elif kind == "GGA" and len(f) > 11:
                if not (f[1] and f[2] and f[4] and f[6] and f[9]) or int(f[6]) < min_quality:
                    continue
                if fixed_only and int(f[6]) != 4:
                    continue
                la = _nmea_angle(f[2], f[3], 2)
                lo = _nmea_angle(f[4], f[5], 3)
                hh = float(f[9]) + (float(f[11]) if f[11] else 0.0)
                _check_llh(la, lo, hh, path, ln)
                tod = _tod_s(f[1])
                dated.append(day_s is not None)
                t.append(tod + (day_s if day_s is not None else 0.0))
                lat.append(la)
                lon.append(lo)
                h.append(hh)
        except ValueError:
            raise InputError(
                f"{kind} sentence: expected numbers in its fields, got {s!r}", str(path), ln
            ) from None
    if not t:
        what = "of quality 4 (RTK fixed)" if fixed_only else f"of quality ≥ {min_quality}"
        raise InputError(f"no GGA fix {what}; expected NMEA $..GGA sentences", str(path))
    t_arr = np.array(t, dtype=float)
    if all(dated):
        # calendar dates were UTC days: the GGA times are UTC
        t_arr = np.asarray(utc2gpst(t_arr), dtype=float)
        return t_arr, _ecef(lat, lon, h), False
    if any(dated):
        raise InputError(
            "a date (RMC/ZDA) only after the first GGA sentences; expected it before them or not at all",
            str(path),
        )
    # seconds of day: unwrap across midnight
    wraps = np.concatenate([[0.0], np.cumsum(np.diff(t_arr) < -43_200.0)]) * 86_400.0
    return t_arr + wraps, _ecef(lat, lon, h), True
