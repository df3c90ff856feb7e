"""Records of RINEX 4.00 navigation files (``> EPH``, ``> ION``, ``> STO``, ``> EOP``).

Every record starts with a record header line ``> TYP SNN MSG`` (record type in columns 3-5,
satellite in 7-9, navigation message type from column 11), followed by its data lines.

Read:

* ``EPH`` of the message types whose orbit model the ephemeris arrays carry: GPS and QZSS
  ``LNAV``, Galileo ``INAV``/``FNAV``, BeiDou ``D1``/``D2``, GLONASS ``FDMA`` and ``SBAS``.
  The data lines are those of RINEX 3 (GLONASS: the fourth line of 4.00, status flags and
  group delay, is not kept).
* ``ION``: Klobuchar (GPS/QZSS/NavIC ``LNAV``, BeiDou ``D1D2``), NeQuick-G (Galileo ``IFNV``)
  and BDGIM (BeiDou ``CNVX``) coefficients.
* ``STO`` (system time offsets) and ``EOP`` (Earth orientation parameters).

Skipped and counted: ``EPH`` of other message types (GPS/QZSS ``CNAV``/``CNV2`` and BeiDou
``CNV1``/``CNV2``/``CNV3`` use an orbit model with semi-major axis and mean-motion rates,
NavIC ``LNAV`` is not used here) and ``ION`` of message types not listed above.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np

from robustrtk.core import InputError
from robustrtk.geometry.navdata import EarthOrientation, IonoModel, TimeOffset
from robustrtk.io.rinex_nav_fields import (
    RecordRows,
    count,
    epoch_r3,
    parse_eph_block,
    parse_fields,
)
from robustrtk.timeutil import BDT_GPST_OFFSET_S, leap_seconds_at_utc

__all__ = ["RECORD_TYPES", "EPH_READ", "V4Messages", "read_v4_records"]

#: Record types of RINEX 4.00 navigation files.
RECORD_TYPES = ("EPH", "STO", "EOP", "ION")

#: EPH message types read per system, with the orbit lines expected after the epoch line.
EPH_READ: dict[tuple[str, str], int] = {
    ("G", "LNAV"): 7,
    ("J", "LNAV"): 7,
    ("E", "INAV"): 7,
    ("E", "FNAV"): 7,
    ("C", "D1"): 7,
    ("C", "D2"): 7,
    ("R", "FDMA"): 3,
    ("S", "SBAS"): 3,
}

# ION message types read: model and data lines after the epoch line.
_ION_READ: dict[tuple[str, str], tuple[str, int]] = {
    ("G", "LNAV"): ("klobuchar", 2),
    ("J", "LNAV"): ("klobuchar", 2),
    ("I", "LNAV"): ("klobuchar", 2),
    ("C", "D1D2"): ("klobuchar", 2),
    ("E", "IFNV"): ("nequick_g", 1),
    ("C", "CNVX"): ("bdgim", 2),
}

_SAT = re.compile(r"[GRECJSI][ 0-9]\d")
_MSG = re.compile(r"[A-Z0-9]{1,4}")


@dataclass
class V4Messages:
    """Non-ephemeris messages of RINEX 4 files.

    Attributes
    ----------
    iono : list of IonoModel
    sto : list of TimeOffset
    eop : list of EarthOrientation
    """

    iono: list[IonoModel] = field(default_factory=list)
    sto: list[TimeOffset] = field(default_factory=list)
    eop: list[EarthOrientation] = field(default_factory=list)


def _to_gpst(system: str, t_sys: float, leap_s: int | None) -> float:
    """Project time of an epoch written in the broadcasting system's own scale."""
    if system == "C":
        return t_sys + BDT_GPST_OFFSET_S
    if system == "R":
        leap = float(leap_s) if leap_s is not None else float(leap_seconds_at_utc(t_sys))
        return t_sys + leap
    return t_sys


def _records(lines: list[str], start: int, path: str) -> Iterator[tuple[int, str, str, str, list[str]]]:
    """Yield ``(line_index, type, sat, message, data_lines)`` per record after the header."""
    i = start
    n = len(lines)
    while i < n:
        line = lines[i]
        if not line.strip():
            i += 1
            continue
        ln = i + 1
        if not line.startswith(">"):
            raise InputError(
                f"expected a record header line '> EPH|STO|EOP|ION SNN TYPE', got {line[:30].rstrip()!r}",
                path=path,
                line=ln,
            )
        kind = line[2:5]
        if line[1:2] != " " or kind not in RECORD_TYPES:
            raise InputError(
                f"bad record header {line.rstrip()!r}: expected record type EPH, STO, EOP or ION "
                "in columns 3-5",
                path=path,
                line=ln,
            )
        sat = line[6:9]
        system_only = kind != "EPH" and bool(re.fullmatch(r"[GRECJSI]  ", sat))
        if not (_SAT.fullmatch(sat) or system_only) or line[5:6] != " ":
            raise InputError(
                f"bad record header {line.rstrip()!r}: expected a satellite (system letter "
                "G R E C J S I and number) in columns 7-9",
                path=path,
                line=ln,
            )
        msg = line[10:].split()[0] if line[10:].strip() else ""
        if line[9:10] != " " or not _MSG.fullmatch(msg):
            raise InputError(
                f"bad record header {line.rstrip()!r}: expected a navigation message type "
                "(e.g. LNAV, INAV, D1, FDMA) from column 11",
                path=path,
                line=ln,
            )
        j = i + 1
        while j < n and not lines[j].startswith(">"):
            j += 1
        data = lines[i + 1 : j]
        while data and not data[-1].strip():
            data.pop()
        # a system-wide STO/ION/EOP record may name its system alone ('> STO E   IFNV')
        yield i, kind, sat[0] if system_only else sat.replace(" ", "0"), msg, data
        i = j


