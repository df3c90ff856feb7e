"""Epoch lines of RINEX 2/3 observation files: where each epoch's records are.

The epoch lines parsed (time, flag, satellite count or list, receiver clock offset), the
event records checked, and the first record line of every observation epoch, for the
whole-text scan of :mod:`robustrtk.io.rinex_text` (which the reader
:mod:`robustrtk.io.rinex_obs` and the fault injection :mod:`robustrtk.sim.inject` share). The
fixed column layout is :mod:`robustrtk.io.rinex_layout`'s.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from robustrtk.core import InputError
from robustrtk.io.rinex_decode import gather_lines
from robustrtk.io.rinex_layout import (
    U8Array,
    join_stray_blank,
    parse_float,
    v2_lines_per_record,
)
from robustrtk.timeutil import gpst_from_calendar

__all__ = [
    "RinexEpochs",
    "check_event_records",
    "epoch_time",
    "scan_epochs_v2",
    "scan_epochs_v3",
]

_SAT_LIST = r"([A-Z ][ \d]\d)+"


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
    stray_blank_lines : list of int
        1-based lines of epoch tags whose seconds had a stray blank next to the point
        (``0 .0000000``), read with the blank removed.
    junk_lines : list of int
        RINEX 3: 1-based lines that start with ``>`` but are no epoch line and have no
        records (skipped).
    truncated_line : int
        1-based line of a last epoch the file ends inside (a file cut short; the epoch is
        dropped), 0 when none.
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
    stray_blank_lines: list[int] = field(default_factory=list)
    junk_lines: list[int] = field(default_factory=list)
    truncated_line: int = 0

    def notes(self) -> list[str]:
        """One sentence per kind of oddity tolerated in the body (empty when none)."""
        out = []
        if self.truncated_line:
            out.append(
                f"the file ends inside its last epoch (line {self.truncated_line}; a file cut short): "
                "that epoch dropped"
            )
        if self.stray_blank_lines:
            n = len(self.stray_blank_lines)
            out.append(
                f"{n} epoch tag(s) with a stray blank in the seconds ('0 .0000000'), read with the "
                f"blank removed (first at line {self.stray_blank_lines[0]})"
            )
        if self.junk_lines:
            n = len(self.junk_lines)
            out.append(
                f"{n} line(s) starting with '>' that are no epoch line and have no records skipped "
                f"(first at line {self.junk_lines[0]})"
            )
        return out


def _seconds_text(sec: str, ep: RinexEpochs, ln: int) -> str:
    """The seconds field of an epoch tag, a stray blank next to the point removed (noted)."""
    joined = join_stray_blank(sec) if " " in sec.strip() else None
    if joined is None:
        return sec
    ep.stray_blank_lines.append(ln)
    return joined


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
    if _plain_epochs_v3(data, bufp, starts, ends, ep_idx, nxt, ep, path):
        return ep
    for i, j in zip(ep_idx.tolist(), nxt.tolist(), strict=True):
        text = data[starts[i] : ends[i]].decode("ascii", "replace")
        ln = i + 1
        fl = text[31:32]
        if not fl.isdigit() or not text[32:35].strip().isdigit() or int(fl) > 6:
            if j == i + 1 and not re.match(r">\s*\d{4}\s", text):
                ep.junk_lines.append(ln)  # no date and no records: not an epoch
                continue
            raise InputError(
                "bad epoch line: expected '> yyyy mm dd hh mm ss.sssssss  f nnn' with flag "
                f"0-6 in column 32 and the satellite count in columns 33-35, found "
                f"{text[:35]!r}",
                path,
                ln,
            )
        flag, n = int(fl), int(text[32:35])
        gap = j - i - 1
        if gap < n and j == n_lines:
            ep.truncated_line = ln  # the file ends inside its last epoch
            break
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
        t_s, t_ns = epoch_time(y, mo, d, hh, mi, _seconds_text(text[18:29], ep, ln), path, ln)
        clk = text[41:56].strip()
        ep.t_s.append(t_s)
        ep.t_ns.append(t_ns)
        ep.flag.append(flag)
        ep.clk_s.append(parse_float(clk, path, ln, "receiver clock offset") if clk else math.nan)
        ep.line.append(i)
        ep.first_rec.append(i + 1)
        ep.nsat.append(n)
    return ep


#: Columns of a RINEX 3 epoch line read by :func:`_plain_epochs_v3` (through the clock).
_V3_EPOCH_COLS = 56
_DIGIT_COLS = (2, 3, 4, 5, 8, 11, 14, 17, 20, 22, 23, 24, 25, 26, 27, 28)
_DIGIT_OR_BLANK_COLS = (7, 10, 13, 16, 19)


def _plain_epochs_v3(
    data: bytes,
    bufp: U8Array,
    starts: npt.NDArray[np.int64],
    ends: npt.NDArray[np.int64],
    ep_idx: npt.NDArray[np.int64],
    nxt: npt.NDArray[np.int64],
    ep: RinexEpochs,
    path: str,
) -> bool:
    """The epochs of :func:`scan_epochs_v3` read as arrays when every epoch line is plain:
    ASCII, a flag 0-6 in column 32, the satellite (record) count right-aligned in columns
    33-35 and that many lines following; for the observation epochs (flags 0 and 1) also
    ``> yyyy mm dd hh mm ss.sssssss`` with the seconds in the ``F11.7`` layout (one or two
    digits before the point, seven after), the date within 1980-2100 and in range. Fills
    ``ep`` and returns True; returns False (``ep`` untouched) when any line is not plain,
    for the line-by-line scan, which reads and refuses what the others hold. The few event
    epochs (flags 2-6) are taken line by line, as that scan takes them.

    The numbers are those of the line-by-line scan: the time tag is the exact integer
    nanoseconds of the text, and ``t_s`` its day start plus the seconds as one correctly
    rounded division (as ``float`` of the text)."""
    lens = ends[ep_idx] - starts[ep_idx]
    if not np.all(lens >= 35):
        return False
    c = gather_lines(bufp, starts[ep_idx], lens, _V3_EPOCH_COLS)
    if np.any(c >= 128):
        return False
    d = c.astype(np.int64) - 48
    isd = (d >= 0) & (d <= 9)
    blank = c == 32
    # every epoch line: flag and count, the count's records following
    if not (np.all(isd[:, 31] & (d[:, 31] <= 6)) and np.all(isd[:, 34])):
        return False
    if not np.all((isd | blank)[:, 32:34]) or np.any(blank[:, 33] & ~blank[:, 32]):
        return False  # a blank only before the count's first digit
    dd = np.where(isd, d, 0)
    n = dd[:, 32] * 100 + dd[:, 33] * 10 + dd[:, 34]
    if not np.array_equal(nxt - ep_idx - 1, n):
        return False
    flag = d[:, 31]
    obs = flag <= 1
    # observation epochs: the time tag
    o = np.flatnonzero(obs)
    co, do, io_, bo = c[o], dd[o], isd[o], blank[o]
    if not (io_[:, _DIGIT_COLS].all() and (io_ | bo)[:, _DIGIT_OR_BLANK_COLS].all()):
        return False
    if not (np.all(co[:, 18] == 32) and np.all(co[:, 21] == 46)):
        return False
    y = do[:, 2] * 1000 + do[:, 3] * 100 + do[:, 4] * 10 + do[:, 5]
    mo, day, hh, mi, whole = (do[:, k] * 10 + do[:, k + 1] for k in (7, 10, 13, 16, 19))
    frac7 = np.zeros_like(y)
    for k in range(22, 29):
        frac7 = frac7 * 10 + do[:, k]
    in_range = (
        (y >= 1980) & (y <= 2100) & (mo >= 1) & (mo <= 12) & (day >= 1) & (day <= 31)
        & (hh <= 24) & (mi <= 59) & (whole < 61)
    )  # fmt: skip
    if not in_range.all():
        return False
    clk = [math.nan] * int(o.size)
    for k in np.flatnonzero(~bo[:, 41:56].all(axis=1)).tolist():
        text = bytes(co[k, 41:56]).decode("ascii").strip()
        if text:
            clk[k] = parse_float(text, path, int(ep_idx[o[k]]) + 1, "receiver clock offset")
    for k in np.flatnonzero(~obs).tolist():  # event epochs, in file order
        i, j, f = int(ep_idx[k]), int(nxt[k]), int(flag[k])
        if 2 <= f <= 5:
            recs = [data[starts[r] : ends[r]].decode("ascii", "replace") for r in range(i + 1, j)]
            check_event_records(recs, path, i + 1)
            ep.events.append({"line": i + 1, "flag": f})
        else:
            ep.n_slip += int(n[k])
    # gpst_from_calendar(y, mo, day, hh, mi, 0.0): the days of H. Hinnant's algorithm
    ya = y - (mo <= 2)
    era = ya // 400  # years >= 1979 here
    yoe = ya - era * 400
    doy = (153 * (mo + np.where(mo > 2, -3, 9)) + 2) // 5 + day - 1
    days = era * 146097 + yoe * 365 + yoe // 4 - yoe // 100 + doy - 719468 - _GPS_EPOCH_DAYS_1970
    base = days * 86400.0 + hh * 3600.0 + mi * 60.0 + 0.0
    sec = (whole * 10_000_000 + frac7).astype(float) / 1e7  # float() of the seconds text
    ep.t_s = (base + sec).tolist()
    ep.t_ns = (base.astype(np.int64) * 1_000_000_000 + whole * 1_000_000_000 + frac7 * 100).tolist()
    ep.flag = flag[o].tolist()
    ep.clk_s = clk
    ep.line = ep_idx[o].tolist()
    ep.first_rec = (ep_idx[o] + 1).tolist()
    ep.nsat = n[o].tolist()
    return True


_GPS_EPOCH_DAYS_1970 = 3657  # days from 1970-01-01 to 1980-01-06


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
    data, starts, ends, hb, path
        As in :func:`scan_epochs_v3`.
    n_lines : int
        Number of lines of ``data``.
    n_obs : int
        Number of observation types (``# / TYPES OF OBSERV``).

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
                ep.truncated_line = ln  # the file ends inside its last epoch
                break
            check_event_records([text_of(k) for k in range(i + 1, i + 1 + n)], path, i + 1)
            ep.events.append({"line": ln, "flag": flag})
            i += 1 + n
            continue
        n_list = max(1, -(-n // 12))
        if i + n_list > n_lines:
            ep.truncated_line = ln  # the file ends inside its last epoch
            break
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
            ep.truncated_line = ln  # the file ends inside its last epoch
            break
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
        t_s, t_ns = epoch_time(y, mo, d, hh, mi, _seconds_text(text[15:26], ep, ln), path, ln)
        clk = text[68:80].strip()
        ep.t_s.append(t_s)
        ep.t_ns.append(t_ns)
        ep.flag.append(flag)
        ep.clk_s.append(parse_float(clk, path, ln, "receiver clock offset") if clk else math.nan)
        ep.line.append(i - n * per_sat - n_list)
        ep.first_rec.append(rec0)
        ep.nsat.append(n)
        ep.sats.append(sats)
    return ep
