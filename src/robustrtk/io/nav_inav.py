"""Galileo I/NAV navigation pages (E1-B) into ephemeris records.

Galileo OS SIS ICD 2.0, section 4.3: a nominal I/NAV page is an even part (even/odd bit 0,
page type bit, 112 data bits, tail) and an odd part (even/odd bit 1, page type bit, 16 data
bits, reserved bits, CRC-24Q, ...). The CRC covers the even part's first 114 bits and the
odd part's first 82 bits (section 4.3.2.3, the generator of RTCM's CRC-24Q). The 128 data
bits form a word whose first 6 bits are its type; words 1-4 (same IODnav) carry the
ephemeris and clock, word 5 the ionosphere, group delays, health, week and time of week
(table 40-44 of section 4.3.5). Angles are in semicircles (converted with the GPS value of
pi, as Galileo's ICD specifies the same constant).
"""

from __future__ import annotations

import math
from typing import Any

from robustrtk.io.bits import crc24q, getbits, getbitu
from robustrtk.io.nav_words import GPS_PI
from robustrtk.timeutil import WEEK_S

__all__ = ["decode_inav_ephemeris", "inav_page_word", "sisa_m"]


def sisa_m(i: int) -> float:
    """Galileo SISA (m) of its 8-bit index (OS SIS ICD 5.1.12); -1 for "no accuracy"."""
    if i < 50:
        return i * 0.01
    if i < 75:
        return 0.5 + (i - 50) * 0.02
    if i < 100:
        return 1.0 + (i - 75) * 0.04
    if i < 126:
        return 2.0 + (i - 100) * 0.16
    return -1.0


def inav_page_word(page: bytes) -> tuple[int, bytes] | None:
    """The word of a nominal I/NAV page (even part in bytes 0-15, odd part in 16-31).

    Returns
    -------
    (word type, 16-byte word) or None
        None for an alert page, parts out of order, or a CRC that fails.
    """
    if len(page) < 32:
        return None
    even, odd = page[:16], page[16:32]
    if getbitu(even, 0, 1) != 0 or getbitu(odd, 0, 1) != 1:
        return None
    if getbitu(even, 1, 1) or getbitu(odd, 1, 1):  # alert page
        return None
    bits = (getbitu(even, 0, 114) << 82) | getbitu(odd, 0, 82)  # 196 bits, padded to 200
    if crc24q(bits.to_bytes(25, "big")) != getbitu(odd, 82, 24):
        return None
    word = (getbitu(even, 2, 112) << 16) | getbitu(odd, 2, 16)
    w = word.to_bytes(16, "big")
    return getbitu(w, 0, 6), w


def decode_inav_ephemeris(sat_id: str, words: dict[int, bytes], t_rx_s: float) -> dict[str, Any] | None:
    """One ephemeris from I/NAV words 1-5 (16 bytes each; OS SIS ICD tables 40-44).

    Parameters
    ----------
    sat_id : str
        ``"E11"``.
    words : dict int -> bytes
        Words 1, 2, 3, 4 and 5.
    t_rx_s : float
        Receiver time (GPST s): resolves the 12-bit GST week.

    Returns
    -------
    dict or None
        The record (field names of :class:`~robustrtk.geometry.navdata.KeplerNav`), or None
        when a word is missing or the IODnav of words 1-4 disagree.
    """
    if any(k not in words for k in (1, 2, 3, 4, 5)):
        return None
    w1, w2, w3, w4, w5 = (words[k] for k in (1, 2, 3, 4, 5))
    iod = [getbitu(w, 6, 10) for w in (w1, w2, w3, w4)]
    if len(set(iod)) != 1:
        return None
    a31 = 2.0**-31 * GPS_PI
    a43 = 2.0**-43 * GPS_PI
    toe_sow = getbitu(w1, 16, 14) * 60.0
    rec: dict[str, Any] = {
        "sat_id": sat_id,
        "m0_rad": getbits(w1, 30, 32) * a31,
        "e": getbitu(w1, 62, 32) * 2.0**-33,
        "sqrt_a_m05": getbitu(w1, 94, 32) * 2.0**-19,
        "omega0_rad": getbits(w2, 16, 32) * a31,
        "i0_rad": getbits(w2, 48, 32) * a31,
        "omega_rad": getbits(w2, 80, 32) * a31,
        "idot_rad_s": getbits(w2, 112, 14) * a43,
        "omega_dot_rad_s": getbits(w3, 16, 24) * a43,
        "delta_n_rad_s": getbits(w3, 40, 16) * a43,
        "cuc_rad": getbits(w3, 56, 16) * 2.0**-29,
        "cus_rad": getbits(w3, 72, 16) * 2.0**-29,
        "crc_m": getbits(w3, 88, 16) * 2.0**-5,
        "crs_m": getbits(w3, 104, 16) * 2.0**-5,
        "accuracy_m": sisa_m(getbitu(w3, 120, 8)),
        "cic_rad": getbits(w4, 22, 16) * 2.0**-29,
        "cis_rad": getbits(w4, 38, 16) * 2.0**-29,
        "af0_s": getbits(w4, 68, 31) * 2.0**-34,
        "af1_s_s": getbits(w4, 99, 21) * 2.0**-46,
        "af2_s_s2": getbits(w4, 120, 6) * 2.0**-59,
        "iode": float(iod[0]),
        "toe_sow_s": toe_sow,
        "tgd1_s": getbits(w5, 47, 10) * 2.0**-32,
        "tgd2_s": getbits(w5, 57, 10) * 2.0**-32,
    }
    if not rec["sqrt_a_m05"] > 1000.0:
        return None
    e5b_hs, e1b_hs = getbitu(w5, 67, 2), getbitu(w5, 69, 2)
    e5b_dvs, e1b_dvs = getbitu(w5, 71, 1), getbitu(w5, 72, 1)
    wn = getbitu(w5, 73, 12)
    tow = getbitu(w5, 85, 20)
    # GST week = GPS week - 1024, broadcast modulo 4096
    gweek = (wn + 1024) + 4096 * round((t_rx_s / WEEK_S - (wn + 1024)) / 4096)
    toe = gweek * WEEK_S + toe_sow
    toe += WEEK_S * round((gweek * WEEK_S + tow - toe) / WEEK_S)  # toe near the word-5 time
    toc = math.floor(toe / WEEK_S) * WEEK_S + getbitu(w4, 54, 14) * 60.0
    toc += WEEK_S * round((toe - toc) / WEEK_S)
    rec.update(
        {
            "toc_s": toc,
            "toe_s": toe,
            "week": float(math.floor(toe / WEEK_S)),
            "code_or_source": 513.0,  # I/NAV E1-B, clock for E5b/E1
            "health": float(e1b_dvs | e1b_hs << 1 | e5b_dvs << 6 | e5b_hs << 7),
            "iodc": math.nan,
            "ttm_s": float(tow),
            "fit_or_aodc": math.nan,
        }
    )
    return rec
