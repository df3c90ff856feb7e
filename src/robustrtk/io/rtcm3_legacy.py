"""RTCM 3 legacy observation messages (1001-1004 GPS, 1009-1012 GLONASS) and station
messages (1005, 1006, 1033).

Observations (RTCM 10403.3 section 3.5.1-3.5.4, tables 3.5-2 to 3.5-15): a header with the
epoch (GPS time of week in ms DF004, or GLONASS time of day in ms DF034), the synchronous-GNSS
flag DF005 and the satellite count, then per satellite:

* L1 pseudorange ``DF011 x 0.02 m + DF014 x 299792.458 m`` (GPS; GLONASS DF041 and DF044 with
  599584.916 m), L1 phase range minus pseudorange DF012/DF042 (0.5 mm, ``0x80000`` invalid),
  lock time indicator DF013/DF043 (7 bits, table 3.4-2), C/N0 DF015/DF045 (0.25 dB-Hz);
* 1004/1012 also L2 - L1 pseudorange DF017/DF047 (0.02 m, ``0x2000`` invalid), L2 phase range
  minus L1 pseudorange DF018/DF048, lock time DF019/DF049 and C/N0 DF020/DF050;
* the code indicators DF010/DF016 (GPS) and DF039/DF046 (GLONASS) choose the signal:
  L1 ``1C`` or ``1P``; GPS L2 ``2X`` (C/A or L2C), ``2P`` (P(Y) direct), ``2D`` (cross-correlated),
  ``2W`` (correlated P/Y); GLONASS L2 ``2C`` or ``2P``. GLONASS 1010/1012 carry the frequency
  channel + 7 (DF040).

1001 and 1003 (no C/N0, no ambiguity) and 1009/1011 are read for their header only: they do
not carry full pseudoranges.

Station (3.5.3): 1005/1006 give the antenna reference point (ECEF, DF025-DF027, 0.1 mm, 38-bit
signed) and 1006 the antenna height DF028; 1033 the antenna and receiver descriptors.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from robustrtk.io.bits import getbits, getbitu

__all__ = ["LegacyCell", "LegacyObs", "decode_legacy_obs", "decode_station", "legacy_lock_time_s"]

_PRUNIT_GPS = 299_792.458
_PRUNIT_GLO = 599_584.916


def legacy_lock_time_s(i: int) -> float:
    """Minimum lock time (s) of a 7-bit lock-time indicator (RTCM 10403.3 table 3.4-2)."""
    if i < 24:
        return float(i)
    if i < 48:
        return 2.0 * i - 24
    if i < 72:
        return 4.0 * i - 120
    if i < 96:
        return 8.0 * i - 408
    if i < 120:
        return 16.0 * i - 1176
    if i < 127:
        return 32.0 * i - 3096
    return 937.0


@dataclass(frozen=True)
class LegacyCell:
    """One satellite-signal of a legacy message; ``phase_minus_code_m`` is NaN when invalid."""

    prn: int
    signal: str
    pseudorange_m: float
    phase_minus_code_m: float
    lock_indicator: int
    cn0_dbhz: float
    channel: int | None


@dataclass(frozen=True)
class LegacyObs:
    """A decoded 1001-1004 / 1009-1012 message."""

    number: int
    station: int
    epoch_ms: int
    sync: bool
    cells: tuple[LegacyCell, ...]


def decode_legacy_obs(msg: bytes) -> LegacyObs:
    """Decode a 1001-1004 or 1009-1012 payload (bit 0 = first bit of DF002).

    Raises
    ------
    IndexError
        A field beyond the payload (a short message).
    """
    number = getbitu(msg, 0, 12)
    station = getbitu(msg, 12, 12)
    glo = number >= 1009
    if glo:
        epoch = getbitu(msg, 24, 27)
        i = 51
    else:
        epoch = getbitu(msg, 24, 30)
        i = 54
    sync = bool(getbitu(msg, i, 1))
    nsat = getbitu(msg, i + 1, 5)
    i += 1 + 5 + 1 + 3  # sync, count, smoothing indicator, interval
    cells: list[LegacyCell] = []
    if number in (1001, 1003, 1009, 1011):
        return LegacyObs(number, station, epoch, sync, ())
    for _ in range(nsat):
        prn = getbitu(msg, i, 6)
        code1 = getbitu(msg, i + 6, 1)
        i += 7
        ch: int | None = None
        if glo:
            ch = getbitu(msg, i, 5) - 7
            pr1 = getbitu(msg, i + 5, 25) * 0.02
            i += 30
        else:
            pr1 = getbitu(msg, i, 24) * 0.02
            i += 24
        ppr1 = getbits(msg, i, 20)
        lti1 = getbitu(msg, i + 20, 7)
        i += 27
        if glo:
            amb = getbitu(msg, i, 7)
            i += 7
            pr1 += amb * _PRUNIT_GLO
        else:
            amb = getbitu(msg, i, 8)
            i += 8
            pr1 += amb * _PRUNIT_GPS
        cnr1 = getbitu(msg, i, 8) * 0.25
        i += 8
        sig1 = "1P" if code1 else "1C"
        cells.append(LegacyCell(prn, sig1, pr1, math.nan if ppr1 == -524288 else ppr1 * 5e-4, lti1, cnr1, ch))
        if number in (1004, 1012):
            code2 = getbitu(msg, i, 2)
            pr21 = getbits(msg, i + 2, 14)
            ppr2 = getbits(msg, i + 16, 20)
            lti2 = getbitu(msg, i + 36, 7)
            cnr2 = getbitu(msg, i + 43, 8) * 0.25
            i += 51
            sig2 = ("2C" if code2 == 0 else "2P") if glo else ("2X", "2P", "2D", "2W")[code2]
            cells.append(
                LegacyCell(
                    prn,
                    sig2,
                    math.nan if pr21 == -8192 else pr1 + pr21 * 0.02,
                    math.nan if ppr2 == -524288 else ppr2 * 5e-4,
                    lti2,
                    cnr2,
                    ch,
                )
            )
    return LegacyObs(number, station, epoch, sync, tuple(cells))


def _s38(msg: bytes, pos: int) -> float:
    return getbits(msg, pos, 38) * 1e-4


def _text(msg: bytes, pos: int, n: int) -> str:
    return bytes(getbitu(msg, pos + 8 * k, 8) for k in range(n)).decode("latin-1").strip()


def decode_station(msg: bytes) -> dict[str, object]:
    """Station fields of 1005, 1006 or 1033: ``station``, ``arp_ecef_m`` (3 floats),
    ``antenna_height_m``, ``itrf_year``; ``antenna``, ``antenna_serial``, ``receiver``,
    ``firmware``, ``receiver_serial`` (1033)."""
    number = getbitu(msg, 0, 12)
    out: dict[str, object] = {"station": getbitu(msg, 12, 12)}
    if number in (1005, 1006):
        out["itrf_year"] = getbitu(msg, 24, 6)
        x = _s38(msg, 34)
        y = _s38(msg, 74)
        z = _s38(msg, 114)
        out["arp_ecef_m"] = (x, y, z)
        if number == 1006:
            out["antenna_height_m"] = getbitu(msg, 152, 16) * 1e-4
        return out
    i = 24
    fields: dict[str, object] = {}
    for name in ("antenna", "antenna_setup", "antenna_serial", "receiver", "firmware", "receiver_serial"):
        if name == "antenna_setup":
            fields[name] = getbitu(msg, i, 8)
            i += 8
            continue
        n = getbitu(msg, i, 8)
        fields[name] = _text(msg, i + 8, n)
        i += 8 + 8 * n
    out.update(fields)
    return out
