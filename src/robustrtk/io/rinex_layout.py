"""Fixed layout of RINEX 2/3 observation files: header records, epoch lines, field columns.

This module knows where things are in the plain RINEX text and parses the parts read line
by line (header, epoch lines); it does not decode the observation values into arrays
(:mod:`robustrtk.io.rinex_obs` does that). It is shared by the reader and by the fault
injection of :mod:`robustrtk.sim.inject`, which rewrites observation fields in place.

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
from robustrtk.timeutil import gpst_from_calendar

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
    "RinexEpochs",
    "RinexObsHeader",
    "RinexObsText",
    "U8Array",
    "check_event_records",
    "epoch_time",
    "field_position",
    "parse_obs_header",
    "rinex3_signal",
    "scan_epochs_v2",
    "scan_epochs_v3",
    "scan_obs_text",
    "split_lines",
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
    leap_s : int or None
        ``LEAP SECONDS`` (s).
    obs_types : dict str -> list of str
        RINEX 3 ``SYS / # / OBS TYPES``: observation codes per system letter, in file order.
    obs_types2 : list of str
        RINEX 2 ``# / TYPES OF OBSERV``: observation codes, in file order.
    glo_channel : dict str -> int
        ``GLONASS SLOT / FRQ #``: frequency channel per satellite id (``"R05"``).
    scale : dict str -> dict str -> float
        ``SYS / SCALE FACTOR``: factor per system and observation code (``"*"``: all codes).
    n_lines : int
        Number of header lines including ``END OF HEADER``.
    """

    version: float = math.nan
    file_system: str = "G"
    marker: str = ""
    receiver_type: str = ""
    antenna_type: str = ""
    approx_pos_m: FloatArray | None = None
    interval_s: float = math.nan
    time_system: str = ""
    leap_s: int | None = None
    obs_types: dict[str, list[str]] = field(default_factory=dict)  # v3 per system
    obs_types2: list[str] = field(default_factory=list)  # v2
    glo_channel: dict[str, int] = field(default_factory=dict)
    scale: dict[str, dict[str, float]] = field(default_factory=dict)
    n_lines: int = 0  # number of header lines including END OF HEADER


# patterns of rare header and error checks: compiled (and cached by :mod:`re`) on first use
_GLO_PAIR = r"R([ \d]\d)\s+([-+]?\d{1,2})"
_GLO_SLOT = r"(\s*R[ \d]\d\s+[-+]?\d{1,2})*\s*"


_SAT_LIST = r"([A-Z ][ \d]\d)+"


def _int(s: str, path: str, line: int, what: str) -> int:
    try:
        return int(s)
    except ValueError:
        raise InputError(f"{what}: expected an integer, found {s.strip()!r}", path, line) from None


def _float(s: str, path: str, line: int, what: str) -> float:
    try:
        return float(s.replace("D", "E").replace("d", "e"))
    except ValueError:
        raise InputError(f"{what}: expected a number, found {s.strip()!r}", path, line) from None


def _check_type_counts(
    h: RinexObsHeader, n2: int, listed2: int, listed3: dict[str, tuple[int, int, int]], path: str, line: int
) -> None:
    """:class:`InputError` when a header's observation-type count disagrees with its list."""
    if h.version < 3.0 and listed2 != n2:
        raise InputError(
            f"# / TYPES OF OBSERV: the header declares {n2} observation types but lists {listed2}",
            path,
            line,
        )
    for s, (n_dec, n_list, at) in listed3.items():
        if n_list != n_dec:
            raise InputError(
                f"SYS / # / OBS TYPES: system {s!r} declares {n_dec} observation types but lists {n_list}",
                path,
                at,
            )


def _check_first_obs(line: str, path: str, i: int) -> None:
    """:class:`InputError` unless ``TIME OF FIRST OBS`` holds a calendar date and time."""
    what = "TIME OF FIRST OBS"
    y, mo, d, hh, mi = (_int(line[c : c + 6], path, i, what) for c in (0, 6, 12, 18, 24))
    sec = _float(line[30:43], path, i, what)
    if not (
        1980 <= y <= 2200 and 1 <= mo <= 12 and 1 <= d <= 31 and 0 <= hh <= 24 and 0 <= mi <= 59
        and 0.0 <= sec < 61.0
    ):  # fmt: skip
        raise InputError(
            f"{what}: expected year month day hour minute second, found {line[:43].strip()!r}", path, i
        )


