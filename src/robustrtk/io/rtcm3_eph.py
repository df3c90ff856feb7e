"""RTCM 3 ephemeris messages into ephemeris records.

RTCM 10403.3 section 3.5.6 and the messages' tables: 1019 GPS (table 3.5-21), 1020 GLONASS
(3.5-22), 1042 BeiDou (3.5-114), 1044 QZSS (3.5-111), 1045 Galileo F/NAV (3.5-112) and 1046
Galileo I/NAV (3.5-113). Fields are read in message order from a table of (name, bits, kind,
scale); angles in semicircles are converted with the GPS ICD value of pi. 1041 (NavIC) is
recognised and counted, not decoded: NavIC orbits are not carried by
:class:`~robustrtk.geometry.navdata.KeplerNav`.

Week numbers are resolved against a reference time (the stream's observation time): GPS and
QZSS weeks are broadcast modulo 1024, Galileo weeks (GST, GPS week - 1024) modulo 4096 and
BeiDou weeks (BDT, GPS week - 1356) modulo 8192. Records carry the RINEX 3 conventions: the
week of GPS, QZSS and Galileo records is the GPS week, that of BeiDou records the BDT week;
``toc_s``/``toe_s`` are GPST (BDT + 14 s for BeiDou).
"""

from __future__ import annotations

import math
from typing import Any

from robustrtk.io.bits import getbitg, getbits, getbitu
from robustrtk.io.nav_inav import sisa_m
from robustrtk.io.nav_words import GPS_PI, ura_m
from robustrtk.timeutil import BDT_GPST_OFFSET_S, DAY_S, WEEK_S

__all__ = ["EPHEMERIS_MESSAGES", "EPHEMERIS_TABLES", "decode_ephemeris", "field_offset"]

#: Ephemeris message numbers recognised.
EPHEMERIS_MESSAGES = (1019, 1020, 1041, 1042, 1044, 1045, 1046)

