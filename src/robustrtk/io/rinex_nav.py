"""RINEX navigation (broadcast ephemeris) reader: RINEX 2 GPS/GLONASS and RINEX 3 mixed.

Supported: RINEX 2.x GPS (``.n``) and GLONASS (``.g``) files, RINEX 3.0x files with GPS,
Galileo, BeiDou, QZSS and GLONASS records (``.nav``, ``.rnx``, ``*N``/``*P`` ...), plain or
gzip-compressed (detected from the content). SBAS and NavIC records are skipped. ``D``
exponents are accepted. Header ionosphere coefficients (RINEX 2 ``ION ALPHA``/``ION BETA``,
RINEX 3 ``IONOSPHERIC CORR GPSA/GPSB/GAL``) and ``LEAP SECONDS`` are kept.

All record epochs are converted to project time ``t_s`` (GPST seconds since 1980-01-06):
GPS/QZSS/Galileo epochs are in GPST-aligned scales, BeiDou epochs in BDT (+14 s), GLONASS
epochs in UTC (+ leap seconds, from the header when given, else from the table).

The result keeps one row per ephemeris record per system, so selecting ephemerides for many
satellites is a vectorised array operation (see :mod:`robustrtk.geometry.ephemeris`).
"""

from __future__ import annotations

import gzip
import math
import os
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np

from robustrtk.core import InputError
from robustrtk.geometry.navdata import KEPLER_SYSTEMS, GloNav, KeplerNav, NavData
from robustrtk.timeutil import (
    BDT_GPST_OFFSET_S,
    WEEK_S,
    gpst_from_calendar,
    leap_seconds_at_utc,
)

__all__ = ["KEPLER_SYSTEMS", "GloNav", "KeplerNav", "NavData", "read_rinex_nav"]

# Number of values in a Keplerian record: 3 clock + 7 lines x 4 (last line partial).
_N_KEPLER_VALUES = 31
# Minimum number of values a Keplerian record must carry (up to the transmission time).
_MIN_KEPLER_VALUES = 28
_N_GLO_VALUES = 15
# Values that must be present (index 22, GPS L2P flag / Galileo and BeiDou spare, may be blank).
_REQUIRED_KEPLER = tuple(k for k in range(_MIN_KEPLER_VALUES) if k != 22)

# Broadcast-orbit lines after the epoch line, per RINEX 3 system (minimum expected).
_R3_MIN_LINES = {"G": 7, "E": 7, "C": 7, "J": 7, "R": 3, "S": 3, "I": 7}


# ----------------------------------------------------------------------------------------
# low-level helpers


def _open_text_lines(path: str) -> list[str]:
    """Lines of a possibly gzip/Unix-compressed text file (trailing newlines removed)."""
    try:
        with open(path, "rb") as fh:
            raw = fh.read()
    except OSError as exc:
        raise InputError(f"cannot read navigation file ({exc.strerror})", path=path) from exc
    if raw[:2] == b"\x1f\x8b":
        try:
            raw = gzip.decompress(raw)
        except (OSError, EOFError) as exc:
            raise InputError(f"corrupt gzip data ({exc})", path=path) from exc
    elif raw[:2] == b"\x1f\x9d":
        try:
            import hatanaka

            raw = hatanaka.decompress(raw)
        except Exception as exc:  # any failure is bad input here
            raise InputError(f"cannot decompress .Z data ({exc})", path=path) from exc
    text = raw.decode("ascii", errors="replace")
    return text.splitlines()


def _num(text: str, path: str, line_no: int, col: int) -> float:
    """Parse one RINEX number (``D`` exponents allowed; blank -> 0.0)."""
    s = text.strip()
    if not s:
        return 0.0
    try:
        return float(s.replace("D", "E").replace("d", "e"))
    except ValueError:
        raise InputError(
            f"expected a number in columns {col + 1}-{col + len(text)}, got {s!r}",
            path=path,
            line=line_no,
        ) from None


def _fields(line: str, start: int, n: int, path: str, line_no: int) -> list[float]:
    """``n`` 19-character numeric fields from column ``start`` (missing fields -> NaN)."""
    out = []
    for k in range(n):
        a = start + 19 * k
        chunk = line[a : a + 19]
        if a >= len(line.rstrip()):
            out.append(math.nan)
        else:
            out.append(_num(chunk, path, line_no, a))
    return out