def parse_obs_header(lines: list[str], path: str) -> RinexObsHeader:
    """Parse the header of a RINEX 2/3 observation file.

    Parameters
    ----------
    lines : list of str
        The file's lines from the first one (``RINEX VERSION / TYPE``) at least up to
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
    if not lines or lines[0][60:].strip() != "RINEX VERSION / TYPE":
        raise InputError(
            "bad version header: the first line must carry 'RINEX VERSION / TYPE' in columns 61-80",
            path,
            1,
        )
    first = lines[0]
    h.version = _float(first[0:9], path, 1, "RINEX VERSION / TYPE version")
    if not (2.0 <= h.version < 5.0):
        raise InputError(f"unsupported RINEX version {h.version}", path, 1)
    if first[20:21] != "O":
        raise InputError(
            f"not an observation file: file type {first[20:21]!r} in column 21, expected 'O'",
            path,
            1,
        )
    h.file_system = first[40:41].strip() or "G"
    pending_sys = ""  # v3 obs types continuation
    pending_n = 0
    pending_scale: tuple[str, float, int] | None = None
    n2 = 0
    listed2 = 0  # RINEX 2 observation codes listed, and per RINEX 3 system (declared, listed, line)
    listed3: dict[str, tuple[int, int, int]] = {}
    for i, line in enumerate(lines[1:], start=2):
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
            xyz = [_float(line[c : c + 14], path, i, label) for c in (0, 14, 28)]
            h.approx_pos_m = np.array(xyz, dtype=float)
        elif label == "INTERVAL":
            h.interval_s = _float(line[0:10], path, i, label)
        elif label == "TIME OF FIRST OBS":
            h.time_system = line[48:51].strip()
            _check_first_obs(line, path, i)
        elif label == "LEAP SECONDS":
            h.leap_s = _int(line[0:6], path, i, label)
        elif label == "# / TYPES OF OBSERV":
            if line[0:6].strip():
                n2 = _int(line[0:6], path, i, label)
            for k in range(9):
                t = line[6 + 6 * k + 4 : 6 + 6 * k + 6].strip()
                listed2 += bool(t)
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
                fac = _float(line[2:6], path, i, label)
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


# --------------------------------------------------------------------------------------------
# epochs


@dataclass
class RinexEpochs:
    """Observation epochs (event flags 0 and 1) of a file and where their records are.

    All lists have one entry per epoch, in file order, except ``events``.

    Attributes
    ----------
    t_s : list of float
        Time tag as written, in the file's time system (s since 1980-01-06, not shifted to
        GPST).
    t_ns : list of int
        The same tag as integer nanoseconds (exact).
    flag : list of int
        Epoch flag (0 or 1).
    clk_s : list of float
        Receiver clock offset from the epoch line (s; NaN when blank).
    line : list of int
        0-based line index of the epoch line.
    first_rec : list of int
        0-based line index of the first satellite record.
    nsat : list of int
        Number of satellite records.
    sats : list of list of str
        RINEX 2 only: the satellite ids of the epoch line(s), 3 characters each as written.
    events : list of dict
        Event epochs (flags 2-5) skipped: ``{"line": 1-based line, "flag": flag}``.
    n_slip : int
        Satellite records of flag-6 (cycle slip) epochs skipped.
    """

    t_s: list[float] = field(default_factory=list)
    t_ns: list[int] = field(default_factory=list)
    flag: list[int] = field(default_factory=list)
    clk_s: list[float] = field(default_factory=list)
    line: list[int] = field(default_factory=list)  # 0-based line index of the epoch line
    first_rec: list[int] = field(default_factory=list)  # 0-based line of the first record
    nsat: list[int] = field(default_factory=list)
    sats: list[list[str]] = field(default_factory=list)  # RINEX 2 only
    events: list[dict[str, object]] = field(default_factory=list)
    n_slip: int = 0


#: Seconds of an epoch tag: digits, optionally a point and more digits.
_SECONDS = re.compile(r"[0-9]+(\.[0-9]*)?|\.[0-9]+")


def epoch_time(y: int, mo: int, d: int, h: int, mi: int, sec: str, path: str, line: int) -> tuple[float, int]:
    """Time of a calendar epoch tag whose seconds are given as text (kept exactly).

    Parameters
    ----------
    y, mo, d, h, mi : int
        Year (4 digits), month, day, hour, minute.
    sec : str
        Seconds field as written (``" 30.0050000"``).
    path : str
        File name for messages.
    line : int
        1-based line for messages.

    Returns
    -------
    t_s : float
        Seconds since 1980-01-06 in the tag's own time scale.
    t_ns : int
        The same as exact integer nanoseconds.

    Raises
    ------
    InputError
        Field out of range or not a number.
    """
    s = sec.strip()
    try:
        if not _SECONDS.fullmatch(s) or float(s) >= 61.0:
            raise ValueError(s)
        whole, _, frac = s.partition(".")
        sec_ns = int(whole or "0") * 1_000_000_000 + int((frac + "000000000")[:9] or "0")
        if s.startswith("-"):
            raise ValueError(s)
        if not (1 <= mo <= 12 and 1 <= d <= 31 and 0 <= h <= 24 and 0 <= mi <= 59):
            raise ValueError(s)
        base = gpst_from_calendar(y, mo, d, h, mi, 0.0)
    except ValueError:
        raise InputError(f"bad epoch time {y} {mo} {d} {h} {mi} {s!r}", path, line) from None
    return base + float(s), int(base) * 1_000_000_000 + sec_ns


def check_event_records(texts: list[str], path: str, line0: int) -> None:
    """Reject event records that change the observation types (unsupported).

    Parameters
    ----------
    texts : list of str
        The records following an event epoch line.
    path : str
        File name for messages.
    line0 : int
        0-based line index of the first record.
    """
    for k, t in enumerate(texts):
        if t[60:].strip() in ("SYS / # / OBS TYPES", "# / TYPES OF OBSERV"):
            raise InputError(
                "observation types change inside the file (event record); unsupported",
                path,
                line0 + k + 1,
            )


def scan_epochs_v3(
    data: bytes,
    bufp: U8Array,
    starts: npt.NDArray[np.int64],
    ends: npt.NDArray[np.int64],
    hb: int,
    n_lines: int,
    path: str,
) -> RinexEpochs:
    """Scan the epoch lines of a RINEX 3 observation body.

    Parameters
    ----------
    data : bytes
        Plain RINEX text.
    bufp : ndarray of uint8
        ``data`` as bytes with at least one space appended.
    starts, ends : ndarray of int64
        Start and end (exclusive, without the newline) offset of every line.
    hb : int
        0-based index of the first body line (the number of header lines).
    n_lines : int
        Number of lines to scan (trailing blank lines excluded).
    path : str
        File name for messages.

    Returns
    -------
    RinexEpochs

    Raises
    ------
    InputError
        Bad epoch line, satellite count that does not match the records, bad time tag,
        observation types changing inside the file.
    """
    first = bufp[starts[hb:n_lines]]
    ep_idx = np.flatnonzero(first == ord(">")) + hb
    ep = RinexEpochs()
    if n_lines > hb and (ep_idx.size == 0 or ep_idx[0] != hb):
        text = data[starts[hb] : ends[hb]].decode("ascii", "replace")
        raise InputError(f"bad epoch line: expected '> yyyy mm dd ...', found {text[:40]!r}", path, hb + 1)
    if ep_idx.size == 0:
        return ep  # no body: a header-only file (refused by the reader with its own message)
    nxt = np.append(ep_idx[1:], n_lines)
    for i, j in zip(ep_idx.tolist(), nxt.tolist(), strict=True):
        text = data[starts[i] : ends[i]].decode("ascii", "replace")
        ln = i + 1
        fl = text[31:32]
        if not fl.isdigit() or not text[32:35].strip().isdigit() or int(fl) > 6:
            raise InputError(
                "bad epoch line: expected '> yyyy mm dd hh mm ss.sssssss  f nnn' with flag "
                f"0-6 in column 32 and the satellite count in columns 33-35, found "
                f"{text[:35]!r}",
                path,
                ln,
            )
        flag, n = int(fl), int(text[32:35])
        gap = j - i - 1
        if gap != n:
            raise InputError(
                f"satellite count does not match: epoch announces {n} "
                f"{'records' if 2 <= flag <= 5 else 'satellites'} but {gap} lines follow "
                "before the next epoch",
                path,
                ln,
            )
        if 2 <= flag <= 5:
            recs = [data[starts[k] : ends[k]].decode("ascii", "replace") for k in range(i + 1, j)]
            check_event_records(recs, path, i + 1)
            ep.events.append({"line": ln, "flag": flag})
            continue
        if flag == 6:
            ep.n_slip += n
            continue
        fields = text[2:6], text[7:9], text[10:12], text[13:15], text[16:18]
        try:
            y, mo, d, hh, mi = (int(f) for f in fields)
        except ValueError:
            raise InputError(
                f"bad epoch line: date/time fields not integers in {text[:29]!r}", path, ln
            ) from None
        t_s, t_ns = epoch_time(y, mo, d, hh, mi, text[18:29], path, ln)
        clk = text[41:56].strip()
        ep.t_s.append(t_s)
        ep.t_ns.append(t_ns)
        ep.flag.append(flag)
        ep.clk_s.append(_float(clk, path, ln, "receiver clock offset") if clk else math.nan)
        ep.line.append(i)
        ep.first_rec.append(i + 1)
        ep.nsat.append(n)
    return ep


def scan_epochs_v2(
    data: bytes,
    starts: npt.NDArray[np.int64],
    ends: npt.NDArray[np.int64],
    hb: int,
    n_lines: int,
    n_obs: int,
    path: str,
) -> RinexEpochs:
    """Scan the epoch lines of a RINEX 2 observation body.

    Parameters
    ----------
    data : bytes
        Plain RINEX text.
    starts, ends : ndarray of int64
        Start and end (exclusive, without the newline) offset of every line.
    hb : int
        0-based index of the first body line (the number of header lines).
    n_lines : int
        Number of lines of ``data``.
    n_obs : int
        Number of observation types (``# / TYPES OF OBSERV``).
    path : str
        File name for messages.

    Returns
    -------
    RinexEpochs
        With ``sats`` filled.

    Raises
    ------
    InputError
        As :func:`scan_epochs_v3`, plus satellite lists that do not match their count.
    """
    ep = RinexEpochs()
    per_sat = v2_lines_per_record(n_obs)
    i = hb

    def text_of(k: int) -> str:
        return data[starts[k] : ends[k]].decode("ascii", "replace")

    while i < n_lines:
        text = text_of(i)
        ln = i + 1
        if not text.strip() and all(not text_of(k).strip() for k in range(i, n_lines)):
            break  # blank lines at the end of the file
        fl = text[28:29]
        count = text[29:32].strip()
        if not (fl.isascii() and fl.isdigit()) or not (count.isascii() and count.isdigit()) or int(fl) > 6:
            raise InputError(
                "bad epoch line: expected ' yy mm dd hh mm ss.sssssss  f nnn' with flag 0-6 "
                f"in column 29 and the satellite count in columns 30-32, found {text[:32]!r}",
                path,
                ln,
            )
        flag, n = int(fl), int(text[29:32])
        if 2 <= flag <= 5:
            if i + 1 + n > n_lines:
                raise InputError(f"file ends inside the {n} event records of this epoch", path, ln)
            check_event_records([text_of(k) for k in range(i + 1, i + 1 + n)], path, i + 1)
            ep.events.append({"line": ln, "flag": flag})
            i += 1 + n
            continue
        n_list = max(1, -(-n // 12))
        if i + n_list > n_lines:
            raise InputError("file ends inside the satellite list of this epoch", path, ln)
        sats: list[str] = []
        for k in range(n_list):
            t = text if k == 0 else text_of(i + k)
            chunk = t[32:68]
            if k > 0 and t[:32].strip():
                raise InputError(
                    f"satellite count does not match: epoch at line {ln} announces {n} "
                    f"satellites, expected a satellite-list continuation line here",
                    path,
                    i + k + 1,
                )
            for c in range(0, 36, 3):
                s = chunk[c : c + 3]
                if s.strip():
                    sats.append(s)
        if len(sats) != n:
            raise InputError(
                f"satellite count does not match: epoch announces {n} satellites but lists {len(sats)}",
                path,
                ln,
            )
        rec0 = i + n_list
        if n % 12 == 0 and rec0 < n_lines:
            nxt = text_of(rec0)
            if not nxt[:32].strip() and re.fullmatch(_SAT_LIST, nxt[32:].rstrip()):
                raise InputError(
                    f"satellite count does not match: epoch announces {n} satellites but the "
                    "list continues on the next line",
                    path,
                    ln,
                )
        i = rec0 + n * per_sat
        if i > n_lines:
            raise InputError(
                f"file ends inside this epoch: {n} satellites x {per_sat} lines announced",
                path,
                ln,
            )
        if flag == 6:
            ep.n_slip += n
            continue
        fields = text[1:3], text[4:6], text[7:9], text[10:12], text[13:15]
        try:
            yy, mo, d, hh, mi = (int(f) for f in fields)
        except ValueError:
            raise InputError(
                f"bad epoch line: date/time fields not integers in {text[:26]!r}", path, ln
            ) from None
        y = yy + (1900 if yy >= 80 else 2000) if yy < 100 else yy
        t_s, t_ns = epoch_time(y, mo, d, hh, mi, text[15:26], path, ln)
        clk = text[68:80].strip()
        ep.t_s.append(t_s)
        ep.t_ns.append(t_ns)
        ep.flag.append(flag)
        ep.clk_s.append(_float(clk, path, ln, "receiver clock offset") if clk else math.nan)
        ep.line.append(i - n * per_sat - n_list)
        ep.first_rec.append(rec0)
        ep.nsat.append(n)
        ep.sats.append(sats)
    return ep


# --------------------------------------------------------------------------------------------
# whole text


def split_lines(data: bytes) -> tuple[I64Array, I64Array, int]:
    """Line offsets of a text.

    Parameters
    ----------
    data : bytes
        Text with ``\n`` line ends (no ``\r``).

    Returns
    -------
    starts, ends : ndarray of int64
        Offset of the first character and one past the last (the newline excluded) of every
        line.
    n_lines : int
        Number of lines (the empty piece after a final newline not counted).
    """
    buf = np.frombuffer(data, dtype=np.uint8)
    nl = np.flatnonzero(buf == 10)
    starts = np.concatenate([[0], nl + 1]).astype(np.int64)
    ends = np.concatenate([nl, [buf.shape[0]]]).astype(np.int64)
    n_lines = int(starts.shape[0])
    if n_lines > 1 and starts[-1] == buf.shape[0]:
        n_lines -= 1  # the empty piece after the final newline
    return starts, ends, n_lines


@dataclass(frozen=True)
class RinexObsText:
    """A plain RINEX observation text located: lines, header and epochs.

    Attributes
    ----------
    data : bytes
        The plain text.
    bufp : ndarray of uint8
        ``data`` as bytes followed by 4 spaces (so fixed-column reads past a short last line
        stay in bounds).
    starts, ends : ndarray of int64
        Line offsets (see :func:`split_lines`).
    n_lines : int
        Lines of the body scanned (RINEX 3: trailing blank lines excluded).
    header : RinexObsHeader
    epochs : RinexEpochs
    v3 : bool
        RINEX 3 layout.
    per_sat : int
        Lines per satellite record (1 in RINEX 3).
    """

    data: bytes
    bufp: U8Array
    starts: I64Array
    ends: I64Array
    n_lines: int
    header: RinexObsHeader
    epochs: RinexEpochs
    v3: bool
    per_sat: int

    def text(self, k: int) -> str:
        """Line ``k`` (0-based) as text, without the newline."""
        return self.data[self.starts[k] : self.ends[k]].decode("ascii", "replace")


def scan_obs_text(data: bytes, path: str) -> RinexObsText:
    """Parse the header and scan the epoch lines of a plain RINEX 2/3 observation text.

    Parameters
    ----------
    data : bytes
        Plain RINEX observation text (``\n`` line ends), e.g. from
        :func:`robustrtk.io.rinex_file.read_rinex_bytes`.
    path : str
        File name for messages.

    Returns
    -------
    RinexObsText

    Raises
    ------
    InputError
        Malformed header or epoch line (see :func:`parse_obs_header`,
        :func:`scan_epochs_v3`, :func:`scan_epochs_v2`).
    """
    starts, ends, n_lines = split_lines(data)
    head: list[str] = []
    for k in range(n_lines):
        text = data[starts[k] : ends[k]].decode("ascii", "replace")
        head.append(text)
        label = text[60:].strip()
        if label == "END OF HEADER" or (k == 0 and label != "RINEX VERSION / TYPE"):
            break
    h = parse_obs_header(head, path)
    hb = h.n_lines  # first body line (0-based)
    v3 = h.version >= 3.0
    bufp = np.concatenate([np.frombuffer(data, dtype=np.uint8), np.full(4, 32, np.uint8)])
    if v3:
        # blank lines after the last record (never part of a RINEX 3 record)
        while n_lines > hb and not data[starts[n_lines - 1] : ends[n_lines - 1]].strip():
            n_lines -= 1
        ep = scan_epochs_v3(data, bufp, starts, ends, hb, n_lines, path)
        per_sat = 1
    else:
        if not h.obs_types2:
            raise InputError("missing '# / TYPES OF OBSERV' header record", path)
        ep = scan_epochs_v2(data, starts, ends, hb, n_lines, len(h.obs_types2), path)
        per_sat = v2_lines_per_record(len(h.obs_types2))
    return RinexObsText(data, bufp, starts, ends, n_lines, h, ep, v3, per_sat)