_SC = GPS_PI
_A31 = 2.0**-31 * GPS_PI  # angle LSB (semicircles -> rad)
_R43 = 2.0**-43 * GPS_PI  # rate LSB (semicircles/s -> rad/s)
# (name, bits, kind: u unsigned / s two's complement, scale)
_KEPLER_TAIL_GPS = [
    ("crs_m", 16, "s", 2.0**-5), ("delta_n_rad_s", 16, "s", _R43), ("m0_rad", 32, "s", _A31),
    ("cuc_rad", 16, "s", 2.0**-29), ("e", 32, "u", 2.0**-33), ("cus_rad", 16, "s", 2.0**-29),
    ("sqrt_a_m05", 32, "u", 2.0**-19), ("toe_sow_s", 16, "u", 16.0), ("cic_rad", 16, "s", 2.0**-29),
    ("omega0_rad", 32, "s", _A31), ("cis_rad", 16, "s", 2.0**-29), ("i0_rad", 32, "s", _A31),
    ("crc_m", 16, "s", 2.0**-5), ("omega_rad", 32, "s", _A31),
    ("omega_dot_rad_s", 24, "s", _R43),
]  # fmt: skip
#: Fields of the Keplerian ephemeris messages after DF002, in message order:
#: (name, bits, ``"u"`` unsigned or ``"s"`` two's complement, scale to the unit of the name).
EPHEMERIS_TABLES: dict[int, list[tuple[str, int, str, float]]] = {
    1019: [
        ("prn", 6, "u", 1), ("week", 10, "u", 1), ("ura", 4, "u", 1), ("code_or_source", 2, "u", 1),
        ("idot_rad_s", 14, "s", _R43), ("iode", 8, "u", 1), ("toc_sow", 16, "u", 16.0),
        ("af2_s_s2", 8, "s", 2.0**-55), ("af1_s_s", 16, "s", 2.0**-43), ("af0_s", 22, "s", 2.0**-31),
        ("iodc", 10, "u", 1), *_KEPLER_TAIL_GPS, ("tgd1_s", 8, "s", 2.0**-31), ("health", 6, "u", 1),
        ("l2p", 1, "u", 1), ("fit", 1, "u", 1),
    ],
    1044: [
        ("prn", 4, "u", 1), ("toc_sow", 16, "u", 16.0), ("af2_s_s2", 8, "s", 2.0**-55),
        ("af1_s_s", 16, "s", 2.0**-43), ("af0_s", 22, "s", 2.0**-31), ("iode", 8, "u", 1),
        *_KEPLER_TAIL_GPS, ("idot_rad_s", 14, "s", _R43), ("code_or_source", 2, "u", 1),
        ("week", 10, "u", 1), ("ura", 4, "u", 1), ("health", 6, "u", 1), ("tgd1_s", 8, "s", 2.0**-31),
        ("iodc", 10, "u", 1), ("fit", 1, "u", 1),
    ],
    1042: [
        ("prn", 6, "u", 1), ("week", 13, "u", 1), ("ura", 4, "u", 1), ("idot_rad_s", 14, "s", _R43),
        ("iode", 5, "u", 1), ("toc_sow", 17, "u", 8.0), ("af2_s_s2", 11, "s", 2.0**-66),
        ("af1_s_s", 22, "s", 2.0**-50), ("af0_s", 24, "s", 2.0**-33), ("aodc", 5, "u", 1),
        ("crs_m", 18, "s", 2.0**-6), ("delta_n_rad_s", 16, "s", _R43), ("m0_rad", 32, "s", _A31),
        ("cuc_rad", 18, "s", 2.0**-31), ("e", 32, "u", 2.0**-33), ("cus_rad", 18, "s", 2.0**-31),
        ("sqrt_a_m05", 32, "u", 2.0**-19), ("toe_sow_s", 17, "u", 8.0), ("cic_rad", 18, "s", 2.0**-31),
        ("omega0_rad", 32, "s", _A31), ("cis_rad", 18, "s", 2.0**-31), ("i0_rad", 32, "s", _A31),
        ("crc_m", 18, "s", 2.0**-6), ("omega_rad", 32, "s", _A31),
        ("omega_dot_rad_s", 24, "s", _R43), ("tgd1_s", 10, "s", 1e-10), ("tgd2_s", 10, "s", 1e-10),
        ("health", 1, "u", 1),
    ],
}  # fmt: skip
_GAL_HEAD = [
    ("prn", 6, "u", 1), ("week", 12, "u", 1), ("iode", 10, "u", 1), ("sisa", 8, "u", 1),
    ("idot_rad_s", 14, "s", _R43), ("toc_sow", 14, "u", 60.0), ("af2_s_s2", 6, "s", 2.0**-59),
    ("af1_s_s", 21, "s", 2.0**-46), ("af0_s", 31, "s", 2.0**-34), *_KEPLER_TAIL_GPS[:7],
    ("toe_sow_s", 14, "u", 60.0), *_KEPLER_TAIL_GPS[8:], ("tgd1_s", 10, "s", 2.0**-32),
]  # fmt: skip
EPHEMERIS_TABLES[1045] = [*_GAL_HEAD, ("e5a_hs", 2, "u", 1), ("e5a_dvs", 1, "u", 1)]
EPHEMERIS_TABLES[1046] = [
    *_GAL_HEAD, ("tgd2_s", 10, "s", 2.0**-32), ("e5b_hs", 2, "u", 1), ("e5b_dvs", 1, "u", 1),
    ("e1b_hs", 2, "u", 1), ("e1b_dvs", 1, "u", 1),
]  # fmt: skip

_SYSTEM = {1019: "G", 1044: "J", 1042: "C", 1045: "E", 1046: "E"}
_MESSAGE = {1019: "LNAV", 1044: "LNAV", 1042: "D1", 1045: "FNAV", 1046: "INAV"}


