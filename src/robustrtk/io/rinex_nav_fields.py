"""Fields, epochs and ephemeris records shared by the RINEX navigation readers (2, 3 and 4).

The RINEX 2/3 reader (:mod:`robustrtk.io.rinex_nav`) and the RINEX 4 record reader
(:mod:`robustrtk.io.rinex_nav4`) parse the same broadcast-orbit blocks: an epoch line with
three clock values and continuation lines of four 19-character numbers (``D`` exponents
allowed). :class:`RecordRows` collects the parsed ephemerides per system until they are turned
into the arrays of :mod:`robustrtk.geometry.navdata`.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

from robustrtk.core import InputError
from robustrtk.geometry.navdata import KEPLER_SYSTEMS
from robustrtk.io.rinex_file import check_regular_file, decompress_rinex
from robustrtk.timeutil import gpst_from_calendar

__all__ = [
    "MIN_KEPLER_VALUES",
    "N_GLO_VALUES",
    "N_KEPLER_VALUES",
    "N_SBAS_VALUES",
    "RecordRows",
    "epoch_r3",
    "check_calendar",
    "count",
    "open_text_lines",
    "parse_eph_block",
    "parse_fields",
    "parse_int",
    "parse_number",
    "store_values",
]

#: Values of a Keplerian record: 3 clock + 7 lines x 4 (last line partial).
N_KEPLER_VALUES = 31
#: Values a Keplerian record must carry (up to the transmission time).
MIN_KEPLER_VALUES = 28
#: Values of a GLONASS record kept (3 clock + 3 lines x 4).
N_GLO_VALUES = 15
#: Values of an SBAS record (3 clock + 3 lines x 4).
N_SBAS_VALUES = 15
# Values that must be present (index 22, GPS L2P flag / Galileo and BeiDou spare, may be blank).
_REQUIRED_KEPLER = tuple(k for k in range(MIN_KEPLER_VALUES) if k != 22)
# SBAS: clock, position, velocity and acceleration must be present.
_REQUIRED_SBAS = (0, 1, 3, 4, 5, 7, 8, 9, 11, 12, 13)


def open_text_lines(path: str) -> list[str]:
    """Lines of a possibly compressed text file (gzip, bzip2, zip, Unix compress; trailing
    newlines removed), the decompressed size capped as for observation files.

    Parameters
    ----------
    path : str

    Returns
    -------
    list of str

    Raises
    ------
    InputError
        Unreadable file or corrupt compressed data.
    """
    check_regular_file(str(path))
    try:
        with open(path, "rb") as fh:
            raw = fh.read()
    except OSError as exc:
        raise InputError(f"cannot read navigation file ({exc.strerror})", path=path) from exc
    raw, _ = decompress_rinex(raw, str(path))  # gzip, bzip2, zip, .Z; capped as for observations
    text = raw.decode("ascii", errors="replace")
    return text.splitlines()


def _zero_with_blank(s: str) -> float:
    """A zero written with a stray blank (``. 000000000000D+00``, seen in real files): 0.0,
    which is also what RTKLIB reads (its scan stops at the blank). Any other number with a
    blank inside is NaN (refused): the two readings would differ."""
    try:
        v = float("".join(s.split()).replace("D", "E").replace("d", "e"))
    except ValueError:
        return math.nan
    return 0.0 if v == 0.0 else math.nan


#: A Fortran ``D``/``E`` field whose exponent needs three digits drops the letter
#: (``0.499063314480-269``): mantissa, then the signed exponent.
_FORTRAN_EXP3 = re.compile(r"([-+]?\d*\.\d+)([-+]\d{3})")


def parse_number(text: str, path: str, line_no: int, col: int) -> float:
    """One RINEX number (``D`` exponents allowed; blank -> 0.0); ``col`` is 0-based."""
    s = text.strip()
    if not s:
        return 0.0
    try:
        v = float(s.replace("D", "E").replace("d", "e"))
    except ValueError:
        m = _FORTRAN_EXP3.fullmatch(s)
        v = float(f"{m.group(1)}e{m.group(2)}") if m else _zero_with_blank(s)
    if not math.isfinite(v):  # a word, or nan/inf/an exponent beyond the double range
        raise InputError(
            f"expected a finite number in columns {col + 1}-{col + len(text)}, got {s!r}",
            path=path,
            line=line_no,
        )
    return v


def parse_fields(line: str, start: int, n: int, path: str, line_no: int) -> list[float]:
    """``n`` 19-character numeric fields from 0-based column ``start`` (missing -> NaN)."""
    out = []
    end = len(line.rstrip())
    for k in range(n):
        a = start + 19 * k
        if a >= end:
            out.append(math.nan)
            continue
        text = line[a : a + 19]
        try:  # the common field at once (float() ignores the blanks parse_number strips)
            v = float(text.replace("D", "E").replace("d", "e"))
        except ValueError:
            v = math.nan
        out.append(v if math.isfinite(v) else parse_number(text, path, line_no, a))
    return out


def parse_int(text: str, path: str, line_no: int, what: str) -> int:
    """An integer field; ``what`` names it in the error message."""
    try:
        return int(text)
    except ValueError:
        raise InputError(
            f"expected an integer {what}, got {text.strip()!r}", path=path, line=line_no
        ) from None


def check_calendar(y: int, mo: int, d: int, h: int, mi: int, s: float, path: str, ln: int) -> None:
    """Raise :class:`InputError` when a calendar epoch is out of range."""
    if not (1980 <= y <= 2100 and 1 <= mo <= 12 and 1 <= d <= 31 and 0 <= h <= 24 and 0 <= mi <= 60):
        raise InputError(f"epoch out of range: {y}-{mo}-{d} {h}:{mi}:{s}", path=path, line=ln)
    if not (0.0 <= s <= 61.0):
        raise InputError(f"epoch seconds out of range: {s}", path=path, line=ln)


def epoch_r3(line: str, path: str, ln: int) -> float:
    """Epoch ``yyyy mm dd hh mm ss`` in columns 5-23 (RINEX 3/4 records), in its own scale.

    Returns
    -------
    float
        Seconds since 1980-01-06 00:00:00 of the record's own time scale.
    """
    try:
        y = int(line[4:8])
        mo = int(line[9:11])
        d = int(line[12:14])
        h = int(line[15:17])
        mi = int(line[18:20])
        s = float(line[21:23])
    except ValueError:
        raise InputError(
            f"bad epoch {line[4:23].strip()!r}; expected 'yyyy mm dd hh mm ss' in columns 5-23",
            path=path,
            line=ln,
        ) from None
    check_calendar(y, mo, d, h, mi, s, path, ln)
    return gpst_from_calendar(y, mo, d, h, mi, s)


def count(counter: dict[str, int], key: str) -> None:
    """Increment ``counter[key]``."""
    counter[key] = counter.get(key, 0) + 1


@dataclass
class RecordRows:
    """Ephemeris records parsed so far, per system, before conversion to arrays.

    Attributes
    ----------
    sat, epoch, vals : dict
        Per system letter (``G E C J R S``): satellite ids, record epochs (own time scale,
        s since 1980-01-06) and the record's values in file order.
    leap : list of float
        Leap seconds per GLONASS record (NaN: take them from the table).
    skipped : dict str -> int
        Skipped ephemeris records per system letter.
    counts, skipped_records : dict str -> int
        Records read / skipped per kind (``"EPH G LNAV"``).
    """

    sat: dict[str, list[str]] = field(default_factory=lambda: {s: [] for s in (*KEPLER_SYSTEMS, "R", "S")})
    epoch: dict[str, list[float]] = field(
        default_factory=lambda: {s: [] for s in (*KEPLER_SYSTEMS, "R", "S")}
    )
    vals: dict[str, list[list[float]]] = field(
        default_factory=lambda: {s: [] for s in (*KEPLER_SYSTEMS, "R", "S")}
    )
    leap: list[float] = field(default_factory=list)
    skipped: dict[str, int] = field(default_factory=dict)
    counts: dict[str, int] = field(default_factory=dict)
    skipped_records: dict[str, int] = field(default_factory=dict)


def parse_eph_block(
    rows: RecordRows,
    system: str,
    sat: str,
    rec: list[str],
    ln: int,
    path: str,
    leap_s: int | None,
    need: int,
) -> list[float]:
    """Parse one RINEX 3/4 ephemeris block (epoch line + ``need`` orbit lines) into ``rows``.

    Parameters
    ----------
    rows : RecordRows
    system : str
        ``G E C J R S``.
    sat : str
        Satellite id (``"G05"``).
    rec : list of str
        The block's lines, the epoch line first.
    ln : int
        1-based line number of ``rec[0]``.
    path : str
    leap_s : int or None
        Header leap seconds (for GLONASS epochs in UTC).
    need : int
        Orbit lines expected after the epoch line (lines beyond are ignored).

    Returns
    -------
    list of float
        The values stored.

    Raises
    ------
    InputError
        Too few lines, bad epoch or number, incomplete or implausible record.
    """
    if len(rec) - 1 < need:
        raise InputError(
            f"record of {sat} has {len(rec) - 1} broadcast-orbit lines, expected {need}",
            path=path,
            line=ln,
        )
    t = epoch_r3(rec[0], path, ln)
    vals = parse_fields(rec[0], 23, 3, path, ln)
    for k, cont in enumerate(rec[1 : need + 1]):
        vals += parse_fields(cont, 4, 4, path, ln + 1 + k)
    store_values(rows, system, sat, t, vals, path, ln, leap_s)
    return vals


def store_values(
    rows: RecordRows,
    system: str,
    sat: str,
    t_sys: float,
    vals: list[float],
    path: str,
    ln: int,
    leap_s: int | None,
) -> None:
    """Check the values of one record and append them to ``rows``.

    Parameters
    ----------
    rows : RecordRows
    system, sat : str
        System letter and satellite id.
    t_sys : float
        Record epoch in the system's own time scale (s since 1980-01-06).
    vals : list of float
        Values in file order (NaN where absent).
    path : str
    ln : int
        1-based line of the record's epoch line.
    leap_s : int or None
        Header leap seconds (GLONASS).

    Raises
    ------
    InputError
        Incomplete record or implausible ``sqrt(A)``.
    """
    if system == "R":
        vals = (vals + [math.nan] * N_GLO_VALUES)[:N_GLO_VALUES]
        if any(math.isnan(v) for v in vals[:14]):
            raise InputError(f"GLONASS record of {sat} is incomplete", path=path, line=ln)
        rows.leap.append(math.nan if leap_s is None else float(leap_s))
    elif system == "S":
        vals = (vals + [math.nan] * N_SBAS_VALUES)[:N_SBAS_VALUES]
        if any(math.isnan(vals[k]) for k in _REQUIRED_SBAS):
            raise InputError(f"SBAS record of {sat} is incomplete", path=path, line=ln)
    else:
        vals = (vals + [math.nan] * N_KEPLER_VALUES)[:N_KEPLER_VALUES]
        missing = [k for k in _REQUIRED_KEPLER if math.isnan(vals[k])]
        if missing:
            raise InputError(
                f"ephemeris record of {sat} is incomplete (value {missing[0] + 1} of "
                f"{MIN_KEPLER_VALUES} missing)",
                path=path,
                line=ln,
            )
        if not vals[10] > 1000.0:  # sqrt(A) in m^0.5 (GNSS orbits: ~5150-6500)
            raise InputError(
                f"implausible sqrt(A) {vals[10]!r} for {sat} (expected > 1000 m^0.5)",
                path=path,
                line=ln + 2,
            )
    rows.sat[system].append(sat)
    rows.epoch[system].append(t_sys)
    rows.vals[system].append(vals)
