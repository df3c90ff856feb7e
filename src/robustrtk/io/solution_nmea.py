"""NMEA GGA sentences from solutions.

See :mod:`robustrtk.io.solution` for the status mapping (GGA quality).
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np
import numpy.typing as npt

from robustrtk.core import InputError, Solution
from robustrtk.geometry.frames import ecef2geodetic
from robustrtk.io.solution_pos import satellites
from robustrtk.io.solution_table import (
    PathLike,
    check_status,
    open_atomic_text,
    require_ecef,
    writable_solutions,
)
from robustrtk.timeutil import gpst2utc

__all__ = ["DIFFERENTIAL_STATUSES", "gga_sentence", "nmea_checksum", "write_nmea"]

_GGA_OF_STATUS = {"fixed": 4, "partial": 4, "float": 5, "dgnss": 2, "code": 2, "single": 1}


def nmea_checksum(sentence_body: str) -> str:
    """XOR of the characters between ``$`` and ``*`` as two upper-case hex digits."""
    cs = 0
    for ch in sentence_body:
        cs ^= ord(ch)
    return f"{cs:02X}"


def _angle_ddmm(value_deg: float, deg_digits: int) -> str:
    minutes = round(abs(value_deg) * 60.0, 7)
    deg = int(minutes // 60.0)
    mins = minutes - deg * 60.0
    return f"{deg:0{deg_digits}d}{mins:010.7f}"


#: Statuses of a differential solution: GGA field 13 carries their age of differential.
DIFFERENTIAL_STATUSES = ("fixed", "partial", "float", "dgnss", "code")


def gga_sentence(
    t_s: float, pos_ecef_m: npt.ArrayLike, status: str, n_used: int, age_s: float | None = None
) -> str:
    """One ``$GPGGA`` sentence (without line terminator).

    Time is UTC (GPST minus leap seconds) as ``hhmmss.ss``; latitude ``ddmm.mmmmmmm``,
    longitude ``dddmm.mmmmmmm``; quality from the status (see module table); satellites =
    ``n_used``; HDOP left empty; altitude = ellipsoidal height with geoid separation 0
    (no geoid model here), both in metres; field 13 = age of differential ``age_s`` (s,
    one decimal) for a differential status, empty otherwise or when None; station ID empty.
    """
    check_status(status)
    if status == "none":
        raise InputError("status 'none' has no GGA quality")
    p = np.asarray(pos_ecef_m, dtype=float).reshape(3)
    if not np.all(np.isfinite(p)):
        raise InputError("position is not finite")
    lat, lon, h = (float(v) for v in ecef2geodetic(p))
    cs = int(round(float(gpst2utc(t_s)) * 100.0))
    sod_cs = cs % (86_400 * 100)
    hh, rem = divmod(sod_cs, 360_000)
    mm, rem = divmod(rem, 6_000)
    ss, cc = divmod(rem, 100)
    lat_deg, lon_deg = math.degrees(lat), math.degrees(lon)
    age_text = ""
    if age_s is not None and status in DIFFERENTIAL_STATUSES and math.isfinite(age_s):
        age_text = f"{max(float(age_s), 0.0):.1f}"
    body = (
        f"GPGGA,{hh:02d}{mm:02d}{ss:02d}.{cc:02d},"
        f"{_angle_ddmm(lat_deg, 2)},{'N' if lat_deg >= 0 else 'S'},"
        f"{_angle_ddmm(lon_deg, 3)},{'E' if lon_deg >= 0 else 'W'},"
        f"{_GGA_OF_STATUS[status]},{min(max(int(n_used), 0), 99):02d},,"
        f"{h:.4f},M,0.000,M,{age_text},"
    )
    return f"${body}*{nmea_checksum(body)}"


def write_nmea(solutions: Iterable[Solution], path: PathLike, *, pos_frame: str = "ecef") -> None:
    """Write one GGA sentence per solution (``\\r\\n`` terminated); see :func:`gga_sentence`.

    Epochs with status ``"none"`` or a non-finite position are skipped. ``pos_frame`` is
    the frame of the positions as the solver reports it; ``"local"`` is refused (NMEA holds
    geodetic positions).
    """
    require_ecef(pos_frame, "NMEA", path)
    sols = writable_solutions(solutions)
    with open_atomic_text(path, newline="") as fh:
        for s in sols:
            fh.write(gga_sentence(s.t_s, s.pos_m, s.status, satellites(s), s.age_s) + "\r\n")
