"""Broadcast navigation record types (Keplerian, GLONASS and SBAS ephemerides, ionosphere,
time-offset and Earth-orientation messages).

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

__all__ = [
    "KEPLER_SYSTEMS",
    "EarthOrientation",
    "GloNav",
    "IonoModel",
    "KeplerNav",
    "NavData",
    "SbasNav",
    "TimeOffset",
]

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
class SbasNav:
    """SBAS GEO broadcast ephemerides (WGS 84 state vectors), one row per record (M rows).

    Attributes
    ----------
    sat_id : ndarray of str, shape (M,)
        Satellite ids (``"S36"``).
    toe_s : ndarray, shape (M,)
        Reference time (record epoch, GPST) in project time (s).
    af0_s, af1_s_s : ndarray, shape (M,)
        Clock offset ``aGf0`` (s) and drift ``aGf1`` (s/s).
    ttm_s : ndarray, shape (M,)
        Transmission time of message (seconds of GPS week).
    pos_m, vel_m_s, acc_m_s2 : ndarray, shape (M, 3)
        Position (m), velocity (m/s) and acceleration (m/s^2) at ``toe_s``.
    health : ndarray, shape (M,)
        Health as broadcast.
    accuracy_m : ndarray, shape (M,)
        URA (m).
    iodn : ndarray, shape (M,)
        Issue of data navigation.
    """

    sat_id: np.ndarray
    toe_s: FloatArray
    af0_s: FloatArray
    af1_s_s: FloatArray
    ttm_s: FloatArray
    pos_m: FloatArray
    vel_m_s: FloatArray
    acc_m_s2: FloatArray
    health: FloatArray
    accuracy_m: FloatArray
    iodn: FloatArray

    def __len__(self) -> int:
        return int(self.sat_id.shape[0])

    def take(self, idx: np.ndarray) -> SbasNav:
        """Rows ``idx`` as a new :class:`SbasNav`."""
        return SbasNav(**{f.name: getattr(self, f.name)[idx] for f in fields(self)})

    @classmethod
    def empty(cls) -> SbasNav:
        """An :class:`SbasNav` without rows."""
        z = np.zeros(0)
        z3 = np.zeros((0, 3))
        return cls(np.zeros(0, dtype="U3"), z, z, z, z, z3, z3, z3, z, z, z)


@dataclass(frozen=True)
class IonoModel:
    """One broadcast ionosphere message (a RINEX 4 ``> ION`` record or a RINEX 3 header).

    Attributes
    ----------
    sat_id : str
        Transmitting satellite (``"G29"``), or the system letter alone for header values.
    message : str
        Navigation message type (``LNAV``, ``D1D2``, ``IFNV``, ``CNVX``; ``HEADER``).
    model : str
        ``"klobuchar"``, ``"nequick_g"`` or ``"bdgim"``.
    t_s : float
        Transmission time in project time (GPST s); NaN for header values.
    coeffs : ndarray
        Klobuchar: ``alpha0..3`` (s, s/semicircle, s/semicircle^2, s/semicircle^3) then
        ``beta0..3`` (s, s/semicircle, ...), shape (8,); NeQuick-G: ``ai0..ai2`` (sfu,
        sfu/degree, sfu/degree^2), shape (3,); BDGIM: ``alpha1..alpha9`` (TECu), shape (9,).
    flags : float
        Klobuchar: region code (QZSS: 0 wide area, 1 Japan area); NeQuick-G: ionospheric
        disturbance flags; NaN otherwise or when not given.
    """

    sat_id: str
    message: str
    model: str
    t_s: float
    coeffs: FloatArray
    flags: float = float("nan")


@dataclass(frozen=True)
class TimeOffset:
    """One broadcast system time offset message (a RINEX 4 ``> STO`` record).

    The offset is ``a0 + a1 (t - t_ref) + a2 (t - t_ref)^2`` (s) with ``t_ref`` = ``t_s``.

    Attributes
    ----------
    sat_id, message : str
        Transmitting satellite (its system letter alone when the record names no
        satellite) and navigation message type.
    t_s : float
        Reference epoch in project time (GPST s).
    code : str
        Time offset identifier (``GPUT`` GPS-UTC, ``GAGP`` Galileo-GPS, ...).
    sbas_id, utc_id : str
        SBAS provider and UTC realisation identifiers (blank when not given).
    t_tot_s : float
        Transmission time of the message (seconds of week).
    a0_s, a1_s_s, a2_s_s2 : float
        Polynomial coefficients (s, s/s, s/s^2).
    """

    sat_id: str
    message: str
    t_s: float
    code: str
    sbas_id: str
    utc_id: str
    t_tot_s: float
    a0_s: float
    a1_s_s: float
    a2_s_s2: float


@dataclass(frozen=True)
class EarthOrientation:
    """One broadcast Earth orientation message (a RINEX 4 ``> EOP`` record).

    Attributes
    ----------
    sat_id, message, t_s
        As in :class:`TimeOffset`.
    xp_as, dxp_as_d, ddxp_as_d2, yp_as, dyp_as_d, ddyp_as_d2 : float
        Pole coordinates (arcsec) and their first and second derivatives (arcsec/day,
        arcsec/day^2).
    t_tm_s : float
        Transmission time of the message (seconds of week).
    dut1_s, ddut1_s_d, dddut1_s_d2 : float
        UT1 - UTC (s) and its first and second derivatives (s/day, s/day^2).
    """

    sat_id: str
    message: str
    t_s: float
    xp_as: float
    dxp_as_d: float
    ddxp_as_d2: float
    yp_as: float
    dyp_as_d: float
    ddyp_as_d2: float
    t_tm_s: float
    dut1_s: float
    ddut1_s_d: float
    dddut1_s_d2: float


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
        The GPS Klobuchar model used by single-frequency users: from the RINEX 2 or 3
        header, or the earliest GPS ``LNAV`` ``> ION`` record of a RINEX 4 file.
    ion_gal : ndarray, shape (3,), or None
        NeQuick-G coefficients ``ai0..ai2`` (kept, not used here).
    ion_bds_alpha, ion_bds_beta : ndarray, shape (4,), or None
        BeiDou Klobuchar coefficients (RINEX 3 ``BDSA``/``BDSB``, RINEX 4 ``D1D2``; kept).
    leap_s : int or None
        GPST - UTC from a header, when given.
    files : tuple of str
        Files read.
    skipped : dict str -> int
        Ephemeris records skipped per system letter (NavIC; RINEX 4 records of message
        types whose orbit model is not carried here, e.g. GPS ``CNAV``).
    sbas : SbasNav
        SBAS GEO ephemerides (read; not used for positioning here).
    iono_models : tuple of IonoModel
        Every broadcast ionosphere message read (header values and RINEX 4 ``> ION``).
    time_offsets : tuple of TimeOffset
        RINEX 4 ``> STO`` records.
    earth_orientation : tuple of EarthOrientation
        RINEX 4 ``> EOP`` records.
    record_counts : dict str -> int
        Records read per kind, ``"EPH G LNAV"``, ``"ION E IFNV"``, ``"STO G LNAV"`` ...
        (RINEX 2/3 ephemerides are labelled with the message type they carry).
    skipped_records : dict str -> int
        Records skipped per kind, labelled as in ``record_counts``.
    versions : tuple of float
        RINEX version of each file in ``files``.
    """

    kepler: dict[str, KeplerNav]
    glonass: GloNav
    ion_gps_alpha: FloatArray | None = None
    ion_gps_beta: FloatArray | None = None
    ion_gal: FloatArray | None = None
    leap_s: int | None = None
    files: tuple[str, ...] = ()
    skipped: dict[str, int] = field(default_factory=dict)
    ion_bds_alpha: FloatArray | None = None
    ion_bds_beta: FloatArray | None = None
    sbas: SbasNav = field(default_factory=SbasNav.empty)
    iono_models: tuple[IonoModel, ...] = ()
    time_offsets: tuple[TimeOffset, ...] = ()
    earth_orientation: tuple[EarthOrientation, ...] = ()
    record_counts: dict[str, int] = field(default_factory=dict)
    skipped_records: dict[str, int] = field(default_factory=dict)
    versions: tuple[float, ...] = ()

    def n_records(self, system: str) -> int:
        """Number of ephemeris records of ``system`` (``G R E C J S``)."""
        if system == "R":
            return len(self.glonass)
        if system == "S":
            return len(self.sbas)
        return len(self.kepler[system]) if system in self.kepler else 0

    def glo_channels(self) -> dict[str, int]:
        """GLONASS frequency channel number per satellite id (latest record wins)."""
        g = self.glonass
        order = np.argsort(g.toe_s, kind="stable")
        return {str(g.sat_id[i]): int(g.freq_channel[i]) for i in order}
