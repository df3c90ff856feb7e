"""RINEX navigation (broadcast ephemeris) reader: RINEX 2, RINEX 3 and RINEX 4.00.

Supported: RINEX 2.x GPS (``.n``), GLONASS (``.g``) and SBAS (``.h``) files, RINEX 2.12
Galileo (``.e``/``.l``) and QZSS (``.q``) files (RINEX 2 or RINEX 3 records) and mixed files,
RINEX 3.0x files
with GPS, Galileo, BeiDou, QZSS, GLONASS and SBAS records (``.nav``, ``.rnx``, ``*N``/``*P``
...), and RINEX 4.00 files (``> EPH``/``> ION``/``> STO``/``> EOP`` records, e.g. the IGS
``BRD400DLR..._MN.rnx``; see :mod:`robustrtk.io.rinex_nav4` for what is read and what is
skipped), plain or gzip-compressed (detected from the content). NavIC records are skipped and
counted. ``D`` exponents are accepted. Header ionosphere coefficients (RINEX 2 ``ION
ALPHA``/``ION BETA``, RINEX 3 ``IONOSPHERIC CORR GPSA/GPSB/GAL/BDSA/BDSB``) and ``LEAP
SECONDS`` are kept; in RINEX 4 files the earliest GPS ``LNAV`` ``> ION`` record gives the GPS
Klobuchar coefficients the single-frequency models use.

All record epochs are converted to project time ``t_s`` (GPST seconds since 1980-01-06):
GPS/QZSS/Galileo/SBAS epochs are in GPST-aligned scales, BeiDou epochs in BDT (+14 s),
GLONASS epochs in UTC (+ leap seconds, from the header when given, else from the table).

The result keeps one row per ephemeris record per system, so selecting ephemerides for many
satellites is a vectorised array operation (see :mod:`robustrtk.geometry.ephemeris`).
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from robustrtk.core import InputError
from robustrtk.geometry.navdata import (
    KEPLER_SYSTEMS,
    GloNav,
    IonoModel,
    KeplerNav,
    NavData,
    SbasNav,
)
from robustrtk.io.rinex_nav_fields import (
    N_GLO_VALUES,
    N_KEPLER_VALUES,
    N_SBAS_VALUES,
    RecordRows,
    check_calendar,
    count,
    open_text_lines,
    parse_eph_block,
    parse_fields,
    parse_int,
    parse_number,
    store_values,
)
from robustrtk.timeutil import (
    BDT_GPST_OFFSET_S,
    WEEK_S,
    gpst_from_calendar,
    leap_seconds_at_utc,
)

if TYPE_CHECKING:  # the RINEX 4 reader is imported where a RINEX 4 file is read
    from robustrtk.io.rinex_nav4 import V4Messages

__all__ = ["KEPLER_SYSTEMS", "GloNav", "KeplerNav", "NavData", "read_rinex_nav"]

# Broadcast-orbit lines after the epoch line, per RINEX 3 system (minimum expected).
_R3_MIN_LINES = {"G": 7, "E": 7, "C": 7, "J": 7, "R": 3, "S": 3, "I": 7}


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
    ion_bds_alpha: list[float] | None = None
    ion_bds_beta: list[float] | None = None
    leap_s: int | None = None


def _parse_header(lines: list[str], path: str) -> _Header:
    if not lines:
        raise InputError("empty file; expected a RINEX navigation header", path=path, line=1)
    skip = 0  # blank lines before the version line (RTKLIB skips them)
    while skip < len(lines) - 1 and not lines[skip].strip():
        skip += 1
    first = lines[skip]
    if "RINEX VERSION / TYPE" not in first[60:]:
        raise InputError(
            "expected 'RINEX VERSION / TYPE' in columns 61-80 of the first line", path=path, line=skip + 1
        )
    try:
        version = float(first[:9])
    except ValueError:
        raise InputError(f"bad RINEX version {first[:9].strip()!r}", path=path, line=skip + 1) from None
    ftype = first[20:21].upper()
    if version >= 5.0 or version < 2.0:
        raise InputError(
            f"unsupported RINEX version {version} (expected 2.x, 3.x or 4.x)", path=path, line=skip + 1
        )
    if version < 3.0:
        # RINEX 2.12: Galileo ('E' in column 41, or file type 'E'/'L'), QZSS ('J') and mixed ('M')
        # navigation files carry RINEX 3 records (system letter, 4-column continuation); a
        # Galileo or QZSS file may also carry RINEX 2 records (bare number, 3-column continuation)
        if ftype == "N" and first[40:41].upper() in ("E", "J", "M"):
            system = first[40:41].upper()
        elif ftype in ("E", "L"):
            system = "E"
        elif ftype == "N":
            system = "G"
        elif ftype == "G":
            system = "R"
        elif ftype == "H":
            system = "S"
        else:
            raise InputError(
                f"RINEX 2 file type {ftype!r} is not navigation data (expected N, G, H or E)",
                path=path,
                line=skip + 1,
            )
    else:
        if ftype != "N":
            raise InputError(
                f"RINEX {int(version)} file type {ftype!r} is not navigation data (expected N)",
                path=path,
                line=1,
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
            hdr.ion_alpha = [
                parse_number(line[2 + 12 * k : 14 + 12 * k], path, ln, 2 + 12 * k) for k in range(4)
            ]
        elif label == "ION BETA":
            hdr.ion_beta = [
                parse_number(line[2 + 12 * k : 14 + 12 * k], path, ln, 2 + 12 * k) for k in range(4)
            ]
        elif label == "IONOSPHERIC CORR":
            kind = line[:4].strip().upper()
            vals = [parse_number(line[5 + 12 * k : 17 + 12 * k], path, ln, 5 + 12 * k) for k in range(4)]
            if kind == "GPSA":
                hdr.ion_alpha = vals
            elif kind == "GPSB":
                hdr.ion_beta = vals
            elif kind == "GAL":
                hdr.ion_gal = vals[:3]
            elif kind == "BDSA":
                hdr.ion_bds_alpha = vals
            elif kind == "BDSB":
                hdr.ion_bds_beta = vals
        elif label == "LEAP SECONDS":
            hdr.leap_s = parse_int(line[:6], path, ln, "leap seconds in columns 1-6")
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
    check_calendar(_year4(y), mo, d, h, mi, s, path, ln)
    return gpst_from_calendar(_year4(y), mo, d, h, mi, s)


def _group_records(
    lines: list[str],
    start: int,
    is_header_line: Callable[[str], bool],
    path: str,
) -> Iterable[tuple[int, list[str]]]:
    """Yield ``(first_line_index, record_lines)`` for each RINEX 2/3 record after the header."""
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


def _v3_message(system: str, prn: int, vals: list[float]) -> str:
    """Navigation message type a RINEX 2/3 ephemeris record carries (RINEX 4 names)."""
    if system == "E":
        src = int(vals[20]) if math.isfinite(vals[20]) else 0
        return "FNAV" if src & 0b010 and not src & 0b101 else "INAV"
    if system == "C":
        return "D2" if prn <= 5 or prn >= 59 else "D1"
    return {"R": "FDMA", "S": "SBAS"}.get(system, "LNAV")


def _read_v2(lines: list[str], hdr: _Header, path: str, rows: RecordRows) -> None:
    system = hdr.file_system

    def is_head2(s: str) -> bool:
        return bool(s[:3].strip())

    need = {"G": 7, "E": 7, "J": 7, "R": 3, "S": 3}[system]
    for i0, rec in _group_records(lines, hdr.n_lines, is_head2, path):
        ln = i0 + 1
        prn = parse_int(rec[0][:2], path, ln, "satellite number in columns 1-2")
        sat = f"{system}{prn:02d}"
        if len(rec) - 1 < need:
            raise InputError(
                f"record of {sat} has {len(rec) - 1} broadcast-orbit lines, expected {need}",
                path=path,
                line=ln,
            )
        t = _epoch_r2(rec[0], path, ln)
        vals = parse_fields(rec[0], 22, 3, path, ln)
        for k, cont in enumerate(rec[1 : need + 1]):
            vals += parse_fields(cont, 3, 4, path, ln + 1 + k)
        store_values(rows, system, sat, t, vals, path, ln, hdr.leap_s)
        count(rows.counts, f"EPH {system} {_v3_message(system, prn, vals)}")


def _read_v3(lines: list[str], hdr: _Header, path: str, rows: RecordRows) -> None:
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
        prn = parse_int(head[1:3], path, ln, "satellite number in columns 2-3")
        if system == "I":
            count(rows.skipped, system)
            count(rows.skipped_records, "EPH I LNAV")
            continue
        vals = parse_eph_block(
            rows, system, f"{system}{prn:02d}", rec, ln, path, hdr.leap_s, _R3_MIN_LINES[system]
        )
        count(rows.counts, f"EPH {system} {_v3_message(system, prn, vals)}")


def _lettered(lines: list[str], hdr: _Header) -> bool:
    """Whether the first record of a RINEX 2.12 Galileo or QZSS file names its satellite with a
    system letter (RINEX 3 records) rather than a bare number (RINEX 2 records, ``I2``)."""
    first = next((ln for ln in lines[hdr.n_lines :] if ln.strip()), "")
    return first[:1].isalpha()


def _read_one(path: str, rows: RecordRows, v4: list[V4Messages]) -> _Header:
    """Read one file's records into ``rows``; a RINEX 4 file's other messages go to the
    container ``v4[0]`` (made by the first RINEX 4 file)."""
    lines = open_text_lines(path)
    hdr = _parse_header(lines, path)
    if hdr.version >= 4.0:
        from robustrtk.io.rinex_nav4 import V4Messages, read_v4_records

        if not v4:
            v4.append(V4Messages())
        read_v4_records(lines, hdr.n_lines, path, rows, v4[0], hdr.leap_s)
    elif hdr.version >= 3.0 or hdr.file_system == "M" or (hdr.file_system in "EJ" and _lettered(lines, hdr)):
        _read_v3(lines, hdr, path, rows)
    else:
        _read_v2(lines, hdr, path, rows)
    return hdr


def _kepler_arrays(system: str, sats: list[str], epochs: list[float], vals: list[list[float]]) -> KeplerNav:
    v = np.asarray(vals, dtype=float).reshape(-1, N_KEPLER_VALUES)
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
    v = np.asarray(vals, dtype=float).reshape(-1, N_GLO_VALUES)
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


def _sbas_arrays(sats: list[str], epochs: list[float], vals: list[list[float]]) -> SbasNav:
    v = np.asarray(vals, dtype=float).reshape(-1, N_SBAS_VALUES)
    return SbasNav(
        sat_id=np.asarray(sats, dtype="U3"),
        toe_s=np.asarray(epochs, dtype=float),
        af0_s=v[:, 0],
        af1_s_s=v[:, 1],
        ttm_s=v[:, 2],
        pos_m=v[:, [3, 7, 11]] * 1e3,
        vel_m_s=v[:, [4, 8, 12]] * 1e3,
        acc_m_s2=v[:, [5, 9, 13]] * 1e3,
        health=v[:, 6],
        accuracy_m=v[:, 10],
        iodn=v[:, 14],
    )


def _header_iono(hdr: _Header) -> list[IonoModel]:
    """Header ionosphere coefficients as :class:`IonoModel` entries."""
    out = []
    if hdr.ion_alpha is not None and hdr.ion_beta is not None:
        out.append(IonoModel("G", "HEADER", "klobuchar", math.nan, np.asarray(hdr.ion_alpha + hdr.ion_beta)))
    if hdr.ion_bds_alpha is not None and hdr.ion_bds_beta is not None:
        out.append(
            IonoModel("C", "HEADER", "klobuchar", math.nan, np.asarray(hdr.ion_bds_alpha + hdr.ion_bds_beta))
        )
    if hdr.ion_gal is not None:
        out.append(IonoModel("E", "HEADER", "nequick_g", math.nan, np.asarray(hdr.ion_gal)))
    return out


def _earliest(models: list[IonoModel], system: str, message: str) -> IonoModel | None:
    cand = [m for m in models if m.sat_id[0] == system and m.message == message]
    return min(cand, key=lambda m: m.t_s) if cand else None


def read_rinex_nav(paths: str | os.PathLike[str] | Sequence[str | os.PathLike[str]]) -> NavData:
    """Read one or more RINEX navigation files into a :class:`NavData`.

    Parameters
    ----------
    paths : path or sequence of paths
        RINEX 2, 3 or 4 navigation files, optionally gzip-compressed. Records of all files
        are concatenated (duplicates kept; selection picks one).

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
    rows = RecordRows()
    v4: list[V4Messages] = []
    alpha = beta = gal = bds_a = bds_b = None
    leap: int | None = None
    versions = []
    header_iono: list[IonoModel] = []
    for p in path_list:
        hdr = _read_one(p, rows, v4)
        versions.append(hdr.version)
        header_iono += _header_iono(hdr)
        alpha = hdr.ion_alpha if hdr.ion_alpha is not None else alpha
        beta = hdr.ion_beta if hdr.ion_beta is not None else beta
        gal = hdr.ion_gal if hdr.ion_gal is not None else gal
        bds_a = hdr.ion_bds_alpha if hdr.ion_bds_alpha is not None else bds_a
        bds_b = hdr.ion_bds_beta if hdr.ion_bds_beta is not None else bds_b
        leap = hdr.leap_s if hdr.leap_s is not None else leap
    iono4, sto4, eop4 = (v4[0].iono, v4[0].sto, v4[0].eop) if v4 else ([], [], [])
    # RINEX 4: the earliest broadcast message where no header gave the coefficients
    gps = _earliest(iono4, "G", "LNAV")
    if (alpha is None or beta is None) and gps is not None:
        alpha, beta = list(gps.coeffs[:4]), list(gps.coeffs[4:8])
    bds = _earliest(iono4, "C", "D1D2")
    if (bds_a is None or bds_b is None) and bds is not None:
        bds_a, bds_b = list(bds.coeffs[:4]), list(bds.coeffs[4:8])
    galm = _earliest(iono4, "E", "IFNV")
    if gal is None and galm is not None:
        gal = list(galm.coeffs)
    kepler = {s: _kepler_arrays(s, rows.sat[s], rows.epoch[s], rows.vals[s]) for s in KEPLER_SYSTEMS}
    glo = _glo_arrays(rows.sat["R"], rows.epoch["R"], rows.vals["R"], rows.leap)

    def arr(x: list[float] | None) -> np.ndarray | None:
        return None if x is None else np.asarray(x, dtype=float)

    return NavData(
        kepler=kepler,
        glonass=glo,
        ion_gps_alpha=arr(alpha),
        ion_gps_beta=arr(beta),
        ion_gal=arr(gal),
        leap_s=leap,
        files=tuple(path_list),
        skipped=dict(rows.skipped),
        ion_bds_alpha=arr(bds_a),
        ion_bds_beta=arr(bds_b),
        sbas=_sbas_arrays(rows.sat["S"], rows.epoch["S"], rows.vals["S"]),
        iono_models=tuple(header_iono + iono4),
        time_offsets=tuple(sto4),
        earth_orientation=tuple(eop4),
        record_counts=dict(rows.counts),
        skipped_records=dict(rows.skipped_records),
        versions=tuple(versions),
    )
