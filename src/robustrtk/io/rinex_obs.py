"""RINEX observation files (2.10/2.11 and 3.02-3.05) into one :class:`~robustrtk.core.ObsBatch`.

Input may be plain text, gzip/bzip2/Unix-compress/zip, Hatanaka (Compact RINEX, ``.crx``,
``.??d``) or both (``.crx.gz``); the kind is detected from the file's first bytes, not its
name, and compressed files are expanded with :func:`hatanaka.decompress`.

Parsing is vectorised: the header and the epoch lines are read line by line (a few thousand
at most), the observation records of all epochs are gathered into one fixed-width byte array
per system and every ``F14.3 I1 I1`` field is converted column-wise (digits times powers of
ten, one matrix product), so the cost per observation is a handful of numpy operations.

Output conventions
------------------
* ``t_s``: GPS time (s since 1980-01-06T00:00:00 GPST) of the receiver time tag, **not
  rounded** (a tag 3 ms after the second stays 3 ms after it). The file's time system is
  read from ``TIME OF FIRST OBS`` (RINEX 2 default: GPS, or UTC for GLONASS-only files):
  GPS/GAL/QZS/IRN tags are used as they are, BDT tags get +14 s, GLO (RINEX's UTC) tags get
  the leap seconds (header ``LEAP SECONDS`` or the table). The offset applied is
  ``meta["time_offset_s"]``; the exact tags as int64 ns are in ``meta["t_ns"]``.
* ``tx_ids``: ``"G05"``, ``"R12"``, ... sorted by system (``G R E C J S I``) then number; a
  blank RINEX 2 system letter means GPS.
* ``signals``: RINEX 3 band + attribute (``"1C"``, ``"2W"``, ``"5Q"``), the sorted union over
  the systems kept. RINEX 3 observation code ``C1C`` fills ``code_m``, ``L1C`` ``phase_cyc``,
  ``D1C`` ``doppler_hz`` and ``S1C`` ``cn0_dbhz`` of signal ``"1C"``; other types (``X``
  channel numbers, ``I`` ionosphere) are ignored. In RINEX 3.00-3.02 BeiDou B1I is written
  with band 1 (``C1I``); it is renamed to the 3.03+ name ``"2I"`` so the carrier is right.
* ``lli``: the loss-of-lock digit of the **phase** observation of each cell (bit 0 loss of
  lock / possible slip, bit 1 half-cycle ambiguity, bit 2 anti-spoofing in RINEX 2 or BOC
  tracking in RINEX 3 -- slip detectors should test bit 0 only);
  0 where the phase is absent. The signal-strength digits of the phases are in
  ``meta["ssi"]`` (int8, 0 = blank).
* ``wavelength_m``: :func:`robustrtk.gnss.wavelength_m` per (transmitter, signal) for the
  signals the transmitter's system declares (NaN for the others); GLONASS FDMA bands use the
  channel from ``GLONASS SLOT / FRQ #`` (NaN without it, e.g. in RINEX 2).
* ``approx_pos_m``: ``APPROX POSITION XYZ`` (ECEF m), ``None`` when absent or all zero.
* Epoch flags: 0 and 1 are kept (``meta["power_failure_epochs"]`` lists the epoch indices
  with flag 1); 2-5 (events with header or comment records) are skipped and listed in
  ``meta["events"]``; 6 (cycle-slip records) is skipped and counted in
  ``meta["n_slip_records_skipped"]``.
* ``SYS / SCALE FACTOR`` (RINEX 3) divides the values of the named types.

RINEX 2 observation codes
-------------------------
=========  ======================  ===========================================================
system     code -> signal          notes
=========  ======================  ===========================================================
GPS, QZSS  C1 -> 1C, P1 -> 1W      ``L1 D1 S1`` -> ``1C``; both C1 and P1 are kept
           C2 -> 2L, P2 -> 2W      ``L2 D2 S2`` -> ``2W``
           C5 L5 D5 S5 -> 5X
GLONASS    C1 -> 1C, P1 -> 1P      ``L1 D1 S1`` -> ``1C``
           C2 -> 2C, P2 -> 2P      ``L2 D2 S2`` -> ``2P``
Galileo    C1 L1 D1 S1 -> 1X       band 5 -> ``5X``, 7 -> ``7X``, 8 -> ``8X``, 6 -> ``6X``
SBAS       C1 L1 D1 S1 -> 1C       band 5 -> ``5X``
=========  ======================  ===========================================================

Codes without an entry (e.g. ``T1``, BeiDou in RINEX 2.12 drafts) are ignored and listed in
``meta["ignored_obs_types"]``.

Malformed input raises :class:`~robustrtk.core.InputError` naming the file, the line and the
reason: bad ``RINEX VERSION / TYPE`` line, missing ``END OF HEADER``, bad epoch line,
satellite count that does not match the records, non-numeric field, time going backwards.
A mid-file change of observation types (event flag 4 with a new obs-type record) is reported
as unsupported.
"""