def _need(data: list[str], n: int, what: str, path: str, ln: int) -> None:
    if len(data) < n:
        raise InputError(f"{what} has {len(data)} data lines, expected {n}", path=path, line=ln)


def _values(data: list[str], n_lines: int, path: str, ln: int) -> list[float]:
    """3 values after the epoch of the first data line, then 4 per continuation line."""
    vals = parse_fields(data[0], 23, 3, path, ln + 1)
    for k in range(1, n_lines + 1):
        vals += parse_fields(data[k], 4, 4, path, ln + 1 + k)
    return vals


def _finite(vals: list[float], n: int, what: str, path: str, ln: int) -> None:
    bad = [k for k in range(n) if math.isnan(vals[k])]
    if bad:
        raise InputError(f"{what} is incomplete (value {bad[0] + 1} of {n} missing)", path=path, line=ln)


def read_v4_records(
    lines: list[str],
    start: int,
    path: str,
    rows: RecordRows,
    msgs: V4Messages,
    leap_s: int | None,
) -> None:
    """Parse the records of a RINEX 4 navigation file into ``rows`` and ``msgs``.

    Parameters
    ----------
    lines : list of str
        All lines of the file.
    start : int
        0-based index of the first line after ``END OF HEADER``.
    path : str
        File name for error messages.
    rows : RecordRows
        Ephemerides (appended to); record counts and skipped records are added there.
    msgs : V4Messages
        ION, STO and EOP messages (appended to).
    leap_s : int or None
        Header leap seconds (GLONASS epochs are UTC).

    Raises
    ------
    InputError
        Malformed record header, record of the wrong satellite, too few data lines, bad epoch
        or number (names the file and line).
    """
    for i, kind, sat, msg, data in _records(lines, start, path):
        ln = i + 1
        system = sat[0]
        label = f"{kind} {system} {msg}"
        if kind == "EPH":
            need = EPH_READ.get((system, msg))
            if need is None:
                count(rows.skipped_records, label)
                count(rows.skipped, system)
                continue
            _need(data, 1 + need, f"{label} record of {sat}", path, ln)
            first = data[0][:3].replace(" ", "0")
            if first != sat:
                raise InputError(
                    f"{label} record of {sat}: the first data line names {data[0][:3]!r} in "
                    f"columns 1-3, expected {sat}",
                    path=path,
                    line=ln + 1,
                )
            parse_eph_block(rows, system, sat, data, ln + 1, path, leap_s, need)
            count(rows.counts, label)
        elif kind == "ION":
            spec = _ION_READ.get((system, msg))
            if spec is None:
                count(rows.skipped_records, label)
                continue
            model, n_cont = spec
            _need(data, 1 + n_cont, f"{label} record", path, ln)
            t = _to_gpst(system, epoch_r3(data[0], path, ln + 1), leap_s)
            vals = _values(data, n_cont, path, ln)
            flags = math.nan
            if model == "klobuchar":
                _finite(vals, 8, f"{label} record", path, ln)
                coeffs = vals[:8]
                flags = vals[8]
            elif model == "nequick_g":
                _finite(vals, 3, f"{label} record", path, ln)
                coeffs = vals[:3]
                flags = vals[3]
            else:  # BDGIM alpha1..alpha9
                _finite(vals, 9, f"{label} record", path, ln)
                coeffs = vals[:9]
            msgs.iono.append(IonoModel(sat, msg, model, t, np.asarray(coeffs, dtype=float), flags))
            count(rows.counts, label)
        elif kind == "STO":
            _need(data, 2, f"{label} record", path, ln)
            head = data[0]
            t = _to_gpst(system, epoch_r3(head, path, ln + 1), leap_s)
            code = head[24:42].strip()
            if not code:
                raise InputError(
                    f"{label} record: expected a time offset identifier (e.g. GPUT) in columns 25-42",
                    path=path,
                    line=ln + 1,
                )
            v = parse_fields(data[1], 4, 4, path, ln + 2)
            _finite(v, 2, f"{label} record", path, ln)
            msgs.sto.append(
                TimeOffset(
                    sat_id=sat,
                    message=msg,
                    t_s=t,
                    code=code,
                    sbas_id=head[42:60].strip(),
                    utc_id=head[60:78].strip(),
                    t_tot_s=v[0],
                    a0_s=v[1],
                    a1_s_s=0.0 if math.isnan(v[2]) else v[2],
                    a2_s_s2=0.0 if math.isnan(v[3]) else v[3],
                )
            )
            count(rows.counts, label)
        else:  # EOP
            _need(data, 3, f"{label} record", path, ln)
            t = _to_gpst(system, epoch_r3(data[0], path, ln + 1), leap_s)
            x = parse_fields(data[0], 23, 3, path, ln + 1)
            y = parse_fields(data[1], 4, 4, path, ln + 2)[1:]
            u = parse_fields(data[2], 4, 4, path, ln + 3)
            _finite(x + y + u[:2], 8, f"{label} record", path, ln)
            u = [0.0 if math.isnan(a) else a for a in u]
            msgs.eop.append(EarthOrientation(sat, msg, t, *x, *y, *u))
            count(rows.counts, label)
