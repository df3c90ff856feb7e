"""Fixed layout of RINEX 2/3 observation files: header records, epoch lines, field columns.

This module knows where things are in the plain RINEX text and parses the parts read line
by line (header, epoch lines); it does not decode the observation values into arrays
(:mod:`robustrtk.io.rinex_obs` does that). It is shared by the reader and by the fault
injection of :mod:`robustrtk.sim.inject`, which rewrites observation fields in place. The
epoch lines are scanned by :mod:`robustrtk.io.rinex_epochs`.

Observation record layout
-------------------------
Every observation is one ``F14.3 I1 I1`` field of :data:`OBS_FIELD_WIDTH` = 16 characters:
the value in :data:`OBS_VALUE_WIDTH` = 14 columns, then the loss-of-lock indicator (LLI) at
offset :data:`LLI_OFFSET` and the signal strength indicator (SSI) at :data:`SSI_OFFSET`.

* RINEX 3: one line per satellite, the 3-character satellite id
  (:data:`V3_SAT_ID_WIDTH`) followed by the fields of the system's observation types.
* RINEX 2: the satellite ids are on the epoch line(s) (:data:`V2_SATS_PER_LINE` per line,
  columns 33-68), each record has :data:`V2_OBS_PER_LINE` fields per 80-column line.

:func:`field_position` gives the (line, column) of observation ``j`` of a record.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from robustrtk.core import FloatArray, InputError

__all__ = [
    "LLI_OFFSET",
    "OBS_FIELD_WIDTH",
    "OBS_VALUE_WIDTH",
    "RINEX2_SIGNAL_MAP",
    "SSI_OFFSET",
    "SYSTEM_ORDER",
    "V2_LINE_WIDTH",
    "V2_OBS_PER_LINE",
    "V2_SATS_PER_LINE",
    "V3_SAT_ID_WIDTH",
    "RinexObsHeader",
    "I64Array",
    "U8Array",
    "field_position",
    "join_stray_blank",
    "parse_float",
    "parse_obs_header",
    "rinex3_signal",
    "v2_lines_per_record",
]

U8Array = npt.NDArray[np.uint8]
I64Array = npt.NDArray[np.int64]

#: Characters of one observation field: ``F14.3`` value, LLI digit, SSI digit.
OBS_FIELD_WIDTH = 16
#: Characters of the ``F14.3`` value (3 decimals, point in the 11th column).
OBS_VALUE_WIDTH = 14
#: Offset of the loss-of-lock indicator digit inside an observation field.
LLI_OFFSET = 14
#: Offset of the signal strength indicator digit inside an observation field.
SSI_OFFSET = 15
#: Characters of the satellite id that starts a RINEX 3 record (``"G05"``).
V3_SAT_ID_WIDTH = 3
#: Observation fields per line of a RINEX 2 record.
V2_OBS_PER_LINE = 5
#: Width of a RINEX 2 record line (columns).
V2_LINE_WIDTH = 80
#: Satellite ids per RINEX 2 epoch line (continuation lines carry the rest).
V2_SATS_PER_LINE = 12

#: System letters in output order.
SYSTEM_ORDER = "GRECJSI"


def _r2_map() -> dict[str, dict[str, str]]:
    gps = {
        "C1": "1C", "P1": "1W", "L1": "1C", "D1": "1C", "S1": "1C",
        "C2": "2L", "P2": "2W", "L2": "2W", "D2": "2W", "S2": "2W",
        "C5": "5X", "L5": "5X", "D5": "5X", "S5": "5X",
    }  # fmt: skip
    glo = {
        "C1": "1C", "P1": "1P", "L1": "1C", "D1": "1C", "S1": "1C",
        "C2": "2C", "P2": "2P", "L2": "2P", "D2": "2P", "S2": "2P",
    }  # fmt: skip
    gal = {t + b: b + "X" for b in "15786" for t in "CLDS"}
    sbas = {t + "1": "1C" for t in "CLDS"} | {t + "5": "5X" for t in "CLDS"}
    return {"G": gps, "J": dict(gps), "R": glo, "E": gal, "S": sbas}


#: RINEX 2 observation code -> RINEX 3 signal name, per system (see module docstring).
RINEX2_SIGNAL_MAP: dict[str, dict[str, str]] = _r2_map()


def v2_lines_per_record(n_obs: int) -> int:
    """Lines of one RINEX 2 satellite record with ``n_obs`` observation types (at least 1)."""
    return max(1, -(-n_obs // V2_OBS_PER_LINE))


def field_position(v3: bool, rec_line: int, j: int) -> tuple[int, int]:
    """Where observation ``j`` of a satellite record is.

    Parameters
    ----------
    v3 : bool
        RINEX 3 (one line per record, after the satellite id) or RINEX 2 layout.
    rec_line : int
        0-based line index of the record's first line.
    j : int
        0-based index of the observation type in the header's list.

    Returns
    -------
    line : int
        0-based line index of the field.
    col : int
        0-based column of the first character of the ``F14.3`` value.
    """
    if v3:
        return rec_line, V3_SAT_ID_WIDTH + OBS_FIELD_WIDTH * j
    return rec_line + j // V2_OBS_PER_LINE, OBS_FIELD_WIDTH * (j % V2_OBS_PER_LINE)


def rinex3_signal(system: str, code: str, version: float) -> str:
    """RINEX 3 signal name (band + attribute) of a 3-character RINEX 3 observation code.

    In RINEX 3.00-3.02 BeiDou B1I/Q/X is written with band 1 (``C1I``); it is renamed to the
    3.03+ band 2 (``"2I"``) so that the carrier is right.

    Parameters
    ----------
    system : str
        System letter.
    code : str
        Observation code (``"L1C"``).
    version : float
        RINEX version of the file.

    Returns
    -------
    str
        Signal name (``"1C"``).
    """
    sig = code[1:]
    if system == "C" and version < 3.03 and code[1:2] == "1" and code[2:3] in ("I", "Q", "X"):
        sig = "2" + code[2]
    return sig


# --------------------------------------------------------------------------------------------
# header


@dataclass
class RinexObsHeader:
    """The header records of a RINEX observation file that the readers use.

    Attributes
    ----------
    version : float
        ``RINEX VERSION / TYPE`` version (2.10 ... 4.00).
    file_system : str
        Satellite system letter of the file (column 41; blank means ``"G"``, ``"M"`` mixed).
    marker : str
        ``MARKER NAME``.
    receiver_type, antenna_type : str
        ``REC # / TYPE / VERS`` and ``ANT # / TYPE`` types.
    approx_pos_m : ndarray, shape (3,), or None
        ``APPROX POSITION XYZ`` (ECEF, m).
    interval_s : float
        ``INTERVAL`` (s; NaN when absent).
    time_system : str
        Time system of ``TIME OF FIRST OBS`` (``"GPS"``, ``"GLO"``, ...; empty when blank).
    first_obs : str
        ``"date"`` when ``TIME OF FIRST OBS`` holds a date, ``"zero"`` when it is all zeros or
        blank, ``""`` when the header has no such record.
    leap_s : int or None
        ``LEAP SECONDS`` (s).
    obs_types : dict str -> list of str
        RINEX 3 ``SYS / # / OBS TYPES``: observation codes per system letter, in file order.
    obs_types2 : list of str
        RINEX 2 ``# / TYPES OF OBSERV``: observation codes, in file order, up to the
        declared count.
    obs_types2_listed : list of str
        The same record's codes as listed, beyond the declared count too.
    glo_channel : dict str -> int
        ``GLONASS SLOT / FRQ #``: frequency channel per satellite id (``"R05"``).
    scale : dict str -> dict str -> float
        ``SYS / SCALE FACTOR``: factor per system and observation code (``"*"``: all codes).
    n_lines : int
        Number of header lines including ``END OF HEADER``.
    notes : list of str
        Oddities tolerated while reading the header (one sentence each, with its line).
    """

    version: float = math.nan
    file_system: str = "G"
    marker: str = ""
    receiver_type: str = ""
    antenna_type: str = ""
    approx_pos_m: FloatArray | None = None
    interval_s: float = math.nan
    time_system: str = ""
    first_obs: str = ""
    leap_s: int | None = None
    obs_types: dict[str, list[str]] = field(default_factory=dict)  # v3 per system
    obs_types2: list[str] = field(default_factory=list)  # v2
    obs_types2_listed: list[str] = field(default_factory=list)
    glo_channel: dict[str, int] = field(default_factory=dict)
    scale: dict[str, dict[str, float]] = field(default_factory=dict)
    n_lines: int = 0  # number of header lines including END OF HEADER
    notes: list[str] = field(default_factory=list)


# patterns of rare header and error checks: compiled (and cached by :mod:`re`) on first use
_GLO_PAIR = r"R([ \d]\d)\s+([-+]?\d{1,2})"
_GLO_SLOT = r"(\s*R[ \d]\d\s+[-+]?\d{1,2})*\s*"


def _int(s: str, path: str, line: int, what: str) -> int:
    try:
        return int(s)
    except ValueError:
        raise InputError(f"{what}: expected an integer, found {s.strip()!r}", path, line) from None


def parse_float(s: str, path: str, line: int, what: str) -> float:
    """``float`` of a RINEX field (``D`` exponents too), or :class:`InputError` naming ``what``."""
    try:
        return float(s.replace("D", "E").replace("d", "e"))
    except ValueError:
        raise InputError(f"{what}: expected a number, found {s.strip()!r}", path, line) from None


#: A number written with one stray blank next to its decimal point (``0 .0000000``,
#: ``0. 5000000``), as some converters write seconds fields.
_STRAY_BLANK = re.compile(r"\s*([-+]?\d+)( +\.\d*|\. +\d+)\s*")


def join_stray_blank(s: str) -> str | None:
    """``s`` with a single run of blanks next to its decimal point removed (``"0 .0000000"``
    -> ``"0.0000000"``), or None when ``s`` is not such a number."""
    m = _STRAY_BLANK.fullmatch(s)
    return m.group(1) + m.group(2).replace(" ", "") if m else None


def _approx_position(line: str, path: str, i: int, notes: list[str]) -> FloatArray:
    """``APPROX POSITION XYZ``: three F14.4 fields, or (noted) three blank-separated numbers
    when a writer shifted the columns."""
    label = "APPROX POSITION XYZ"
    try:
        xyz = [parse_float(line[c : c + 14], path, i, label) for c in (0, 14, 28)]
    except InputError:
        parts = line[:60].split()
        try:
            xyz = [float(t) for t in parts]
        except ValueError:
            xyz = []
        if len(xyz) != 3:
            raise
        notes.append(
            f"line {i}: {label} not in the columns RINEX fixes (3 x F14.4); read as three "
            "blank-separated numbers"
        )
    return np.array(xyz, dtype=float)


def _check_type_counts(
    h: RinexObsHeader, n2: int, listed2: int, listed3: dict[str, tuple[int, int, int]], path: str, line: int
) -> None:
    """:class:`InputError` when a header's observation-type count disagrees with its list in
    a way that changes how the records are laid out.

    As RTKLIB, the types are read up to the declared count: a list shorter than its count
    gives the listed types (the records carry those), a longer one its first ``count``
    (RINEX 3 records are one line, their extra fields unread). In RINEX 2 a record takes
    one line per five types, so a count and a list that need a different number of lines
    leave the records unreadable and are refused.
    """
    if h.version < 3.0 and listed2 != n2 and v2_lines_per_record(n2) != v2_lines_per_record(listed2):
        raise InputError(
            f"# / TYPES OF OBSERV: the header declares {n2} observation types but lists {listed2} "
            "(records of a different number of lines)",
            path,
            line,
        )
    for s, (n_dec, n_list, at) in listed3.items():
        if n_list == 0 and n_dec > 0:
            raise InputError(
                f"SYS / # / OBS TYPES: system {s!r} declares {n_dec} observation types but lists none",
                path,
                at,
            )


def _check_first_obs(line: str, path: str, i: int, notes: list[str]) -> str:
    """:class:`InputError` unless ``TIME OF FIRST OBS`` holds a calendar date and time, or
    zeros or blanks (written by some converters; the first epoch gives the time, as RTKLIB).
    Seconds with a stray blank next to the point are read (noted in ``notes``).

    Returns
    -------
    str
        ``"zero"`` (all zeros or blank) or ``"date"``."""
    what = "TIME OF FIRST OBS"
    if not line[:43].replace("0", "").replace(".", "").strip():
        return "zero"
    y, mo, d, hh, mi = (_int(line[c : c + 6], path, i, what) for c in (0, 6, 12, 18, 24))
    joined = join_stray_blank(line[30:43])
    if joined is not None:
        notes.append(f"line {i}: {what} seconds {line[30:43].strip()!r} (a stray blank) read as {joined}")
    sec = parse_float(line[30:43] if joined is None else joined, path, i, what)
    if not (
        1980 <= y <= 2200 and 1 <= mo <= 12 and 1 <= d <= 31 and 0 <= hh <= 24 and 0 <= mi <= 59
        and 0.0 <= sec < 61.0
    ):  # fmt: skip
        raise InputError(
            f"{what}: expected year month day hour minute second, found {line[:43].strip()!r}", path, i
        )
    return "date"


def parse_obs_header(lines: list[str], path: str) -> RinexObsHeader:
    """Parse the header of a RINEX 2/3 observation file.

    Parameters
    ----------
    lines : list of str
        The file's lines from the first one (``RINEX VERSION / TYPE``, after any blank lines) up to
        ``END OF HEADER``; later lines are ignored.
    path : str
        File name for messages.

    Returns
    -------
    RinexObsHeader

    Raises
    ------
    InputError
        Bad ``RINEX VERSION / TYPE`` line, not an observation file, unsupported version,
        malformed record, missing ``END OF HEADER`` (message names file, line and reason).
    """
    h = RinexObsHeader()
    skip = 0  # blank lines before the first one (RTKLIB skips them)
    while skip < len(lines) - 1 and not lines[skip].strip():
        skip += 1
    if not lines or lines[skip][60:].strip() != "RINEX VERSION / TYPE":
        raise InputError(
            "bad version header: the first line must carry 'RINEX VERSION / TYPE' in columns 61-80",
            path,
            skip + 1,
        )
    first = lines[skip]
    h.version = parse_float(first[0:9], path, skip + 1, "RINEX VERSION / TYPE version")
    if not (2.0 <= h.version < 5.0):
        raise InputError(f"unsupported RINEX version {h.version}", path, skip + 1)
    if first[20:21] != "O":
        raise InputError(
            f"not an observation file: file type {first[20:21]!r} in column 21, expected 'O'",
            path,
            skip + 1,
        )
    h.file_system = first[40:41].strip() or "G"
    pending_sys = ""  # v3 obs types continuation
    pending_n = 0
    pending_scale: tuple[str, float, int] | None = None
    n2 = 0
    listed2 = 0  # RINEX 2 observation codes listed, and per RINEX 3 system (declared, listed, line)
    listed3: dict[str, tuple[int, int, int]] = {}
    for i, line in enumerate(lines[skip + 1 :], start=skip + 2):
        label = line[60:].strip()
        if label == "END OF HEADER":
            h.n_lines = i
            _check_type_counts(h, n2, listed2, listed3, path, i)
            return h
        if label == "MARKER NAME":
            h.marker = line[:60].strip()
        elif label == "REC # / TYPE / VERS":
            h.receiver_type = line[20:40].strip()
        elif label == "ANT # / TYPE":
            h.antenna_type = line[20:40].strip()
        elif label == "APPROX POSITION XYZ":
            h.approx_pos_m = _approx_position(line, path, i, h.notes)
        elif label == "INTERVAL":
            h.interval_s = parse_float(line[0:10], path, i, label)
        elif label == "TIME OF FIRST OBS":
            h.time_system = line[48:51].strip()
            h.first_obs = _check_first_obs(line, path, i, h.notes)
        elif label == "LEAP SECONDS":
            h.leap_s = _int(line[0:6], path, i, label)
        elif label == "# / TYPES OF OBSERV":
            if line[0:6].strip():
                n2 = _int(line[0:6], path, i, label)
            for k in range(9):
                t = line[6 + 6 * k + 4 : 6 + 6 * k + 6].strip()
                listed2 += bool(t)
                if t:
                    h.obs_types2_listed.append(t)
                if t and len(h.obs_types2) < n2:
                    h.obs_types2.append(t)
        elif label == "SYS / # / OBS TYPES":
            if line[0:1].strip():
                pending_sys = line[0]
                pending_n = _int(line[3:6], path, i, label)
                h.obs_types[pending_sys] = []
            elif not pending_sys:
                raise InputError(f"{label}: continuation line without a system", path, i)
            if line[0:1].strip():
                listed3[pending_sys] = (pending_n, 0, i)
            for k in range(13):
                t = line[7 + 4 * k : 10 + 4 * k].strip()
                if t:
                    n_dec, n_list, at = listed3[pending_sys]
                    listed3[pending_sys] = (n_dec, n_list + 1, at)
                if t and len(h.obs_types[pending_sys]) < pending_n:
                    h.obs_types[pending_sys].append(t)
        elif label == "GLONASS SLOT / FRQ #":
            # nominally I3,1X,8(A1,I2.2,1X,I2,1X); some writers shift the columns, so the
            # (slot, channel) pairs are matched by pattern
            body = line[3:60] if line[:3].strip().isdigit() else line[:60]
            if body.strip() and not re.fullmatch(_GLO_SLOT, body):
                raise InputError(f"{label}: expected 'Rnn k' pairs, found {body.strip()!r}", path, i)
            for m in re.finditer(_GLO_PAIR, body):
                h.glo_channel["R" + m.group(1).replace(" ", "0")] = int(m.group(2))
        elif label == "SYS / SCALE FACTOR":
            if line[0:1].strip():
                fac = parse_float(line[2:6], path, i, label)
                n = _int(line[8:10], path, i, label) if line[8:10].strip() else 0
                pending_scale = (line[0], fac, n)
                h.scale.setdefault(line[0], {})
                if n == 0:
                    h.scale[line[0]]["*"] = fac
            if pending_scale is not None:
                s, fac, _ = pending_scale
                for k in range(12):
                    t = line[10 + 4 * k : 14 + 4 * k].strip()
                    if t:
                        h.scale[s][t] = fac
    raise InputError("missing END OF HEADER", path)