from __future__ import annotations

import bz2
import gzip
import math
import re
from dataclasses import dataclass, field
from os import PathLike
from pathlib import Path

import numpy as np
import numpy.typing as npt

from robustrtk.core import FloatArray, InputError, ObsBatch
from robustrtk.gnss import wavelength_m
from robustrtk.timeutil import BDT_GPST_OFFSET_S, gpst_from_calendar, leap_seconds_at_utc

__all__ = ["read_rinex_obs", "read_rinex_bytes", "RINEX2_SIGNAL_MAP"]

U8Array = npt.NDArray[np.uint8]

#: System letters in output order.
SYSTEM_ORDER = "GRECJSI"

# Observation type letter -> index into (code_m, phase_cyc, doppler_hz, cn0_dbhz).
_TYPE2FIELD = {"C": 0, "L": 1, "D": 2, "S": 3}
_PHASE = 1


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

# --------------------------------------------------------------------------------------------
# bytes in


def read_rinex_bytes(path: str | PathLike[str]) -> tuple[bytes, str]:
    """The plain RINEX text of ``path`` and how it was stored.

    Returns
    -------
    data : bytes
        Plain RINEX, ``\\r`` removed.
    compression : str
        ``"none"``, ``"gzip"``, ``"hatanaka"``, ``"hatanaka+gzip"``, ... (detected from
        content).
    """
    p = str(path)
    try:
        raw = Path(p).read_bytes()
    except FileNotFoundError:
        raise InputError("file not found", path=p) from None
    except OSError as exc:
        raise InputError(f"cannot read file ({exc.strerror})", path=p) from None
    kinds = []
    if raw[:2] == b"\x1f\x8b":
        kinds.append("gzip")
    elif raw[:2] == b"\x1f\x9d":
        kinds.append("compress")
    elif raw[:3] == b"BZh":
        kinds.append("bzip2")
    elif raw[:4] == b"PK\x03\x04":
        kinds.append("zip")
    data = raw
    if kinds:
        try:
            if kinds[0] == "gzip":
                data = gzip.decompress(raw)
            elif kinds[0] == "bzip2":
                data = bz2.decompress(raw)
            else:
                import hatanaka

                data = hatanaka.decompress(raw)
        except Exception as exc:  # corrupt archive: report, no traceback
            raise InputError(f"cannot decompress {kinds[0]} data: {exc}", path=p) from None
    if b"CRINEX VERS" in data[:200] or b"COMPACT RINEX" in data[:200]:
        kinds.insert(0, "hatanaka")
        try:
            import hatanaka

            data = hatanaka.decompress(data)
        except Exception as exc:
            raise InputError(f"bad Hatanaka (Compact RINEX) data: {exc}", path=p) from None
    if b"\r" in data:
        data = data.replace(b"\r", b"")
    return data, "+".join(kinds) if kinds else "none"


# --------------------------------------------------------------------------------------------
# header


@dataclass
class _Header:
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


