"""RINEX 3.04 navigation writer (broadcast ephemerides of a :class:`NavData`).

Writes the GPS, Galileo, BeiDou, QZSS, GLONASS and SBAS ephemerides of a :class:`NavData` as
a RINEX 3.04 mixed navigation file, with the GPS, Galileo and BeiDou ionosphere coefficients
and the leap seconds in the header. With it a RINEX 4 file can be handed to programs that
read only RINEX 3 (ION/STO/EOP records other than the header ionosphere are not written).

Values are written as ``D19.12`` numbers with ``E`` exponents. Values a :class:`KeplerNav`
does not keep are written as 0 (GPS L2 P data flag, spares); a GLONASS record gets the three
RINEX 3 orbit lines.
"""

from __future__ import annotations

import math
import os

import numpy as np

from robustrtk.geometry.navdata import KEPLER_SYSTEMS, NavData
from robustrtk.io.atomic import atomic_path
from robustrtk.timeutil import BDT_GPST_OFFSET_S, calendar_from_gpst, leap_seconds_at_gpst

__all__ = ["write_rinex3_nav"]


def _num(x: float) -> str:
    return " " * 19 if not math.isfinite(x) else f"{x: .12E}"


def _epoch(sat: str, t_sys: float) -> str:
    y, mo, d, h, mi, s = calendar_from_gpst(round(t_sys))
    return f"{sat:3s} {y:04d} {mo:02d} {d:02d} {h:02d} {mi:02d} {round(s):02d}"


def _block(sat: str, t_sys: float, vals: list[float]) -> list[str]:
    """Epoch line with 3 values, then lines of 4 (trailing NaN values left out)."""
    while vals and not math.isfinite(vals[-1]):
        vals = vals[:-1]
    out = [_epoch(sat, t_sys) + "".join(_num(v) for v in vals[:3])]
    for k in range(3, len(vals), 4):
        out.append("    " + "".join(_num(v) for v in vals[k : k + 4]).rstrip())
    return out


def _hdr(text: str, label: str) -> str:
    return f"{text:<60s}{label:<20s}"


def _corr(kind: str, vals: np.ndarray) -> str:
    body = "".join(f"{v:12.4E}" for v in vals)
    return _hdr(f"{kind:<4s} {body}", "IONOSPHERIC CORR")


def write_rinex3_nav(nav: NavData, path: str | os.PathLike[str]) -> None:
    """Write the ephemerides of ``nav`` as a RINEX 3.04 mixed navigation file.

    Parameters
    ----------
    nav : NavData
    path : path-like
        Output file (written atomically).

    Notes
    -----
    Records are written per system in the order G, E, C, J, R, S, each in the order of
    ``nav``. Epochs are whole seconds in each system's own time scale (BDT for BeiDou, UTC
    for GLONASS, using ``nav.leap_s`` or the leap second table).
    """
    lines = [_hdr("     3.04           N: GNSS NAV DATA    M: MIXED", "RINEX VERSION / TYPE")]
    if nav.ion_gps_alpha is not None and nav.ion_gps_beta is not None:
        lines += [_corr("GPSA", nav.ion_gps_alpha), _corr("GPSB", nav.ion_gps_beta)]
    if nav.ion_gal is not None:
        lines.append(_corr("GAL", np.append(nav.ion_gal, 0.0)))
    if nav.ion_bds_alpha is not None and nav.ion_bds_beta is not None:
        lines += [_corr("BDSA", nav.ion_bds_alpha), _corr("BDSB", nav.ion_bds_beta)]
    if nav.leap_s is not None:
        lines.append(_hdr(f"{nav.leap_s:6d}", "LEAP SECONDS"))
    lines.append(_hdr("", "END OF HEADER"))
    for s in KEPLER_SYSTEMS:
        k = nav.kepler[s]
        offset = BDT_GPST_OFFSET_S if s == "C" else 0.0
        is_gq = s in ("G", "J")
        for i in range(len(k)):
            vals = [
                k.af0_s[i], k.af1_s_s[i], k.af2_s_s2[i],
                k.iode[i], k.crs_m[i], k.delta_n_rad_s[i], k.m0_rad[i],
                k.cuc_rad[i], k.e[i], k.cus_rad[i], k.sqrt_a_m05[i],
                k.toe_sow_s[i], k.cic_rad[i], k.omega0_rad[i], k.cis_rad[i],
                k.i0_rad[i], k.crc_m[i], k.omega_rad[i], k.omega_dot_rad_s[i],
                k.idot_rad_s[i], k.code_or_source[i], k.week[i], 0.0,
                k.accuracy_m[i], k.health[i], k.tgd1_s[i], k.iodc[i] if is_gq else k.tgd2_s[i],
                k.ttm_s[i], k.fit_or_aodc[i],
            ]  # fmt: skip
            lines += _block(str(k.sat_id[i]), float(k.toc_s[i]) - offset, [float(v) for v in vals])
    g = nav.glonass
    for i in range(len(g)):
        t = float(g.toe_s[i])
        leap = float(nav.leap_s) if nav.leap_s is not None else float(leap_seconds_at_gpst(t))
        p, v, a = g.pos_m[i] / 1e3, g.vel_m_s[i] / 1e3, g.acc_m_s2[i] / 1e3
        vals = [
            g.minus_tau_n_s[i], g.gamma_n[i], g.tk_s[i],
            p[0], v[0], a[0], g.health[i],
            p[1], v[1], a[1], float(g.freq_channel[i]),
            p[2], v[2], a[2], g.age_d[i],
        ]  # fmt: skip
        lines += _block(str(g.sat_id[i]), t - leap, [float(x) for x in vals])
    b = nav.sbas
    for i in range(len(b)):
        p, v, a = b.pos_m[i] / 1e3, b.vel_m_s[i] / 1e3, b.acc_m_s2[i] / 1e3
        vals = [
            b.af0_s[i], b.af1_s_s[i], b.ttm_s[i],
            p[0], v[0], a[0], b.health[i],
            p[1], v[1], a[1], b.accuracy_m[i],
            p[2], v[2], a[2], b.iodn[i],
        ]  # fmt: skip
        lines += _block(str(b.sat_id[i]), float(b.toe_s[i]), [float(x) for x in vals])
    with atomic_path(path) as tmp, open(tmp, "w", encoding="ascii") as fh:
        fh.write("\n".join(lines) + "\n")