def _int(text: str, path: str, line_no: int, what: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise InputError(
            f"expected an integer {what}, got {text.strip()!r}", path=path, line=line_no
        ) from None


# ----------------------------------------------------------------------------------------
# header


@dataclass
class _Header:
    version: float
    file_system: str  # "G", "R", "E", "C", "J", "M", "S"
    n_lines: int
    ion_alpha: list[float] | None = None
    ion_beta: list[float] | None = None
    ion_gal: list[float] | None = None
    leap_s: int | None = None


def _parse_header(lines: list[str], path: str) -> _Header:
    if not lines:
        raise InputError("empty file; expected a RINEX navigation header", path=path, line=1)
    first = lines[0]
    if "RINEX VERSION / TYPE" not in first[60:]:
        raise InputError(
            "expected 'RINEX VERSION / TYPE' in columns 61-80 of the first line", path=path, line=1
        )
    try:
        version = float(first[:9])
    except ValueError:
        raise InputError(f"bad RINEX version {first[:9].strip()!r}", path=path, line=1) from None
    ftype = first[20:21].upper()
    if version >= 4.0 or version < 2.0:
        raise InputError(f"unsupported RINEX version {version} (expected 2.x or 3.x)", path=path, line=1)
    if version < 3.0:
        if ftype == "N":
            system = "G"
        elif ftype == "G":
            system = "R"
        elif ftype == "H":
            system = "S"
        else:
            raise InputError(
                f"RINEX 2 file type {ftype!r} is not navigation data (expected N or G)",
                path=path,
                line=1,
            )
    else:
        if ftype != "N":
            raise InputError(
                f"RINEX 3 file type {ftype!r} is not navigation data (expected N)", path=path, line=1
            )
        system = first[40:41].upper() or "M"
        if system == " ":
            system = "G"
    hdr = _Header(version=version, file_system=system, n_lines=0)
    for i, line in enumerate(lines):
        label = line[60:].strip()
        if label == "END OF HEADER":
            hdr.n_lines = i + 1
            return hdr
        ln = i + 1
        if label == "ION ALPHA":
            hdr.ion_alpha = [_num(line[2 + 12 * k : 14 + 12 * k], path, ln, 2 + 12 * k) for k in range(4)]
        elif label == "ION BETA":
            hdr.ion_beta = [_num(line[2 + 12 * k : 14 + 12 * k], path, ln, 2 + 12 * k) for k in range(4)]
        elif label == "IONOSPHERIC CORR":
            kind = line[:4].strip().upper()
            vals = [_num(line[5 + 12 * k : 17 + 12 * k], path, ln, 5 + 12 * k) for k in range(4)]
            if kind == "GPSA":
                hdr.ion_alpha = vals
            elif kind == "GPSB":
                hdr.ion_beta = vals
            elif kind == "GAL":
                hdr.ion_gal = vals[:3]
        elif label == "LEAP SECONDS":
            hdr.leap_s = _int(line[:6], path, ln, "leap seconds in columns 1-6")
    raise InputError("no 'END OF HEADER' line found", path=path, line=len(lines))


# ----------------------------------------------------------------------------------------
# records


def _year4(y: int) -> int:
    if y < 100:
        return y + 2000 if y < 80 else y + 1900
    return y


def _epoch_r2(line: str, path: str, ln: int) -> float:
    """Epoch of a RINEX 2 record header (``PRN yy mm dd hh mm ss.s``) in its own scale."""
    try:
        y = int(line[2:5])
        mo = int(line[5:8])
        d = int(line[8:11])
        h = int(line[11:14])
        mi = int(line[14:17])
        s = float(line[17:22])
    except ValueError:
        raise InputError(
            f"bad epoch {line[2:22].strip()!r}; expected 'yy mm dd hh mm ss.s' in columns 3-22",
            path=path,
            line=ln,
        ) from None
    _check_calendar(_year4(y), mo, d, h, mi, s, path, ln)
    return gpst_from_calendar(_year4(y), mo, d, h, mi, s)


def _epoch_r3(line: str, path: str, ln: int) -> float:
    """Epoch of a RINEX 3 record header (``Xnn yyyy mm dd hh mm ss``) in its own scale."""
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
    _check_calendar(y, mo, d, h, mi, s, path, ln)
    return gpst_from_calendar(y, mo, d, h, mi, s)


def _check_calendar(y: int, mo: int, d: int, h: int, mi: int, s: float, path: str, ln: int) -> None:
    if not (1980 <= y <= 2100 and 1 <= mo <= 12 and 1 <= d <= 31 and 0 <= h <= 24 and 0 <= mi <= 60):
        raise InputError(f"epoch out of range: {y}-{mo}-{d} {h}:{mi}:{s}", path=path, line=ln)
    if not (0.0 <= s <= 61.0):
        raise InputError(f"epoch seconds out of range: {s}", path=path, line=ln)


@dataclass
class _Rows:
    """Accumulates raw records per system before conversion to arrays."""

    sat: dict[str, list[str]] = field(default_factory=lambda: {s: [] for s in (*KEPLER_SYSTEMS, "R")})
    epoch: dict[str, list[float]] = field(default_factory=lambda: {s: [] for s in (*KEPLER_SYSTEMS, "R")})
    vals: dict[str, list[list[float]]] = field(
        default_factory=lambda: {s: [] for s in (*KEPLER_SYSTEMS, "R")}
    )
    leap: list[float] = field(default_factory=list)  # leap seconds per GLONASS record
    skipped: dict[str, int] = field(default_factory=dict)


def _group_records(
    lines: list[str],
    start: int,
    is_header_line: Callable[[str], bool],
    path: str,
) -> Iterable[tuple[int, list[str]]]:
    """Yield ``(first_line_index, record_lines)`` for each record after the header."""
    i = start
    n = len(lines)
    while i < n:
        if not lines[i].strip():
            i += 1
            continue
        if not is_header_line(lines[i]):
            raise InputError(
                f"expected the first line of an ephemeris record, got {lines[i][:30].rstrip()!r}",
                path=path,
                line=i + 1,
            )
        j = i + 1
        while j < n and lines[j].strip() and not is_header_line(lines[j]):
            j += 1
        yield i, lines[i:j]
        i = j


def _read_one(path: str, rows: _Rows) -> _Header:
    lines = _open_text_lines(path)
    hdr = _parse_header(lines, path)
    leap_default = hdr.leap_s
    if hdr.version < 3.0:
        system = hdr.file_system

        def is_head2(s: str) -> bool:
            return bool(s[:3].strip())

        groups = _group_records(lines, hdr.n_lines, is_head2, path)
        need = {"G": 7, "R": 3, "S": 3}[system]
        for i0, rec in groups:
            ln = i0 + 1
            if system == "S":
                rows.skipped["S"] = rows.skipped.get("S", 0) + 1
                continue
            prn = _int(rec[0][:2], path, ln, "satellite number in columns 1-2")
            if len(rec) - 1 < need:
                raise InputError(
                    f"record of {system}{prn:02d} has {len(rec) - 1} broadcast-orbit lines, expected {need}",
                    path=path,
                    line=ln,
                )
            t = _epoch_r2(rec[0], path, ln)
            vals = _fields(rec[0], 22, 3, path, ln)
            for k, cont in enumerate(rec[1 : need + 1]):
                vals += _fields(cont, 3, 4, path, ln + 1 + k)
            _store(rows, system, f"{system}{prn:02d}", t, vals, path, ln, leap_default)
        return hdr

    def is_head3(s: str) -> bool:
        return bool(s[:1].strip())

    for i0, rec in _group_records(lines, hdr.n_lines, is_head3, path):
        ln = i0 + 1
        head = rec[0]
        system = head[0].upper()
        if system not in _R3_MIN_LINES:
            raise InputError(
                f"unknown satellite system {head[0]!r} in column 1 (expected G R E C J S I)",
                path=path,
                line=ln,
            )
        need = _R3_MIN_LINES[system]
        if system in ("S", "I"):
            rows.skipped[system] = rows.skipped.get(system, 0) + 1
            continue
        prn = _int(head[1:3], path, ln, "satellite number in columns 2-3")
        if len(rec) - 1 < need:
            raise InputError(
                f"record of {system}{prn:02d} has {len(rec) - 1} broadcast-orbit lines, expected {need}",
                path=path,
                line=ln,
            )
        t = _epoch_r3(head, path, ln)
        vals = _fields(head, 23, 3, path, ln)
        for k, cont in enumerate(rec[1 : need + 1]):
            vals += _fields(cont, 4, 4, path, ln + 1 + k)
        _store(rows, system, f"{system}{prn:02d}", t, vals, path, ln, leap_default)
    return hdr


def _store(
    rows: _Rows,
    system: str,
    sat: str,
    t_sys: float,
    vals: list[float],
    path: str,
    ln: int,
    leap_s: int | None,
) -> None:
    if system == "R":
        vals = (vals + [math.nan] * _N_GLO_VALUES)[:_N_GLO_VALUES]
        if any(math.isnan(v) for v in vals[:14]):
            raise InputError(f"GLONASS record of {sat} is incomplete", path=path, line=ln)
        rows.leap.append(math.nan if leap_s is None else float(leap_s))
    else:
        vals = (vals + [math.nan] * _N_KEPLER_VALUES)[:_N_KEPLER_VALUES]
        missing = [k for k in _REQUIRED_KEPLER if math.isnan(vals[k])]
        if missing:
            raise InputError(
                f"ephemeris record of {sat} is incomplete (value {missing[0] + 1} of "
                f"{_MIN_KEPLER_VALUES} missing)",
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


def _kepler_arrays(system: str, sats: list[str], epochs: list[float], vals: list[list[float]]) -> KeplerNav:
    v = np.asarray(vals, dtype=float).reshape(-1, _N_KEPLER_VALUES)
    t_sys = np.asarray(epochs, dtype=float)
    toe_sow = v[:, 11]
    # Toe in the system's own continuous scale: same week as toc, nearest to toc.
    week_start = np.floor(t_sys / WEEK_S) * WEEK_S
    toe_sys = week_start + toe_sow
    toe_sys = toe_sys + WEEK_S * np.round((t_sys - toe_sys) / WEEK_S)
    offset = BDT_GPST_OFFSET_S if system == "C" else 0.0
    is_gq = system in ("G", "J")
    return KeplerNav(
        sat_id=np.asarray(sats, dtype="U3"),
        toc_s=t_sys + offset,
        toe_s=toe_sys + offset,
        toe_sow_s=toe_sow,
        af0_s=v[:, 0],
        af1_s_s=v[:, 1],
        af2_s_s2=v[:, 2],
        iode=v[:, 3],
        crs_m=v[:, 4],
        delta_n_rad_s=v[:, 5],
        m0_rad=v[:, 6],
        cuc_rad=v[:, 7],
        e=v[:, 8],
        cus_rad=v[:, 9],
        sqrt_a_m05=v[:, 10],
        cic_rad=v[:, 12],
        omega0_rad=v[:, 13],
        cis_rad=v[:, 14],
        i0_rad=v[:, 15],
        crc_m=v[:, 16],
        omega_rad=v[:, 17],
        omega_dot_rad_s=v[:, 18],
        idot_rad_s=v[:, 19],
        code_or_source=v[:, 20],
        week=v[:, 21],
        accuracy_m=v[:, 23],
        health=v[:, 24],
        tgd1_s=v[:, 25],
        tgd2_s=np.full(v.shape[0], np.nan) if is_gq else v[:, 26],
        iodc=v[:, 26] if is_gq else np.full(v.shape[0], np.nan),
        ttm_s=v[:, 27],
        fit_or_aodc=v[:, 28] if system in ("G", "J", "C") else np.full(v.shape[0], np.nan),
    )


def _glo_arrays(sats: list[str], epochs: list[float], vals: list[list[float]], leap: list[float]) -> GloNav:
    v = np.asarray(vals, dtype=float).reshape(-1, _N_GLO_VALUES)
    t_utc = np.asarray(epochs, dtype=float)
    leap_arr = np.asarray(leap, dtype=float)
    leap_arr = np.where(np.isnan(leap_arr), leap_seconds_at_utc(t_utc), leap_arr)
    return GloNav(
        sat_id=np.asarray(sats, dtype="U3"),
        toe_s=t_utc + leap_arr,
        minus_tau_n_s=v[:, 0],
        gamma_n=v[:, 1],
        tk_s=v[:, 2],
        pos_m=v[:, [3, 7, 11]] * 1e3,
        vel_m_s=v[:, [4, 8, 12]] * 1e3,
        acc_m_s2=v[:, [5, 9, 13]] * 1e3,
        health=v[:, 6],
        freq_channel=np.rint(v[:, 10]).astype(np.int64),
        age_d=v[:, 14],
    )


def read_rinex_nav(paths: str | os.PathLike[str] | Sequence[str | os.PathLike[str]]) -> NavData:
    """Read one or more RINEX navigation files into a :class:`NavData`.

    Parameters
    ----------
    paths : path or sequence of paths
        RINEX 2 GPS/GLONASS or RINEX 3 navigation files, optionally gzip-compressed.
        Records of all files are concatenated (duplicates kept; selection picks one).

    Returns
    -------
    NavData

    Raises
    ------
    InputError
        Unreadable file, unsupported version or type, malformed header or record (the
        message names the file and line).
    """
    if isinstance(paths, (str, os.PathLike)):
        path_list = [os.fspath(paths)]
    else:
        path_list = [os.fspath(p) for p in paths]
    rows = _Rows()
    alpha = beta = gal = None
    leap: int | None = None
    for p in path_list:
        hdr = _read_one(p, rows)
        alpha = hdr.ion_alpha if hdr.ion_alpha is not None else alpha
        beta = hdr.ion_beta if hdr.ion_beta is not None else beta
        gal = hdr.ion_gal if hdr.ion_gal is not None else gal
        leap = hdr.leap_s if hdr.leap_s is not None else leap
    kepler = {s: _kepler_arrays(s, rows.sat[s], rows.epoch[s], rows.vals[s]) for s in KEPLER_SYSTEMS}
    glo = _glo_arrays(rows.sat["R"], rows.epoch["R"], rows.vals["R"], rows.leap)
    return NavData(
        kepler=kepler,
        glonass=glo,
        ion_gps_alpha=None if alpha is None else np.asarray(alpha, dtype=float),
        ion_gps_beta=None if beta is None else np.asarray(beta, dtype=float),
        ion_gal=None if gal is None else np.asarray(gal, dtype=float),
        leap_s=leap,
        files=tuple(path_list),
        skipped=dict(rows.skipped),
    )