_GLO_PAIR = re.compile(r"R([ \d]\d)\s+([-+]?\d{1,2})")
_GLO_SLOT = re.compile(r"(\s*R[ \d]\d\s+[-+]?\d{1,2})*\s*")


_SAT_LIST = re.compile(r"([A-Z ][ \d]\d)+")


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


def _parse_header(lines: list[str], path: str) -> _Header:
    h = _Header()
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
    for i, line in enumerate(lines[1:], start=2):
        label = line[60:].strip()
        if label == "END OF HEADER":
            h.n_lines = i
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
        elif label == "LEAP SECONDS":
            h.leap_s = _int(line[0:6], path, i, label)
        elif label == "# / TYPES OF OBSERV":
            if line[0:6].strip():
                n2 = _int(line[0:6], path, i, label)
            for k in range(9):
                t = line[6 + 6 * k + 4 : 6 + 6 * k + 6].strip()
                if t and len(h.obs_types2) < n2:
                    h.obs_types2.append(t)
        elif label == "SYS / # / OBS TYPES":
            if line[0:1].strip():
                pending_sys = line[0]
                pending_n = _int(line[3:6], path, i, label)
                h.obs_types[pending_sys] = []
            elif not pending_sys:
                raise InputError(f"{label}: continuation line without a system", path, i)
            for k in range(13):
                t = line[7 + 4 * k : 10 + 4 * k].strip()
                if t and len(h.obs_types[pending_sys]) < pending_n:
                    h.obs_types[pending_sys].append(t)
        elif label == "GLONASS SLOT / FRQ #":
            # nominally I3,1X,8(A1,I2.2,1X,I2,1X); some writers shift the columns, so the
            # (slot, channel) pairs are matched by pattern
            body = line[3:60] if line[:3].strip().isdigit() else line[:60]
            if body.strip() and not _GLO_SLOT.fullmatch(body):
                raise InputError(f"{label}: expected 'Rnn k' pairs, found {body.strip()!r}", path, i)
            for m in _GLO_PAIR.finditer(body):
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
# vectorised field conversion

# Place value of each of the 14 characters of an F14.3 field (point at index 10), in 1e-3.
_W14 = tuple([10.0 ** (12 - i) for i in range(10)] + [0.0, 100.0, 10.0, 1.0])


def _gather(bufp: U8Array, starts: npt.NDArray[np.int64], lens: npt.NDArray[np.int64], width: int) -> U8Array:
    """Lines ``bufp[starts[i] : starts[i] + lens[i]]`` as rows of a space-padded ``(n, width)``
    byte array (longer lines are cut)."""
    cols = np.arange(width, dtype=np.int64)
    idx = starts[:, None] + cols[None, :]
    np.minimum(idx, bufp.shape[0] - 1, out=idx)
    out = bufp[idx]
    out[cols[None, :] >= lens[:, None]] = 32
    return out


