"""GNSS constants: carrier frequencies and system letters.

Signals are named by RINEX 3 band + attribute (``"1C"``, ``"2W"``, ``"5Q"``); the band digit
and the system fix the carrier frequency. GLONASS FDMA bands 1 and 2 depend on the
satellite's frequency channel ``k``: ``f = f0 + k * df``.
"""

from __future__ import annotations

import math

from robustrtk.core import CLIGHT

#: One-letter system codes used in transmitter ids.
SYSTEMS = {
    "G": "GPS",
    "R": "GLONASS",
    "E": "Galileo",
    "C": "BeiDou",
    "J": "QZSS",
    "S": "SBAS",
    "I": "NavIC",
    "P": "pseudolite",
}

#: Carrier frequency (Hz) by (system, band digit) for CDMA signals.
FREQ_HZ: dict[tuple[str, str], float] = {
    ("G", "1"): 1575.42e6,
    ("G", "2"): 1227.60e6,
    ("G", "5"): 1176.45e6,
    ("J", "1"): 1575.42e6,
    ("J", "2"): 1227.60e6,
    ("J", "5"): 1176.45e6,
    ("J", "6"): 1278.75e6,
    ("S", "1"): 1575.42e6,
    ("S", "5"): 1176.45e6,
    ("E", "1"): 1575.42e6,
    ("E", "5"): 1176.45e6,
    ("E", "7"): 1207.140e6,
    ("E", "8"): 1191.795e6,
    ("E", "6"): 1278.75e6,
    ("C", "1"): 1575.42e6,
    ("C", "2"): 1561.098e6,
    ("C", "5"): 1176.45e6,
    ("C", "7"): 1207.140e6,
    ("C", "8"): 1191.795e6,
    ("C", "6"): 1268.52e6,
    ("R", "3"): 1202.025e6,
    ("R", "4"): 1600.995e6,
    ("R", "6"): 1248.06e6,
    ("I", "5"): 1176.45e6,
    ("I", "9"): 2492.028e6,
}

#: GLONASS FDMA: band -> (f0, df) in Hz.
GLO_FDMA_HZ = {"1": (1602.0e6, 0.5625e6), "2": (1246.0e6, 0.4375e6)}


def carrier_frequency_hz(system: str, signal: str, glo_channel: int | None = None) -> float:
    """Carrier frequency (Hz) of ``signal`` (e.g. ``"1C"``) on ``system``.

    Returns NaN when unknown (including GLONASS FDMA without a channel number).
    """
    band = signal[:1]
    if system == "R" and band in GLO_FDMA_HZ:
        if glo_channel is None:
            return math.nan
        f0, df = GLO_FDMA_HZ[band]
        return f0 + glo_channel * df
    return FREQ_HZ.get((system, band), math.nan)


def wavelength_m(system: str, signal: str, glo_channel: int | None = None) -> float:
    """Carrier wavelength (m) of ``signal`` on ``system``; NaN when unknown."""
    f = carrier_frequency_hz(system, signal, glo_channel)
    return CLIGHT / f if f == f else math.nan
