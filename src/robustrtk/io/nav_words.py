"""Broadcast navigation words into ephemeris records: GPS/QZSS LNAV subframes and GLONASS
strings.

* GPS and QZSS LNAV (IS-GPS-200, section 20.3.3: subframe 1 clock 20.3.3.3, subframes 2 and 3
  ephemeris 20.3.3.4, subframe 4 page 18 ionosphere and UTC 20.3.3.5.1.6-7). A subframe is
  given as its ten 24-bit data words packed into 30 bytes (parity removed); subframes 1-3
  with the same issue of data (IODC low byte = IODE of subframes 2 and 3) make one record.
  Angles are broadcast in semicircles and converted with the ICD value of pi
  (3.1415926535898, IS-GPS-200 20.3.3.4.3).
* GLONASS (ICD edition 5.1, section 4.4, table 4.5): strings 1-4 of one frame make one
  record. A string is given as its bits from the idle bit onwards packed into 11 bytes (85
  bits used); numbers are sign-magnitude.

Each record is a dict with the field names of :class:`~robustrtk.geometry.navdata.KeplerNav`
or :class:`~robustrtk.geometry.navdata.GloNav` (times in GPST seconds since 1980-01-06).
"""

from __future__ import annotations

import math
from typing import Any

from robustrtk.io.bits import getbitg, getbits, getbitu
from robustrtk.timeutil import DAY_S, WEEK_S

__all__ = [
    "GPS_PI",
    "decode_glonass_frame",
    "decode_lnav_ephemeris",
    "decode_lnav_iono_utc",
    "glonass_string_number",
    "glonass_string_ok",
    "lnav_subframe_id",
    "lnav_subframe_tow",
    "ura_m",
]

#: Value of pi the GPS ICD prescribes for semicircle conversions (IS-GPS-200 20.3.3.4.3).
GPS_PI = 3.1415926535898


def ura_m(index: int) -> float:
    """Nominal URA (m) of a URA index (IS-GPS-200 20.3.3.3.1.3): ``2^(1+N/2)`` for N <= 6,
    ``2^(N-2)`` for 6 < N < 15, 8192 m (no prediction) for N = 15."""
    if index <= 6:
        return round(2.0 ** (1.0 + index / 2.0), 1)
    return 2.0 ** (index - 2) if index < 15 else 8192.0


def lnav_subframe_id(sf: bytes) -> int:
    """Subframe ID (HOW bits 20-22; IS-GPS-200 20.3.3.2) of a packed subframe."""
    return getbitu(sf, 43, 3)


def lnav_subframe_tow(sf: bytes) -> float:
    """Time of week (s) of the start of the *next* subframe, from the HOW TOW count (x6 s)."""
    return getbitu(sf, 24, 17) * 6.0


def _adj_week(t_s: float, t_ref_s: float) -> float:
    """``t_s`` shifted by whole weeks to lie within half a week of ``t_ref_s``."""
    return t_s + WEEK_S * round((t_ref_s - t_s) / WEEK_S)