def _f14_to_float(f: U8Array) -> tuple[FloatArray, npt.NDArray[np.bool_]]:
    """Convert ``F14.3`` fields to float.

    Parameters
    ----------
    f : ndarray of uint8, shape (..., 14)
        ASCII characters of each field.

    Returns
    -------
    value : ndarray, shape (...)
        ``sign * sum_i digit_i * w_i / 1000`` with ``w`` the place values of the fixed
        layout (NaN for blank fields). Exactly ``float(text)``: the integer mantissa is below
        2**53 and one correctly rounded division by 1000 follows.
    odd : ndarray of bool, shape (...)
        Non-blank fields that do not follow the ``[-]ddd.ddd`` layout with the point in
        column 11; their ``value`` is meaningless and must be parsed another way.

    Notes
    -----
    The layout test uses counts over the integer part (columns 1-10): with ``s`` spaces,
    ``d`` digits and ``m`` minus signs, a valid field has ``s + d + m = 10``, the spaces
    leading (sum of their column indices ``= s(s-1)/2``), at most one minus, in column
    ``s``; then a point and three digits.
    """
    shape = f.shape[:-1]
    cols = np.ascontiguousarray(np.moveaxis(f, -1, 0)).reshape(14, -1)  # one row per column
    n = cols.shape[1]
    n_sp = np.zeros(n, np.int16)  # spaces in the integer part
    pos_sp = np.zeros(n, np.int16)  # sum of their column indices
    n_dig = np.zeros(n, np.int16)  # digits in the integer part
    n_dec = np.zeros(n, np.int16)  # digits among the decimals
    n_mi = np.zeros(n, np.int16)  # minus signs
    pos_mi = np.zeros(n, np.int16)
    n_blank = np.zeros(n, np.int16)  # spaces anywhere
    mant = np.zeros(n)
    point = cols[10] == 46
    for i in range(14):  # 14 column-wise passes, each vectorised over all fields
        c = cols[i]
        sp = c == 32
        n_blank += sp
        if i == 10:
            continue
        d = c - np.uint8(48)
        isd = d < 10
        d *= isd
        mant += d * _W14[i]
        if i < 10:
            n_dig += isd
            n_sp += sp
            pos_sp += sp * np.int16(i)
            mi = c == 45
            n_mi += mi
            pos_mi += mi * np.int16(i)
        else:
            n_dec += isd
    blank = n_blank == 14
    ok = (
        (n_sp + n_dig + n_mi == 10)
        & (2 * pos_sp == n_sp * (n_sp - 1))
        & ((n_mi == 0) | ((n_mi == 1) & (pos_mi == n_sp)))
        & point
        & (n_dec == 3)
    )
    mant[n_mi > 0] *= -1.0
    value = mant / 1000.0
    value[blank] = np.nan
    return value.reshape(shape), (~ok & ~blank).reshape(shape)


def _digit(c: U8Array) -> npt.NDArray[np.int8]:
    """One-character integer fields (LLI, SSI): the digit, 0 for blank or anything else."""
    isd = (c >= 48) & (c <= 57)
    return np.where(isd, c.astype(np.int16) - 48, 0).astype(np.int8)


def _fix_odd(
    values: FloatArray,
    odd: npt.NDArray[np.bool_],
    fields: U8Array,
    line_of: npt.NDArray[np.int64],
    col_of: npt.NDArray[np.int64],
    path: str,
    codes: list[str],
) -> None:
    """Parse the few non-standard fields with ``float`` or raise :class:`InputError`."""
    for r, j in zip(*np.nonzero(odd), strict=True):
        text = fields[r, j].tobytes().decode("ascii", "replace")
        try:
            values[r, j] = float(text)
        except ValueError:
            raise InputError(
                f"observation {codes[j]} (columns {col_of[r, j] + 1}-{col_of[r, j] + 14}): "
                f"expected a number in F14.3, found {text.strip()!r}",
                path,
                int(line_of[r, j]) + 1,
            ) from None


# --------------------------------------------------------------------------------------------
# epochs


@dataclass
class _Epochs:
    """Epochs kept (flag 0/1) and where their records are."""

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


def _time_of(y: int, mo: int, d: int, h: int, mi: int, sec: str, path: str, line: int) -> tuple[float, int]:
    """(t_s, t_ns) of a calendar time tag, seconds given as text (kept exactly)."""
    s = sec.strip()
    try:
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


def _check_event_records(texts: list[str], path: str, line0: int) -> None:
    for k, t in enumerate(texts):
        if t[60:].strip() in ("SYS / # / OBS TYPES", "# / TYPES OF OBSERV"):
            raise InputError(
                "observation types change inside the file (event record); unsupported",
                path,
                line0 + k + 1,
            )


