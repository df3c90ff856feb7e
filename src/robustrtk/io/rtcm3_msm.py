"""RTCM 3 Multiple Signal Messages (MSM4-MSM7) into satellite-signal cells.

RTCM 10403.3 section 3.5.12 ("Multiple Signal Messages"): a header (table 3.5-78) with the
epoch time, the multiple-message bit and the satellite, signal and cell masks, then the
satellite data (table 3.5-79: rough range in whole milliseconds DF397, extended satellite
information DF419 in MSM5/7 -- the GLONASS frequency channel + 7 --, rough range modulo 1 ms
DF398, rough phase-range rate DF399 in MSM5/7) and the signal data of each cell (table 3.5-80):

=====  =====================  ====================  ===============  =========  ===========
MSM    fine pseudorange       fine phase range      lock time        C/N0       fine rate
=====  =====================  ====================  ===============  =========  ===========
4      DF400, 15 b, 2^-24 ms  DF401, 22 b, 2^-29 ms DF402 (4 b)      DF403 1 dB -
5      DF400                  DF401                 DF402            DF403      DF404 1e-4 m/s
6      DF405, 20 b, 2^-29 ms  DF406, 24 b, 2^-31 ms DF407 (10 b)     DF408 1/16 -
7      DF405                  DF406                 DF407            DF408      DF404
=====  =====================  ====================  ===============  =========  ===========

plus the half-cycle ambiguity indicator DF420 of each cell. The full pseudorange and phase
range (m) are ``c/1000 (rough + fine)`` with ``rough = DF397 + DF398 / 1024`` ms (3.5.12.3);
the Doppler (Hz) is ``-(DF399 + DF404) / wavelength``. Invalid-value markers (DF397 = 255,
the most negative value of each fine field) give NaN.

Signal ids map to RINEX codes by tables 3.5-91 (GPS), 3.5-96 (GLONASS), 3.5-99 (Galileo),
3.5-102 (SBAS), 3.5-105 (QZSS) and 3.5-108 (BeiDou, with B1I named ``2I`` as in RINEX 3.04).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["MSM_SYSTEMS", "MsmCell", "MsmMessage", "decode_msm", "msm_lock_time_s", "msm_sat_id"]

#: First message number of each system's MSM range (1071-1077 GPS, ...).
MSM_SYSTEMS = {1070: "G", 1080: "R", 1090: "E", 1100: "S", 1110: "J", 1120: "C", 1130: "I"}

RANGE_MS_M = 299_792.458  # metres in one millisecond of light time

_SIG: dict[str, tuple[str, ...]] = {
    "G": ("", "1C", "1P", "1W", "", "", "", "2C", "2P", "2W", "", "", "", "", "2S", "2L", "2X", "",
          "", "", "", "5I", "5Q", "5X", "", "", "", "", "", "1S", "1L", "1X"),
    "R": ("", "1C", "1P", "", "", "", "", "2C", "2P") + ("",) * 23,
    "E": ("", "1C", "1A", "1B", "1X", "1Z", "", "6C", "6A", "6B", "6X", "6Z", "", "7I", "7Q", "7X",
          "", "8I", "8Q", "8X", "", "5I", "5Q", "5X") + ("",) * 8,
    "S": ("", "1C") + ("",) * 19 + ("5I", "5Q", "5X") + ("",) * 8,
    "J": ("", "1C", "", "", "", "", "", "", "6S", "6L", "6X", "", "", "", "2S", "2L", "2X", "", "",
          "", "", "5I", "5Q", "5X", "", "", "", "", "", "1S", "1L", "1X"),
    "C": ("", "2I", "2Q", "2X", "", "", "", "6I", "6Q", "6X", "", "", "", "7I", "7Q", "7X", "", "",
          "", "", "", "5D", "5P", "5X", "7D", "", "", "", "", "1D", "1P", "1X"),
    "I": ("",) * 21 + ("5A",) + ("",) * 10,
}  # fmt: skip


def msm_sat_id(system: str, sat: int) -> str | None:
    """Satellite id of MSM satellite-mask position ``sat`` (1-64), None when out of range."""
    if system == "S":
        prn = sat + 119
        return f"S{prn - 100:02d}" if prn <= 158 else None
    limit = {"G": 32, "R": 27, "E": 36, "C": 63, "J": 10, "I": 14}[system]
    return f"{system}{sat:02d}" if sat <= limit else None


def msm_lock_time_s(indicator: int, extended: bool) -> float:
    """Minimum lock time (s) of a lock-time indicator.

    DF402 (4 bits, MSM4/5; table 3.5-74): 0 for 0, else ``2^(i+4)`` ms. DF407 (10 bits,
    MSM6/7; table 3.5-75): ``i`` ms below 64, then ``2^c (i - 32 c - 32) + 2^(c+5)`` ms with
    ``c = (i - 64) // 32 + 1``.
    """
    if not extended:
        return 0.0 if indicator <= 0 else 2.0 ** (min(indicator, 15) + 4) * 1e-3
    if indicator < 64:
        return indicator * 1e-3
    c = min((indicator - 64) // 32 + 1, 21)
    base = 64 + 32 * (c - 1)
    return (2.0**c * (indicator - base) + 2.0 ** (c + 5)) * 1e-3


@dataclass(frozen=True)
class MsmCell:
    """One satellite-signal cell of an MSM (values in metres; NaN when not given)."""

    sat: int
    signal: str
    signal_id: int
    pseudorange_m: float
    phaserange_m: float
    rate_m_s: float
    lock_indicator: int
    half_cycle: int
    cn0_dbhz: float
    ext_info: int


@dataclass(frozen=True)
class MsmMessage:
    """A decoded MSM: header fields and cells."""

    number: int
    system: str
    msm: int
    station: int
    epoch_field: int
    multiple: bool
    cells: tuple[MsmCell, ...]


class MsmError(ValueError):
    """The message is shorter than its masks say or its masks are impossible."""


def decode_msm(msg: bytes) -> MsmMessage:
    """Decode the payload ``msg`` of an MSM4-7 message (bit 0 = first bit of DF002).

    Raises
    ------
    MsmError
        Inconsistent length or masks; IndexError from a field beyond the payload.
    """
    big = int.from_bytes(msg, "big")
    nb = 8 * len(msg)

    def u(pos: int, n: int) -> int:
        if pos + n > nb:
            raise IndexError(f"bit field {pos}+{n} beyond {nb} bits")
        return (big >> (nb - pos - n)) & ((1 << n) - 1)

    def sg(pos: int, n: int) -> int:
        v = u(pos, n)
        return v - (1 << n) if v >> (n - 1) else v

    number = u(0, 12)
    system = MSM_SYSTEMS[number - number % 10]
    msm = number % 10
    if msm not in (4, 5, 6, 7):
        raise MsmError(f"MSM{msm} not decoded")
    station = u(12, 12)
    epoch = u(24, 30)
    multiple = bool(u(54, 1))
    i = 24 + 30 + 1 + 3 + 7 + 2 + 2 + 1 + 3  # DF003 .. DF418
    sat_mask = u(i, 64)
    sats = [k + 1 for k in range(64) if sat_mask >> (63 - k) & 1]
    i += 64
    sig_mask = u(i, 32)
    sigs = [k + 1 for k in range(32) if sig_mask >> (31 - k) & 1]
    i += 32
    ns, ng = len(sats), len(sigs)
    if ns * ng > 64:
        raise MsmError(f"{ns} satellites x {ng} signals exceed 64 cells")
    cell_mask = u(i, ns * ng)
    mask = [cell_mask >> (ns * ng - 1 - k) & 1 for k in range(ns * ng)]
    i += ns * ng
    nc = sum(mask)
    ext = msm in (5, 7)
    hi = msm in (6, 7)
    need = i + ns * (36 if ext else 18) + nc * ((80 if hi else 63) if ext else (65 if hi else 48))
    if need > nb:
        raise MsmError(f"message of {nb} bits, its masks need {need}")
    rough_ms = []
    for _ in range(ns):
        v = u(i, 8)
        i += 8
        rough_ms.append(math.nan if v == 255 else float(v))
    info = [15] * ns
    if ext:
        for k in range(ns):
            info[k] = u(i, 4)
            i += 4
    for k in range(ns):
        rough_ms[k] += u(i, 10) / 1024.0
        i += 10
    rate = [math.nan] * ns
    if ext:
        for k in range(ns):
            v = sg(i, 14)
            i += 14
            rate[k] = math.nan if v == -8192 else float(v)

    def column(bits: int, scale: float, invalid: int | None, signed: bool = True) -> list[float]:
        nonlocal i
        out = []
        for _ in range(nc):
            v = sg(i, bits) if signed else u(i, bits)
            i += bits
            out.append(math.nan if invalid is not None and v == invalid else v * scale)
        return out

    if hi:
        fpr = column(20, 2.0**-29, -524288)
        fcp = column(24, 2.0**-31, -8388608)
        lti = [int(v) for v in column(10, 1.0, None, signed=False)]
    else:
        fpr = column(15, 2.0**-24, -16384)
        fcp = column(22, 2.0**-29, -2097152)
        lti = [int(v) for v in column(4, 1.0, None, signed=False)]
    half = [int(v) for v in column(1, 1.0, None, signed=False)]
    cnr = column(10, 0.0625, None, signed=False) if hi else column(6, 1.0, None, signed=False)
    frate = column(15, 1e-4, -16384) if ext else [math.nan] * nc
    cells = []
    j = 0
    table = _SIG[system]
    for a, sat in enumerate(sats):
        for b, sig_id in enumerate(sigs):
            if not mask[a * ng + b]:
                continue
            r = rough_ms[a]
            cells.append(
                MsmCell(
                    sat=sat,
                    signal=table[sig_id - 1],
                    signal_id=sig_id,
                    pseudorange_m=(r + fpr[j]) * RANGE_MS_M,
                    phaserange_m=(r + fcp[j]) * RANGE_MS_M,
                    rate_m_s=rate[a] + frate[j],
                    lock_indicator=lti[j],
                    half_cycle=half[j],
                    cn0_dbhz=cnr[j],
                    ext_info=info[a],
                )
            )
            j += 1
    return MsmMessage(number, system, msm, station, epoch, multiple, tuple(cells))