def decode_lnav_ephemeris(
    sat_id: str, sf1: bytes, sf2: bytes, sf3: bytes, t_rx_s: float
) -> dict[str, Any] | None:
    """One ephemeris from LNAV subframes 1, 2 and 3 (IS-GPS-200 20.3.3.3-4).

    Parameters
    ----------
    sat_id : str
        ``"G05"`` or ``"J01"``.
    sf1, sf2, sf3 : bytes
        Packed subframes (30 bytes each).
    t_rx_s : float
        Receiver time (GPST s) near the reception of subframe 1: resolves the 10-bit week
        number and the transmission time.

    Returns
    -------
    dict or None
        The record, or None when the issues of data disagree (a mixed set).
    """
    iode2 = getbitu(sf2, 48, 8)
    iode3 = getbitu(sf3, 216, 8)
    iodc = (getbitu(sf1, 82, 2) << 8) | getbitu(sf1, 168, 8)
    if not (iode2 == iode3 == (iodc & 0xFF)):
        return None
    # subframe 1 (20.3.3.3)
    wn10 = getbitu(sf1, 48, 10)
    l2code = getbitu(sf1, 58, 2)
    ura = getbitu(sf1, 60, 4)
    health = getbitu(sf1, 64, 6)
    l2p = getbitu(sf1, 72, 1)
    tgd = getbits(sf1, 160, 8) * 2.0**-31
    toc_sow = getbitu(sf1, 176, 16) * 16.0
    af2 = getbits(sf1, 192, 8) * 2.0**-55
    af1 = getbits(sf1, 200, 16) * 2.0**-43
    af0 = getbits(sf1, 216, 22) * 2.0**-31
    # subframe 2 (20.3.3.4)
    crs = getbits(sf2, 56, 16) * 2.0**-5
    dn = getbits(sf2, 72, 16) * 2.0**-43 * GPS_PI
    m0_int = (getbitu(sf2, 88, 8) << 24) | getbitu(sf2, 96, 24)
    m0 = (m0_int - (1 << 32) if m0_int >> 31 else m0_int) * 2.0**-31 * GPS_PI
    cuc = getbits(sf2, 120, 16) * 2.0**-29
    e = ((getbitu(sf2, 136, 8) << 24) | getbitu(sf2, 144, 24)) * 2.0**-33
    cus = getbits(sf2, 168, 16) * 2.0**-29
    sqrt_a = ((getbitu(sf2, 184, 8) << 24) | getbitu(sf2, 192, 24)) * 2.0**-19
    toe_sow = getbitu(sf2, 216, 16) * 16.0
    fit_flag = getbitu(sf2, 232, 1)
    # subframe 3
    cic = getbits(sf3, 48, 16) * 2.0**-29

    def s32(hi: int, lo: int) -> int:
        v = (hi << 24) | lo
        return v - (1 << 32) if v >> 31 else v

    omega0 = s32(getbitu(sf3, 64, 8), getbitu(sf3, 72, 24)) * 2.0**-31 * GPS_PI
    cis = getbits(sf3, 96, 16) * 2.0**-29
    i0 = s32(getbitu(sf3, 112, 8), getbitu(sf3, 120, 24)) * 2.0**-31 * GPS_PI
    crc = getbits(sf3, 144, 16) * 2.0**-5
    omega = s32(getbitu(sf3, 160, 8), getbitu(sf3, 168, 24)) * 2.0**-31 * GPS_PI
    omega_dot = getbits(sf3, 192, 24) * 2.0**-43 * GPS_PI
    idot = getbits(sf3, 224, 14) * 2.0**-43 * GPS_PI
    if not sqrt_a > 1000.0:
        return None
    # full week: the 10-bit WN counted modulo 1024 (20.3.3.3.1.1) nearest the receiver time
    rx_week = math.floor(t_rx_s / WEEK_S)
    week = wn10 + 1024 * round((rx_week - wn10) / 1024)
    toe = _adj_week(week * WEEK_S + toe_sow, t_rx_s)
    toc = _adj_week(week * WEEK_S + toc_sow, toe)
    ttm = lnav_subframe_tow(sf1)  # RINEX: the HOW time of subframe 1
    t_tx = _adj_week(math.floor(t_rx_s / WEEK_S) * WEEK_S + ttm, t_rx_s)
    ttm_sow = t_tx - math.floor(toe / WEEK_S) * WEEK_S
    return {
        "sat_id": sat_id,
        "toc_s": toc,
        "toe_s": toe,
        "toe_sow_s": toe_sow,
        "af0_s": af0,
        "af1_s_s": af1,
        "af2_s_s2": af2,
        "iode": float(iode2),
        "crs_m": crs,
        "delta_n_rad_s": dn,
        "m0_rad": m0,
        "cuc_rad": cuc,
        "e": e,
        "cus_rad": cus,
        "sqrt_a_m05": sqrt_a,
        "cic_rad": cic,
        "omega0_rad": omega0,
        "cis_rad": cis,
        "i0_rad": i0,
        "crc_m": crc,
        "omega_rad": omega,
        "omega_dot_rad_s": omega_dot,
        "idot_rad_s": idot,
        "week": float(math.floor(toe / WEEK_S)),
        "code_or_source": float(l2code),
        "accuracy_m": ura_m(ura),
        "health": float(health),
        "tgd1_s": tgd,
        "tgd2_s": math.nan,
        "iodc": float(iodc),
        "ttm_s": ttm_sow,
        "fit_or_aodc": 4.0 if fit_flag == 0 else 6.0,
        "l2p_flag": float(l2p),
    }


