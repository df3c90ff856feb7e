"""Broadcast navigation record types (Keplerian and GLONASS ephemerides).

These containers hold broadcast ephemeris parameters as arrays, one row per record per
system, independent of any file format. They are filled by readers such as
:func:`robustrtk.io.rinex_nav.read_rinex_nav` and consumed by
:mod:`robustrtk.geometry.ephemeris` and :mod:`robustrtk.geometry.orbits`.

All times are project time (GPST seconds since 1980-01-06) unless a field says otherwise.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import numpy as np

from robustrtk.core import FloatArray, IntArray

__all__ = ["KEPLER_SYSTEMS", "GloNav", "KeplerNav", "NavData"]

#: Systems with Keplerian broadcast orbits (GPS, Galileo, BeiDou, QZSS).
KEPLER_SYSTEMS = ("G", "E", "C", "J")


@dataclass(frozen=True)
class KeplerNav:
    """Keplerian broadcast ephemerides of one system, one row per record (M rows).

    Attributes
    ----------
    sat_id : ndarray of str, shape (M,)
        Satellite ids (``"G05"``).
    toc_s, toe_s : ndarray, shape (M,)
        Clock reference time and ephemeris reference time in project time (GPST s).
    toe_sow_s : ndarray, shape (M,)
        Toe as broadcast (seconds of week in the system's own time scale; used by the orbit
        equations for the longitude of the ascending node).
    af0_s, af1_s_s, af2_s_s2 : ndarray, shape (M,)
        Clock polynomial.
    iode : ndarray, shape (M,)
        IODE (GPS/QZSS), IODnav (Galileo), AODE (BeiDou).
    crs_m, delta_n_rad_s, m0_rad, cuc_rad, e, cus_rad, sqrt_a_m05, cic_rad, omega0_rad,
    cis_rad, i0_rad, crc_m, omega_rad, omega_dot_rad_s, idot_rad_s : ndarray, shape (M,)
        Orbit elements (IS-GPS-200 Table 20-III names).
    week : ndarray, shape (M,)
        Week number as broadcast in the record.
    code_or_source : ndarray, shape (M,)
        GPS: codes on L2; Galileo: data sources bit field (bit 0 I/NAV E1-B, 1 F/NAV E5a-I,
        2 I/NAV E5b-I, 8 clock for E5a/E1, 9 clock for E5b/E1); BeiDou: spare.
    accuracy_m : ndarray, shape (M,)
        SV accuracy (URA / SISA) in metres.
    health : ndarray, shape (M,)
        Health word as broadcast (0 = healthy for every system).
    tgd1_s, tgd2_s : ndarray, shape (M,)
        GPS/QZSS: TGD and IODC; Galileo: BGD E5a/E1 and BGD E5b/E1; BeiDou: TGD1 (B1I) and
        TGD2 (B2I).
    iodc : ndarray, shape (M,)
        GPS/QZSS IODC (NaN for other systems).
    ttm_s : ndarray, shape (M,)
        Transmission time of message (seconds of week).
    fit_or_aodc : ndarray, shape (M,)
        GPS/QZSS fit interval (h or flag), BeiDou AODC, NaN otherwise.
    """

    sat_id: np.ndarray
    toc_s: FloatArray
    toe_s: FloatArray
    toe_sow_s: FloatArray
    af0_s: FloatArray
    af1_s_s: FloatArray
    af2_s_s2: FloatArray
    iode: FloatArray
    crs_m: FloatArray
    delta_n_rad_s: FloatArray
    m0_rad: FloatArray
    cuc_rad: FloatArray
    e: FloatArray
    cus_rad: FloatArray
    sqrt_a_m05: FloatArray
    cic_rad: FloatArray
    omega0_rad: FloatArray
    cis_rad: FloatArray
    i0_rad: FloatArray
    crc_m: FloatArray
    omega_rad: FloatArray
    omega_dot_rad_s: FloatArray
    idot_rad_s: FloatArray
    week: FloatArray
    code_or_source: FloatArray
    accuracy_m: FloatArray
    health: FloatArray
    tgd1_s: FloatArray
    tgd2_s: FloatArray
    iodc: FloatArray
    ttm_s: FloatArray
    fit_or_aodc: FloatArray

    def __len__(self) -> int:
        return int(self.sat_id.shape[0])

    def take(self, idx: np.ndarray) -> KeplerNav:
        """Rows ``idx`` (integer or boolean index) as a new :class:`KeplerNav`."""
        return KeplerNav(**{f.name: getattr(self, f.name)[idx] for f in fields(self)})


@dataclass(frozen=True)
class GloNav:
    """GLONASS broadcast ephemerides (PZ-90 state vectors), one row per record (M rows).

    Attributes
    ----------
    sat_id : ndarray of str, shape (M,)
    toe_s : ndarray, shape (M,)
        Reference time ``tb`` (record epoch, UTC in the file) in project time (GPST s).
    minus_tau_n_s : ndarray, shape (M,)
        ``-tau_n`` as broadcast: satellite clock offset is ``-tau_n + gamma_n (t - tb)``.
    gamma_n : ndarray, shape (M,)
        Relative frequency bias.
    tk_s : ndarray, shape (M,)
        Message frame time (seconds of UTC day / of week as in the file).
    pos_m, vel_m_s, acc_m_s2 : ndarray, shape (M, 3)
        PZ-90 position, velocity and luni-solar acceleration at ``tb``.
    health : ndarray, shape (M,)
        ``Bn`` health flag (0 = healthy).
    freq_channel : ndarray of int, shape (M,)
        Frequency channel number ``k`` (-7..+6).
    age_d : ndarray, shape (M,)
        Age of operation information (days).
    """

    sat_id: np.ndarray
    toe_s: FloatArray
    minus_tau_n_s: FloatArray
    gamma_n: FloatArray
    tk_s: FloatArray
    pos_m: FloatArray
    vel_m_s: FloatArray
    acc_m_s2: FloatArray
    health: FloatArray
    freq_channel: IntArray
    age_d: FloatArray

    def __len__(self) -> int:
        return int(self.sat_id.shape[0])

    def take(self, idx: np.ndarray) -> GloNav:
        """Rows ``idx`` as a new :class:`GloNav`."""
        return GloNav(**{f.name: getattr(self, f.name)[idx] for f in fields(self)})


@dataclass(frozen=True)
class NavData:
    """Broadcast navigation data read from one or more files.

    Attributes
    ----------
    kepler : dict str -> KeplerNav
        Per system letter (``G E C J``); every key present (possibly with zero rows).
    glonass : GloNav
    ion_gps_alpha, ion_gps_beta : ndarray, shape (4,), or None
        Klobuchar coefficients (s, s/semicircle, ...; s, s/semicircle, ...).
    ion_gal : ndarray, shape (3,), or None
        NeQuick-G coefficients ``ai0..ai2`` (kept, not used here).
    leap_s : int or None
        GPST - UTC from a header, when given.
    files : tuple of str
        Files read.
    skipped : dict str -> int
        Records skipped per system letter (SBAS, NavIC, unknown).
    """

    kepler: dict[str, KeplerNav]
    glonass: GloNav
    ion_gps_alpha: FloatArray | None = None
    ion_gps_beta: FloatArray | None = None
    ion_gal: FloatArray | None = None
    leap_s: int | None = None
    files: tuple[str, ...] = ()
    skipped: dict[str, int] = field(default_factory=dict)

    def n_records(self, system: str) -> int:
        """Number of ephemeris records of ``system`` (``G R E C J``)."""
        if system == "R":
            return len(self.glonass)
        return len(self.kepler[system]) if system in self.kepler else 0

    def glo_channels(self) -> dict[str, int]:
        """GLONASS frequency channel number per satellite id (latest record wins)."""
        g = self.glonass
        order = np.argsort(g.toe_s, kind="stable")
        return {str(g.sat_id[i]): int(g.freq_channel[i]) for i in order}