def field_offset(number: int, name: str) -> tuple[int, int]:
    """Bit position (from the start of the payload) and width of field ``name`` of a
    Keplerian ephemeris message."""
    i = 12
    for n, bits, _, _ in EPHEMERIS_TABLES[number]:
        if n == name:
            return i, bits
        i += bits
    raise KeyError(name)


def _read_table(msg: bytes, table: list[tuple[str, int, str, float]]) -> dict[str, float]:
    i = 12
    out: dict[str, float] = {}
    for name, bits, kind, scale in table:
        v = getbits(msg, i, bits) if kind == "s" else getbitu(msg, i, bits)
        out[name] = v * scale if scale != 1 else float(v)
        i += bits
    return out


def _nearest(t_s: float, t_ref_s: float, period_s: float) -> float:
    return t_s + period_s * round((t_ref_s - t_s) / period_s)


def _kepler(number: int, f: dict[str, float], t_ref_s: float) -> tuple[str, dict[str, Any], str]:
    system = _SYSTEM[number]
    prn = int(f["prn"])
    if system == "J":
        sat = f"J{prn if prn else 10:02d}"
    else:
        sat = f"{system}{prn if prn else 64 if system == 'C' else 36:02d}"
    w = int(f["week"])
    # GPS-aligned full week (GPST), then the system's own continuous time
    if system in ("G", "J"):
        gweek = w + 1024 * round((t_ref_s / WEEK_S - w) / 1024)
        offset = 0.0
        rinex_week = gweek
    elif system == "E":
        gweek = (w + 1024) + 4096 * round((t_ref_s / WEEK_S - (w + 1024)) / 4096)
        offset = 0.0
        rinex_week = gweek
    else:
        bweek = w + 8192 * round(((t_ref_s - BDT_GPST_OFFSET_S) / WEEK_S - 1356 - w) / 8192)
        gweek = bweek + 1356
        offset = BDT_GPST_OFFSET_S
        rinex_week = bweek
    toe_sys = gweek * WEEK_S + f["toe_sow_s"]  # the system's own scale (BDT for BeiDou)
    toc_sys = _nearest(math.floor(toe_sys / WEEK_S) * WEEK_S + f["toc_sow"], toe_sys, WEEK_S)
    if system == "E":
        health = (
            int(f.get("e1b_dvs", 0))
            | int(f.get("e1b_hs", 0)) << 1
            | int(f.get("e5a_dvs", 0)) << 3
            | int(f.get("e5a_hs", 0)) << 4
            | int(f.get("e5b_dvs", 0)) << 6
            | int(f.get("e5b_hs", 0)) << 7
        )
        source = 517.0 if number == 1046 else 258.0
        acc = sisa_m(int(f["sisa"]))
    else:
        health = int(f["health"])
        source = f.get("code_or_source", 0.0)
        acc = ura_m(int(f["ura"]))
    ttm_sow = (t_ref_s - offset) - math.floor(toe_sys / WEEK_S) * WEEK_S
    rec = {
        "sat_id": sat,
        "toc_s": toc_sys + offset,
        "toe_s": toe_sys + offset,
        "toe_sow_s": f["toe_sow_s"],
        "af0_s": f["af0_s"],
        "af1_s_s": f["af1_s_s"],
        "af2_s_s2": f["af2_s_s2"],
        "iode": f["iode"],
        **{k: f[k] for k in ("crs_m", "delta_n_rad_s", "m0_rad", "cuc_rad", "e", "cus_rad", "sqrt_a_m05")},
        **{k: f[k] for k in ("cic_rad", "omega0_rad", "cis_rad", "i0_rad", "crc_m", "omega_rad")},
        "omega_dot_rad_s": f["omega_dot_rad_s"],
        "idot_rad_s": f["idot_rad_s"],
        "week": float(rinex_week),
        "code_or_source": float(source),
        "accuracy_m": acc,
        "health": float(health),
        "tgd1_s": f["tgd1_s"],
        "tgd2_s": f.get("tgd2_s", math.nan),
        "iodc": f.get("iodc", math.nan),
        "ttm_s": ttm_sow,
        "fit_or_aodc": (4.0 if f.get("fit", 0) == 0 else 6.0)
        if system in ("G", "J")
        else f.get("aodc", math.nan),
    }
    return system, rec, _MESSAGE[number] if not (system == "C" and (prn <= 5 or prn >= 59)) else "D2"