def decode_lnav_iono_utc(sf4: bytes) -> tuple[list[float], int] | None:
    """Klobuchar coefficients and GPST-UTC leap seconds from subframe 4 page 18
    (IS-GPS-200 20.3.3.5.1.6-7), or None for another page.

    Returns
    -------
    (list of float, int) or None
        ``[alpha0..3, beta0..3]`` (s, s/semicircle, ...) and ``delta t_LS`` (s).
    """
    if getbitu(sf4, 50, 6) != 56:  # SV ID 56 = page 18
        return None
    a = [
        getbits(sf4, 56, 8) * 2.0**-30,
        getbits(sf4, 64, 8) * 2.0**-27,
        getbits(sf4, 72, 8) * 2.0**-24,
        getbits(sf4, 80, 8) * 2.0**-24,
        getbits(sf4, 88, 8) * 2.0**11,
        getbits(sf4, 96, 8) * 2.0**14,
        getbits(sf4, 104, 8) * 2.0**16,
        getbits(sf4, 112, 8) * 2.0**16,
    ]
    dt_ls = getbits(sf4, 192, 8)
    return a, dt_ls


def _hamming_cover() -> list[int]:
    """Hamming position of each GLONASS string bit b9..b85 (index i -> bit b(9+i)): the
    positions 3, 5, 6, 7, 9, ... that are not powers of two, in order (ICD 4.7)."""
    out: list[int] = []
    pos = 3
    while len(out) < 77:
        if pos & (pos - 1):
            out.append(pos)
        pos += 1
    return out


_HAMMING = _hamming_cover()


def _check_masks() -> tuple[int, ...]:
    """Per check sum C_k (k = 1..7), the bits of the 85-bit string word it xors: the check
    bit b_k and the data bits b9..b85 whose Hamming position has bit k-1 set (ICD bit j is
    bit j-1 of the word)."""
    out = []
    for k in range(7):
        mask = 1 << k
        for i, hp in enumerate(_HAMMING):
            if hp >> k & 1:
                mask |= 1 << (8 + i)
        out.append(mask)
    return tuple(out)


_CHECK_MASKS = _check_masks()


def glonass_string_ok(string: bytes) -> bool:
    """Hamming check of a GLONASS string (ICD 5.1 section 4.7, table 4.13).

    Check sums ``C_k = b_k xor (xor of the data bits b9..b85 whose Hamming position has bit
    k-1 set)`` for k = 1..7 and ``C_sum = xor of b1..b85``. The string is accepted when all
    are 0, or when exactly one ``C_k`` and ``C_sum`` are 1 (the error is in a check bit);
    anything else is an error in the data and the string is rejected (no correction is
    attempted).
    """
    if len(string) * 8 < 85:
        return False
    word = getbitu(string, 0, 85)  # bit k-1 of word = ICD bit k (string bit 0 is b85)
    n = sum((word & mask).bit_count() & 1 for mask in _CHECK_MASKS)
    c_sum = word.bit_count() & 1
    return (n == 0 and c_sum == 0) or (n == 1 and c_sum == 1)