def _epochs_v3(
    data: bytes,
    bufp: U8Array,
    starts: npt.NDArray[np.int64],
    ends: npt.NDArray[np.int64],
    hb: int,
    n_lines: int,
    path: str,
) -> _Epochs:
    first = bufp[starts[hb:n_lines]]
    ep_idx = np.flatnonzero(first == ord(">")) + hb
    ep = _Epochs()
    if n_lines > hb and (ep_idx.size == 0 or ep_idx[0] != hb):
        text = data[starts[hb] : ends[hb]].decode("ascii", "replace")
        raise InputError(f"bad epoch line: expected '> yyyy mm dd ...', found {text[:40]!r}", path, hb + 1)
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
            _check_event_records(recs, path, i + 1)
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
        t_s, t_ns = _time_of(y, mo, d, hh, mi, text[18:29], path, ln)
        clk = text[41:56].strip()
        ep.t_s.append(t_s)
        ep.t_ns.append(t_ns)
        ep.flag.append(flag)
        ep.clk_s.append(_float(clk, path, ln, "receiver clock offset") if clk else math.nan)
        ep.line.append(i)
        ep.first_rec.append(i + 1)
        ep.nsat.append(n)
    return ep


def _epochs_v2(
    data: bytes,
    starts: npt.NDArray[np.int64],
    ends: npt.NDArray[np.int64],
    hb: int,
    n_lines: int,
    n_obs: int,
    path: str,
) -> _Epochs:
    ep = _Epochs()
    per_sat = max(1, -(-n_obs // 5))
    i = hb

    def text_of(k: int) -> str:
        return data[starts[k] : ends[k]].decode("ascii", "replace")

    while i < n_lines:
        text = text_of(i)
        ln = i + 1
        if not text.strip() and all(not text_of(k).strip() for k in range(i, n_lines)):
            break  # blank lines at the end of the file
        fl = text[28:29]
        if not fl.isdigit() or not text[29:32].strip().isdigit() or int(fl) > 6:
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
            _check_event_records([text_of(k) for k in range(i + 1, i + 1 + n)], path, i + 1)
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
            if not nxt[:32].strip() and _SAT_LIST.fullmatch(nxt[32:].rstrip()):
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
        t_s, t_ns = _time_of(y, mo, d, hh, mi, text[15:26], path, ln)
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
# main reader


def _time_offset(h: _Header, t0_s: float | None, path: str) -> tuple[str, float]:
    """(time system, seconds to add to the tags to get GPST)."""
    ts = h.time_system.upper()
    if not ts:
        ts = "GLO" if h.file_system == "R" else "GPS"
    if ts in ("GPS", "GAL", "QZS", "IRN"):
        return ts, 0.0
    if ts == "BDT":
        return ts, BDT_GPST_OFFSET_S
    if ts in ("GLO", "UTC"):
        if h.leap_s is not None:
            return ts, float(h.leap_s)
        return ts, float(leap_seconds_at_utc(t0_s)) if t0_s is not None else 0.0
    raise InputError(f"TIME OF FIRST OBS: unknown time system {ts!r}", path)


def _sys_and_prn(
    bufp: U8Array,
    st: npt.NDArray[np.int64],
    sys_default: str,
    lines: npt.NDArray[np.int64],
    path: str,
) -> tuple[U8Array, npt.NDArray[np.int64]]:
    """System letter codes and PRN numbers of 3-character satellite ids at ``st``."""
    sy = bufp[st].copy()
    sy[sy == 32] = ord(sys_default)
    d1 = bufp[st + 1]
    d2 = bufp[st + 2]
    ok1 = ((d1 >= 48) & (d1 <= 57)) | (d1 == 32)
    ok2 = (d2 >= 48) & (d2 <= 57)
    known = np.isin(sy, np.frombuffer(SYSTEM_ORDER.encode(), np.uint8))
    bad = ~(ok1 & ok2 & known)
    if bad.any():
        r = int(np.argmax(bad))
        sid = bufp[st[r] : st[r] + 3].tobytes().decode("ascii", "replace")
        raise InputError(
            f"bad satellite id {sid!r}: expected a system letter from {SYSTEM_ORDER} and a 2-digit number",
            path,
            int(lines[r]) + 1,
        )
    prn = np.where(d1 == 32, 0, d1.astype(np.int64) - 48) * 10 + (d2.astype(np.int64) - 48)
    return sy, prn


def read_rinex_obs(
    path: str | PathLike[str],
    *,
    systems: str | None = None,
    t_start_s: float | None = None,
    t_end_s: float | None = None,
) -> ObsBatch:
    """Read a RINEX 2.10/2.11 or 3.0x observation file.

    Parameters
    ----------
    path : str or path-like
        Plain, gzip or Hatanaka-compressed RINEX observation file (detected from content).
    systems : str, optional
        System letters to keep, e.g. ``"GE"``; all when ``None``.
    t_start_s, t_end_s : float, optional
        Keep epochs with ``t_start_s <= t_s <= t_end_s`` (GPS seconds, see module docstring).

    Returns
    -------
    ObsBatch
        ``(T, N, K)`` arrays: T epochs (flags 0 and 1), N transmitters (union over the
        file), K signals (union over the kept systems' observation types).

    Raises
    ------
    InputError
        Unreadable or malformed file (message names file, line and reason).
    """
    p = str(path)
    if systems is not None:
        unknown = sorted(set(systems) - set(SYSTEM_ORDER))
        if unknown:
            raise InputError(
                f"systems: unknown system letter(s) {''.join(unknown)!r}; expected letters "
                f"from {SYSTEM_ORDER}"
            )
    data, compression = read_rinex_bytes(p)
    buf = np.frombuffer(data, dtype=np.uint8)
    bufp = np.concatenate([buf, np.full(1, 32, np.uint8)])
    nl = np.flatnonzero(buf == 10)
    starts = np.concatenate([[0], nl + 1]).astype(np.int64)
    ends = np.concatenate([nl, [buf.shape[0]]]).astype(np.int64)
    n_lines = starts.shape[0]
    if n_lines > 1 and starts[-1] == buf.shape[0]:
        n_lines -= 1  # the empty piece after the final newline
    lens = ends - starts

    head_lines: list[str] = []
    for k in range(n_lines):
        text = data[starts[k] : ends[k]].decode("ascii", "replace")
        head_lines.append(text)
        label = text[60:].strip()
        if label == "END OF HEADER" or (k == 0 and label != "RINEX VERSION / TYPE"):
            break
    h = _parse_header(head_lines, p)
    hb = h.n_lines  # first body line (0-based)
    v3 = h.version >= 3.0

    if v3:
        # blank lines after the last record (never part of a RINEX 3 record)
        while n_lines > hb and not data[starts[n_lines - 1] : ends[n_lines - 1]].strip():
            n_lines -= 1
        ep = _epochs_v3(data, bufp, starts, ends, hb, n_lines, p)
    else:
        if not h.obs_types2:
            raise InputError("missing '# / TYPES OF OBSERV' header record", p)
        ep = _epochs_v2(data, starts, ends, hb, n_lines, len(h.obs_types2), p)

    t_all = np.asarray(ep.t_s, dtype=float)
    tsys, offset = _time_offset(h, float(t_all[0]) if t_all.size else None, p)
    t_all = t_all + offset
    t_ns_all = np.asarray(ep.t_ns, dtype=np.int64) + int(round(offset * 1e9))
    back = np.flatnonzero(np.diff(t_all) <= 0)
    if back.size:
        k = int(back[0]) + 1
        raise InputError(
            "epoch time does not increase (duplicate or earlier than the previous epoch)",
            p,
            ep.line[k] + 1,
        )
    keep = np.ones(t_all.shape, bool)
    if t_start_s is not None:
        keep &= t_all >= t_start_s
    if t_end_s is not None:
        keep &= t_all <= t_end_s
    kept = np.flatnonzero(keep)
    T = kept.size
    nsat = np.asarray(ep.nsat, dtype=np.int64)[kept]
    first_rec = np.asarray(ep.first_rec, dtype=np.int64)[kept]
    # one entry per satellite record: epoch index (0..T-1) and first line
    ep_of = np.repeat(np.arange(T, dtype=np.int64), nsat)
    offs = np.arange(nsat.sum(), dtype=np.int64) - np.repeat(np.cumsum(nsat) - nsat, nsat)

    ignored: dict[str, list[str]] = {}
    if v3:
        rec_line = np.repeat(first_rec, nsat) + offs
        sy, prn = _sys_and_prn(bufp, starts[rec_line], "G", rec_line, p)
        obs_types = dict(h.obs_types)
        sig_map: dict[str, list[tuple[int, int, str]]] = {}  # sys -> (col j, field, signal)
        for s, codes in obs_types.items():
            lst = []
            for j, c in enumerate(codes):
                if len(c) == 3 and c[0] in _TYPE2FIELD:
                    sig = c[1:]
                    if s == "C" and h.version < 3.03 and c[1] == "1" and c[2] in "IQX":
                        sig = "2" + c[2]
                    lst.append((j, _TYPE2FIELD[c[0]], sig))
                else:
                    ignored.setdefault(s, []).append(c)
            sig_map[s] = lst
        present = set(np.unique(sy).tobytes().decode())
        missing = sorted(present - set(obs_types))
        if missing:
            r = int(np.argmax(sy == ord(missing[0])))
            raise InputError(
                f"satellite system {missing[0]!r} has no 'SYS / # / OBS TYPES' header record",
                p,
                int(rec_line[r]) + 1,
            )
    else:
        codes2 = h.obs_types2
        per_sat = max(1, -(-len(codes2) // 5))
        rec_line = np.repeat(first_rec, nsat) + offs * per_sat
        sat_txt = "".join("".join(ep.sats[k]) for k in kept.tolist()).encode("ascii", "replace")
        sat_buf = np.frombuffer(sat_txt, np.uint8)
        sy, prn = _sys_and_prn(
            np.concatenate([sat_buf, np.full(3, 32, np.uint8)]),
            np.arange(nsat.sum(), dtype=np.int64) * 3,
            "G",
            np.repeat(np.asarray(ep.line, np.int64)[kept], nsat),
            p,
        )
        present = set(np.unique(sy).tobytes().decode())
        obs_types = {s: list(codes2) for s in sorted(present, key=SYSTEM_ORDER.index)}
        sig_map = {}
        for s in obs_types:
            table = RINEX2_SIGNAL_MAP.get(s, {})
            lst = []
            for j, c in enumerate(codes2):
                if c in table:
                    lst.append((j, _TYPE2FIELD.get(c[0], 0), table[c]))  # P1/P2: code
                else:
                    ignored.setdefault(s, []).append(c)
            sig_map[s] = lst

    sys_keep = [s for s in SYSTEM_ORDER if s in obs_types and (systems is None or s in systems)]
    signals = tuple(sorted({sig for s in sys_keep for _, _, sig in sig_map[s]}))
    sig_index = {sig: k for k, sig in enumerate(signals)}

    sel = np.isin(sy, np.frombuffer("".join(sys_keep).encode(), np.uint8))
    rank = np.zeros(256, np.int64)
    for r, s in enumerate(SYSTEM_ORDER):
        rank[ord(s)] = r
    key = rank[sy] * 1000 + prn
    ukeys, tx_of = np.unique(key[sel], return_inverse=True)
    tx_ids = tuple(f"{SYSTEM_ORDER[k // 1000]}{k % 1000:02d}" for k in ukeys.tolist())
    tx_sys = tuple(t[0] for t in tx_ids)
    N, K = len(tx_ids), len(signals)

    out = np.full((4, T, N, K), np.nan)
    lli = np.zeros((T, N, K), np.int8)
    ssi = np.zeros((T, N, K), np.int8)
    rec_sel = np.flatnonzero(sel)
    sys_sel = sy[rec_sel]
    for s in sys_keep:
        m = sys_sel == ord(s)
        if not m.any() or not sig_map[s]:
            continue
        rows = rec_sel[m]
        tx = tx_of[m]
        ee = ep_of[rows]
        cols = np.array([j for j, _, _ in sig_map[s]], dtype=np.int64)
        n_types = len(obs_types[s])
        if v3:
            width = 3 + 16 * n_types
            block = _gather(bufp, starts[rec_line[rows]], lens[rec_line[rows]], width)
            f16 = block[:, 3:].reshape(rows.size, n_types, 16)[:, cols]
            line_of = np.broadcast_to(rec_line[rows][:, None], f16.shape[:2])
            col_of = np.broadcast_to(3 + 16 * cols[None, :], f16.shape[:2])
        else:
            per_sat = max(1, -(-n_types // 5))
            ln = rec_line[rows][:, None] + np.arange(per_sat)[None, :]
            block = _gather(bufp, starts[ln.ravel()], lens[ln.ravel()], 80)
            f16 = block.reshape(rows.size, per_sat * 5, 16)[:, cols]
            line_of = rec_line[rows][:, None] + (cols // 5)[None, :]
            col_of = np.broadcast_to(16 * (cols % 5)[None, :], f16.shape[:2])
        vals, odd = _f14_to_float(f16[..., :14])
        if odd.any():
            _fix_odd(
                vals,
                odd,
                f16[..., :14],
                line_of,
                col_of,
                p,
                [obs_types[s][j] for j in cols.tolist()],
            )
        d_lli = _digit(f16[..., 14])
        d_ssi = _digit(f16[..., 15])
        scale = h.scale.get(s, {})
        for q, (j, fld, sig) in enumerate(sig_map[s]):
            v = vals[:, q]
            fac = scale.get(obs_types[s][j], scale.get("*", 1.0))
            if fac != 1.0:
                v = v / fac
            k = sig_index[sig]
            out[fld, ee, tx, k] = v
            if fld == _PHASE:
                has = ~np.isnan(v)
                lli[ee[has], tx[has], k] = d_lli[has, q]
                ssi[ee[has], tx[has], k] = d_ssi[has, q]

    # wavelength of the signals each system declares (NaN elsewhere)
    declared = {s: {sig for _, _, sig in sig_map[s]} for s in sys_keep}
    wl = np.full((N, K), np.nan)
    for n, tid in enumerate(tx_ids):
        ch = h.glo_channel.get(tid) if tid[0] == "R" else None
        for k, sig in enumerate(signals):
            if sig in declared[tid[0]]:
                wl[n, k] = wavelength_m(tid[0], sig, ch)

    flags = np.asarray(ep.flag, dtype=np.int64)[kept]
    approx = h.approx_pos_m
    if approx is not None and not np.any(approx):
        approx = None
    meta: dict[str, object] = {
        "file": Path(p).name,
        "path": p,
        "compression": compression,
        "rinex_version": h.version,
        "file_system": h.file_system,
        "marker_name": h.marker,
        "receiver_type": h.receiver_type,
        "antenna_type": h.antenna_type,
        "interval_s": h.interval_s,
        "obs_types": {s: list(obs_types[s]) for s in sys_keep},
        "ignored_obs_types": {s: v for s, v in ignored.items() if s in sys_keep},
        "time_system": tsys,
        "time_offset_s": offset,
        "leap_seconds": h.leap_s,
        "glonass_channels": dict(h.glo_channel),
        "t_ns": t_ns_all[kept],
        "rcv_clock_offset_s": np.asarray(ep.clk_s, dtype=float)[kept],
        "power_failure_epochs": np.flatnonzero(flags == 1).tolist(),
        "events": ep.events,
        "n_slip_records_skipped": ep.n_slip,
        "ssi": ssi,
    }
    return ObsBatch(
        t_s=t_all[kept],
        tx_ids=tx_ids,
        system=tx_sys,
        signals=signals,
        code_m=out[0],
        phase_cyc=out[1],
        doppler_hz=out[2],
        cn0_dbhz=out[3],
        lli=lli,
        wavelength_m=wl,
        receiver=h.marker,
        approx_pos_m=approx,
        meta=meta,
    )