def _glonass(msg: bytes, t_ref_s: float, leap_s: float) -> dict[str, Any]:
    i = 12
    prn = getbitu(msg, i, 6)
    ch = getbitu(msg, i + 6, 5) - 7
    i += 6 + 5 + 1 + 1 + 2
    tk_h = getbitu(msg, i, 5)
    tk_m = getbitu(msg, i + 5, 6)
    tk_s = getbitu(msg, i + 11, 1) * 30
    i += 12
    bn = getbitu(msg, i, 1)
    i += 2
    tb = getbitu(msg, i, 7)
    i += 7
    vals = []
    for _ in range(3):
        v = getbitg(msg, i, 24) * 2.0**-20
        p = getbitg(msg, i + 24, 27) * 2.0**-11
        a = getbitg(msg, i + 51, 5) * 2.0**-30
        vals.append((p, v, a))
        i += 56
    i += 1
    gamma = getbitg(msg, i, 11) * 2.0**-40
    i += 11 + 2
    ln = getbitu(msg, i, 1)
    i += 1
    tau = getbitg(msg, i, 22) * 2.0**-30
    i += 22 + 5
    age = getbitu(msg, i, 5)
    t_msk = t_ref_s - leap_s + 10800.0
    day0 = math.floor(t_msk / DAY_S) * DAY_S
    toe_msk = _nearest(day0 + tb * 900.0, t_msk, DAY_S)
    tk_utc = _nearest(day0 + tk_h * 3600.0 + tk_m * 60.0 + tk_s, t_msk, DAY_S) - 10800.0
    return {
        "sat_id": f"R{prn:02d}",
        "toe_s": toe_msk - 10800.0 + leap_s,
        "minus_tau_n_s": -tau,
        "gamma_n": gamma,
        "tk_s": tk_utc - math.floor(tk_utc / WEEK_S) * WEEK_S,
        "pos_m": [vals[k][0] * 1e3 for k in range(3)],
        "vel_m_s": [vals[k][1] * 1e3 for k in range(3)],
        "acc_m_s2": [vals[k][2] * 1e3 for k in range(3)],
        "health": float(bn),
        "ln": float(ln),
        "freq_channel": ch,
        "age_d": float(age),
    }


def decode_ephemeris(msg: bytes, t_ref_s: float, leap_s: float) -> tuple[str, dict[str, Any], str] | None:
    """Decode an ephemeris message payload.

    Parameters
    ----------
    msg : bytes
        Payload (bit 0 = first bit of DF002).
    t_ref_s : float
        Reference time (GPST s) within a few days of the ephemeris.
    leap_s : float
        GPST - UTC (GLONASS).

    Returns
    -------
    (system, record, message kind) or None
        None for 1041 (NavIC, not carried).

    Raises
    ------
    IndexError
        A field beyond the payload.
    ValueError
        Implausible values (``sqrt(A)`` below 1000 m^0.5, satellite number 0 for GLONASS).
    """
    number = getbitu(msg, 0, 12)
    if number == 1041:
        return None
    if number == 1020:
        rec = _glonass(msg, t_ref_s, leap_s)
        if rec["sat_id"] == "R00":
            raise ValueError("GLONASS satellite number 0")
        return "R", rec, "FDMA"
    f = _read_table(msg, EPHEMERIS_TABLES[number])
    if not f["sqrt_a_m05"] > 1000.0:
        raise ValueError(f"implausible sqrt(A) {f['sqrt_a_m05']}")
    return _kepler(number, f, t_ref_s)