def glonass_string_number(string: bytes) -> int:
    """String number ``m`` (bits 84-81 of the string; ICD 4.4)."""
    return getbitu(string, 1, 4)


def decode_glonass_frame(
    sat_id: str, strings: dict[int, bytes], channel: int, t_rx_s: float, leap_s: float
) -> dict[str, Any] | None:
    """One GLONASS ephemeris from strings 1-4 of a frame (ICD 5.1 section 4.4, table 4.5).

    Parameters
    ----------
    sat_id : str
        ``"R07"``.
    strings : dict int -> bytes
        Strings 1, 2, 3 and 4 (11 bytes each, idle bit first).
    channel : int
        Frequency channel number (-7..6) of the satellite.
    t_rx_s : float
        Receiver time (GPST s) of the reception of the frame: resolves the day of ``tb``.
    leap_s : float
        GPST - UTC (s).

    Returns
    -------
    dict or None
        The record, or None when a string is missing.
    """
    if any(k not in strings for k in (1, 2, 3, 4)):
        return None
    s1, s2, s3, s4 = strings[1], strings[2], strings[3], strings[4]
    # string 1: tk, x', x'', x (positions in km, velocities km/s, accelerations km/s^2)
    tk_h = getbitu(s1, 9, 5)
    tk_m = getbitu(s1, 14, 6)
    tk_s = getbitu(s1, 20, 1) * 30
    vx = getbitg(s1, 21, 24) * 2.0**-20
    ax = getbitg(s1, 45, 5) * 2.0**-30
    x = getbitg(s1, 50, 27) * 2.0**-11
    # string 2: Bn, tb, y', y'', y
    bn = getbitu(s2, 5, 3)
    tb = getbitu(s2, 9, 7)
    vy = getbitg(s2, 21, 24) * 2.0**-20
    ay = getbitg(s2, 45, 5) * 2.0**-30
    y = getbitg(s2, 50, 27) * 2.0**-11
    # string 3: gamma_n, ln, z', z'', z
    gamma = getbitg(s3, 6, 11) * 2.0**-40
    ln3 = getbitu(s3, 20, 1)
    vz = getbitg(s3, 21, 24) * 2.0**-20
    az = getbitg(s3, 45, 5) * 2.0**-30
    z = getbitg(s3, 50, 27) * 2.0**-11
    # string 4: tau_n, delta tau_n, E_n (age of the data, days)
    tau_n = getbitg(s4, 5, 22) * 2.0**-30
    age = getbitu(s4, 32, 5)
    # tb: 15-minute index of the day in Moscow time (UTC + 3 h); the day from the receiver
    t_utc = t_rx_s - leap_s
    t_msk = t_utc + 10800.0
    day0 = math.floor(t_msk / DAY_S) * DAY_S
    toe_msk = day0 + tb * 900.0
    toe_msk += DAY_S * round((t_msk - toe_msk) / DAY_S)
    tk_msk = day0 + tk_h * 3600.0 + tk_m * 60.0 + tk_s
    tk_msk += DAY_S * round((t_msk - tk_msk) / DAY_S)
    tk_utc = tk_msk - 10800.0
    tk_sow = tk_utc - math.floor(tk_utc / WEEK_S) * WEEK_S
    return {
        "sat_id": sat_id,
        "toe_s": toe_msk - 10800.0 + leap_s,
        "minus_tau_n_s": -tau_n,
        "gamma_n": gamma,
        "tk_s": tk_sow,
        "pos_m": [x * 1e3, y * 1e3, z * 1e3],
        "vel_m_s": [vx * 1e3, vy * 1e3, vz * 1e3],
        "acc_m_s2": [ax * 1e3, ay * 1e3, az * 1e3],
        "health": float(bn),
        "ln": float(ln3),
        "freq_channel": int(channel),
        "age_d": float(age),
        "tb_index": tb,
    }
