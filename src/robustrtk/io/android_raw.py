"""Android raw GNSS measurements (``GnssMeasurement`` / ``GnssClock`` fields) into an ObsBatch.

The measurement model shared by the GnssLogger text log (:mod:`robustrtk.io.gnsslogger`)
and the GSDC ``device_gnss.csv`` (:mod:`robustrtk.io.gsdc`): signals and satellite ids, the
pseudorange from the clock and satellite time fields, the code-usability rules, and the
cube of one epoch per ``GnssClock`` (:func:`batch_from_rows`).

Time tag and pseudorange
------------------------
For each epoch the receiver's GPS time is ``tRx = TimeNanos - (FullBiasNanos + BiasNanos)``
(ns since 1980-01-06 GPST), taken per epoch so that the tag follows the receiver's own
estimate of GPS time; ``t_s`` is that tag in seconds (``meta["t_ns"]`` the same as int64 ns,
rounded). Each measurement's reception time adds ``TimeOffsetNanos``; the pseudorange is
``c * (tRx - tTx)`` with ``tTx = ReceivedSvTimeNanos`` in the constellation's time:

=========  =====================================================  =================
system     ``tRx`` reduced to                                     ``tTx`` valid when
=========  =====================================================  =================
GPS, QZSS  time of week (GPST)                                    ``TOW_DECODED`` or
Galileo    time of week (GST = GPST)                              ``TOW_KNOWN``
NavIC      time of week (IRNSS time = GPST)
BeiDou     time of week of BDT (``tRx - 14 s``)
GLONASS    time of day of GLONASS time (``tRx + 3 h - leap``)     ``GLO_TOD_DECODED``
                                                                  or ``GLO_TOD_KNOWN``
=========  =====================================================  =================

The difference is taken modulo the week (day for GLONASS) so week and day rollovers between
transmission and reception are handled. A code is kept only with a code lock
(``CODE_LOCK``, ``GAL_E1BC_CODE_LOCK`` or ``2ND_CODE_LOCK``), the time bits above, no
``MSEC_AMBIGUOUS``, ``ReceivedSvTimeUncertaintyNanos`` at most ``max_sv_time_unc_ns`` and a
range between 1,000 and 100,000 km; ``meta["n_code_rejected"]`` counts the others by reason.
The leap seconds come from the row's ``LeapSecond`` when given, else from the table.

Carrier phase, Doppler, C/N0
----------------------------
* ``phase_cyc = AccumulatedDeltaRangeMeters / wavelength`` where the ADR state has
  ``VALID``. ``lli`` bit 0 (loss of lock) is set where the state has ``RESET`` or
  ``CYCLE_SLIP``, on the first phase after the cell had none in the previous epoch and at
  every phase of the first epoch after a ``HardwareClockDiscontinuityCount`` change (the
  accumulation depends on the receiver clock). Bit 1 (half-cycle ambiguity) is set where
  ``HALF_CYCLE_REPORTED`` is set without ``HALF_CYCLE_RESOLVED``.
* ``doppler_hz = -PseudorangeRateMetersPerSecond / wavelength`` (RINEX sign: positive when
  the satellite approaches), kept with a code lock.
* ``cn0_dbhz = Cn0DbHz``.
* ``code_sigma_m = c * ReceivedSvTimeUncertaintyNanos``, ``phase_sigma_cyc =
  AccumulatedDeltaRangeUncertaintyMeters / wavelength``.

Signals
-------
``CarrierFrequencyHz`` gives the band (absent, as in 2016 logs: the L1/E1/B1I/G1 band), the
``CodeType`` column the RINEX attribute (absent: the defaults of :data:`DEFAULT_ATTRIBUTE`),
so GPS L1 C/A is ``"1C"``, GPS L5 ``"5Q"``, Galileo E1 ``"1C"``, E5a ``"5Q"``, BeiDou B1I
``"2I"``, GLONASS G1 ``"1C"`` as the RINEX reader names them. GLONASS frequency channels
come from the carrier frequency (``meta["glonass_channels"]``); GLONASS rows whose
``Svid`` is a channel number (93-106, slot unknown) and SBAS rows are skipped.

"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from robustrtk.core import CLIGHT, FloatArray, ObsBatch
from robustrtk.gnss import FREQ_HZ, GLO_FDMA_HZ, wavelength_m
from robustrtk.io.obs_checks import mask_impossible
from robustrtk.timeutil import BDT_GPST_OFFSET_S, DAY_S, GLONASS_UTC_OFFSET_S, WEEK_S, leap_seconds_at_gpst

__all__ = [
    "ADR_STATE",
    "CODE_LOCKS",
    "CONSTELLATIONS",
    "DEFAULT_ATTRIBUTE",
    "NS_PER_S",
    "RANGE_MAX_M",
    "RANGE_MIN_M",
    "STATE",
    "AndroidRows",
    "android_signal",
    "batch_from_rows",
    "code_usable",
    "pseudorange_m",
    "skip_reason",
    "time_window",
    "tx_id",
]

#: ``GnssMeasurement`` state bits.
STATE = {
    "CODE_LOCK": 1,
    "BIT_SYNC": 2,
    "SUBFRAME_SYNC": 4,
    "TOW_DECODED": 8,
    "MSEC_AMBIGUOUS": 16,
    "SYMBOL_SYNC": 32,
    "GLO_STRING_SYNC": 64,
    "GLO_TOD_DECODED": 128,
    "BDS_D2_BIT_SYNC": 256,
    "BDS_D2_SUBFRAME_SYNC": 512,
    "GAL_E1BC_CODE_LOCK": 1024,
    "GAL_E1C_2ND_CODE_LOCK": 2048,
    "GAL_E1B_PAGE_SYNC": 4096,
    "SBAS_SYNC": 8192,
    "TOW_KNOWN": 16384,
    "GLO_TOD_KNOWN": 32768,
    "2ND_CODE_LOCK": 65536,
}

#: ``AccumulatedDeltaRangeState`` bits.
ADR_STATE = {"VALID": 1, "RESET": 2, "CYCLE_SLIP": 4, "HALF_CYCLE_RESOLVED": 8, "HALF_CYCLE_REPORTED": 16}

#: Android ``ConstellationType`` -> system letter (SBAS 2 and unknown 0 are not read).
CONSTELLATIONS = {1: "G", 3: "R", 4: "J", 5: "C", 6: "E", 7: "I"}

#: RINEX attribute per (system, band) when the log has no ``CodeType``.
DEFAULT_ATTRIBUTE = {
    ("G", "1"): "C",
    ("G", "5"): "Q",
    ("J", "1"): "C",
    ("J", "5"): "Q",
    ("E", "1"): "C",
    ("E", "5"): "Q",
    ("E", "7"): "Q",
    ("C", "1"): "P",
    ("C", "2"): "I",
    ("C", "5"): "P",
    ("C", "7"): "I",
    ("R", "1"): "C",
    ("R", "2"): "C",
    ("I", "5"): "A",
}

#: Band assumed when ``CarrierFrequencyHz`` is absent.
_DEFAULT_BAND = {"G": "1", "J": "1", "E": "1", "C": "2", "R": "1", "I": "5"}

NS_PER_S = 1_000_000_000
_WEEK_NS = int(WEEK_S) * NS_PER_S
_DAY_NS = int(DAY_S) * NS_PER_S
CODE_LOCKS = STATE["CODE_LOCK"] | STATE["GAL_E1BC_CODE_LOCK"] | STATE["2ND_CODE_LOCK"]
_TOW = STATE["TOW_DECODED"] | STATE["TOW_KNOWN"]
_TOD = STATE["GLO_TOD_DECODED"] | STATE["GLO_TOD_KNOWN"]
#: Plausible pseudorange range (m).
RANGE_MIN_M, RANGE_MAX_M = 1.0e6, 1.0e8

# --------------------------------------------------------------------------------------------
# signals and satellites


def android_signal(
    system: str, carrier_hz: float | None, code_type: str = ""
) -> tuple[str | None, int | None]:
    """RINEX signal name and GLONASS channel of an Android measurement.

    Parameters
    ----------
    system : str
        System letter (``G R E C J I``).
    carrier_hz : float or None
        ``CarrierFrequencyHz`` (Hz); None or NaN for the system's first band.
    code_type : str
        ``CodeType`` (RINEX attribute letter); empty for the default attribute.

    Returns
    -------
    signal : str or None
        ``"1C"``, ``"5Q"``, ``"2I"``...; None when the frequency matches no band.
    glo_channel : int or None
        GLONASS FDMA channel from the frequency (None otherwise).
    """
    band: str | None = None
    channel: int | None = None
    if carrier_hz is None or not math.isfinite(carrier_hz) or carrier_hz <= 0:
        band = _DEFAULT_BAND.get(system)
    elif system == "R":
        for b, (f0, df) in GLO_FDMA_HZ.items():
            k = round((carrier_hz - f0) / df)
            if -7 <= k <= 13 and abs(carrier_hz - (f0 + k * df)) < 0.1 * df:
                band, channel = b, int(k)
                break
        if band is None:
            for (s, b), f in FREQ_HZ.items():
                if s == "R" and abs(carrier_hz - f) < 1.0e6:
                    band = b
    else:
        for (s, b), f in FREQ_HZ.items():
            if s == system and abs(carrier_hz - f) < 1.0e6:
                band = b
                break
    if band is None:
        return None, None
    attr = code_type.strip()
    if len(attr) != 1 or not attr.isalpha():
        attr = DEFAULT_ATTRIBUTE.get((system, band), "C")
    return band + attr.upper(), channel


def tx_id(constellation: int, svid: int) -> str | None:
    """Transmitter id (``"G05"``, ``"J01"``) of an Android ``ConstellationType``/``Svid``.

    None for constellations not read (SBAS, unknown), GLONASS ``Svid`` 93-106 (a channel
    number, slot unknown) and out-of-range numbers.
    """
    s = CONSTELLATIONS.get(constellation)
    if s is None:
        return None
    prn = svid
    if s == "J":
        prn = svid - 192 if svid >= 193 else svid
    if s == "R" and not 1 <= svid <= 24:
        return None
    if not 1 <= prn <= 99:
        return None
    return f"{s}{prn:02d}"


def skip_reason(constellation: int, svid: int) -> str:
    """Why :func:`tx_id` gives no transmitter for this ``ConstellationType``/``Svid``."""
    if constellation == 3 and 93 <= svid <= 106:
        return "GLONASS Svid 93-106 (frequency channel, slot unknown)"
    if constellation not in CONSTELLATIONS:
        return f"ConstellationType {constellation} not read"
    return f"ConstellationType {constellation}: Svid {svid} out of range"


def code_usable(system: str, state: int) -> str:
    """Why a code measurement is unusable given its ``State`` bits ("" when usable)."""
    if not state & CODE_LOCKS:
        return "no code lock"
    if state & STATE["MSEC_AMBIGUOUS"]:
        return "millisecond ambiguity"
    if system == "R":
        return "" if state & _TOD else "GLONASS time of day unknown"
    return "" if state & _TOW else "time of week unknown"


def pseudorange_m(
    system: str,
    time_nanos: int,
    full_bias_nanos: int,
    bias_nanos: float,
    time_offset_nanos: float,
    received_sv_time_nanos: int,
    leap_s: float | None = None,
) -> float:
    """Pseudorange (m) from the raw Android fields of one measurement.

    Parameters
    ----------
    system : str
        System letter.
    time_nanos, full_bias_nanos : int
        ``TimeNanos`` and ``FullBiasNanos`` (ns, exact integers).
    bias_nanos, time_offset_nanos : float
        ``BiasNanos`` and ``TimeOffsetNanos`` (ns).
    received_sv_time_nanos : int
        ``ReceivedSvTimeNanos`` (ns of week, or of day for GLONASS).
    leap_s : float, optional
        GPST - UTC (s), GLONASS only; from the table when None.

    Returns
    -------
    float
        ``c * (tRx - tTx)`` (m), the difference taken modulo the week (day for GLONASS).
    """
    t_int = int(time_nanos) - int(full_bias_nanos)
    frac = float(time_offset_nanos) - float(bias_nanos)
    if system == "R":
        if leap_s is None:
            leap_s = float(leap_seconds_at_gpst(t_int / NS_PER_S))
        period = _DAY_NS
        t_rx = t_int + int(GLONASS_UTC_OFFSET_S) * NS_PER_S - int(round(leap_s)) * NS_PER_S
    else:
        period = _WEEK_NS
        t_rx = t_int - (int(BDT_GPST_OFFSET_S) * NS_PER_S if system == "C" else 0)
    d = (t_rx - int(received_sv_time_nanos)) % period
    if d > period // 2:
        d -= period
    return (d + frac) * 1e-9 * CLIGHT


# --------------------------------------------------------------------------------------------
# flat measurement table -> ObsBatch


@dataclass
class AndroidRows:
    """Android measurements of one log, one entry per row, grouped into epochs.

    Attributes
    ----------
    t_s : ndarray, shape (T,)
        Epoch tags (GPST s), increasing.
    t_ns : ndarray of int64, shape (T,)
        The same as ns (rounded).
    clock_count : ndarray of int64, shape (T,)
        ``HardwareClockDiscontinuityCount`` of each epoch (0 when not logged).
    epoch, tx, signal : list, length R
        Epoch index, transmitter id and signal name of each row.
    code_m, code_sigma_m, adr_m, adr_sigma_m, prr_m_s, cn0_dbhz : list of float
        Pseudorange (NaN when unusable), its sigma (m), ADR (m), its sigma (m),
        pseudorange rate (m/s, NaN when unusable) and C/N0 (dB-Hz), NaN where absent.
    adr_state : list of int
        ``AccumulatedDeltaRangeState`` (0 when absent).
    line : list of int
        1-based line of each row (for messages).
    glo_channel : dict
        GLONASS channel per transmitter.
    """

    t_s: list[float] = field(default_factory=list)
    t_ns: list[int] = field(default_factory=list)
    clock_count: list[int] = field(default_factory=list)
    epoch: list[int] = field(default_factory=list)
    tx: list[str] = field(default_factory=list)
    signal: list[str] = field(default_factory=list)
    code_m: list[float] = field(default_factory=list)
    code_sigma_m: list[float] = field(default_factory=list)
    adr_m: list[float] = field(default_factory=list)
    adr_sigma_m: list[float] = field(default_factory=list)
    adr_state: list[int] = field(default_factory=list)
    prr_m_s: list[float] = field(default_factory=list)
    cn0_dbhz: list[float] = field(default_factory=list)
    line: list[int] = field(default_factory=list)
    glo_channel: dict[str, int] = field(default_factory=dict)


_ORDER = "GRECJSI"


def _tx_key(t: str) -> tuple[int, int]:
    return _ORDER.index(t[0]) if t[0] in _ORDER else len(_ORDER), int(t[1:])


def time_window(batch: ObsBatch, t_start_s: float | None, t_end_s: float | None) -> ObsBatch:
    if t_start_s is None and t_end_s is None:
        return batch
    keep = np.ones(len(batch), bool)
    if t_start_s is not None:
        keep &= batch.t_s >= t_start_s
    if t_end_s is not None:
        keep &= batch.t_s <= t_end_s
    return batch.select_epochs(keep)


def batch_from_rows(
    rows: AndroidRows,
    meta: dict[str, object],
    receiver: str = "",
    approx_pos_m: FloatArray | None = None,
) -> ObsBatch:
    """Stack an :class:`AndroidRows` table into an :class:`ObsBatch` (phase, LLI, sigmas).

    Parameters
    ----------
    rows : AndroidRows
    meta : dict
        Extra entries for ``ObsBatch.meta`` (``t_ns``, ``n_duplicates`` and
        ``clock_discontinuity_epochs`` are added).
    receiver : str
        Receiver name.
    approx_pos_m : ndarray, shape (3,), optional
        Approximate ECEF position (m).

    Returns
    -------
    ObsBatch
        With ``code_sigma_m`` and ``phase_sigma_cyc`` filled (NaN where unknown).
    """
    tx_ids = tuple(sorted(set(rows.tx), key=_tx_key))
    signals = tuple(sorted(set(rows.signal)))
    T, N, K = len(rows.t_s), len(tx_ids), len(signals)
    ti = {t: n for n, t in enumerate(tx_ids)}
    si = {s: k for k, s in enumerate(signals)}
    e = np.asarray(rows.epoch, np.int64)
    n = np.asarray([ti[t] for t in rows.tx], np.int64)
    k = np.asarray([si[s] for s in rows.signal], np.int64)
    # duplicates (same epoch, transmitter and signal): the first row wins
    flat = (e * N + n) * K + k if e.size else np.zeros(0, np.int64)
    _, first = np.unique(flat, return_index=True)
    first.sort()
    n_dup = int(e.size - first.size)
    e, n, k = e[first], n[first], k[first]

    def arr(values: Sequence[float]) -> FloatArray:
        return np.asarray(values, float)[first]

    # wavelengths of the signals each system has (NaN elsewhere, as the RINEX reader)
    declared = {(t[0], sg) for t, sg in zip(rows.tx, rows.signal, strict=True)}
    wl = np.full((N, K), np.nan)
    for t, nn in ti.items():
        ch = rows.glo_channel.get(t)
        for sig, kk in si.items():
            if (t[0], sig) in declared:
                wl[nn, kk] = wavelength_m(t[0], sig, ch)
    lam = wl[n, k]

    def cube(values: FloatArray) -> FloatArray:
        out = np.full((T, N, K), np.nan)
        out[e, n, k] = values
        return out

    state = np.asarray(rows.adr_state, np.int64)[first]
    adr = arr(rows.adr_m)
    ok_phase = ((state & ADR_STATE["VALID"]) != 0) & np.isfinite(adr) & (adr != 0.0) & np.isfinite(lam)
    phase = np.where(ok_phase, adr / lam, np.nan)
    phase_sig = np.where(ok_phase, arr(rows.adr_sigma_m) / lam, np.nan)
    code = arr(rows.code_m)
    code_sig = np.where(np.isfinite(code), arr(rows.code_sigma_m), np.nan)
    doppler = -arr(rows.prr_m_s) / lam

    lli = np.zeros((T, N, K), np.int8)
    slip = ok_phase & ((state & (ADR_STATE["RESET"] | ADR_STATE["CYCLE_SLIP"])) != 0)
    half = (
        ok_phase
        & ((state & ADR_STATE["HALF_CYCLE_REPORTED"]) != 0)
        & ((state & ADR_STATE["HALF_CYCLE_RESOLVED"]) == 0)
    )
    lli[e[slip], n[slip], k[slip]] |= 1
    lli[e[half], n[half], k[half]] |= 2
    phase_c = cube(phase)
    has = np.isfinite(phase_c)
    # first phase after a gap, and every phase after a clock discontinuity
    gap = has[1:] & ~has[:-1]
    lli[1:][gap] |= 1
    cc = np.asarray(rows.clock_count, np.int64)
    jumps = np.flatnonzero(np.diff(cc) != 0) + 1 if cc.size else np.zeros(0, np.int64)
    for j in jumps.tolist():
        lli[j][has[j]] |= 1

    out_meta = dict(meta)
    out_meta["t_ns"] = np.asarray(rows.t_ns, np.int64)
    out_meta["glonass_channels"] = dict(sorted(rows.glo_channel.items()))
    out_meta["clock_discontinuity_epochs"] = jumps.tolist()
    out_meta["hardware_clock_discontinuity_count"] = cc
    out_meta["n_duplicates"] = n_dup
    return mask_impossible(
        ObsBatch(
            t_s=np.asarray(rows.t_s, float),
            tx_ids=tx_ids,
            system=tuple(t[0] for t in tx_ids),
            signals=signals,
            code_m=cube(code),
            phase_cyc=phase_c,
            doppler_hz=cube(doppler),
            cn0_dbhz=cube(arr(rows.cn0_dbhz)),
            lli=lli,
            wavelength_m=wl,
            receiver=receiver,
            approx_pos_m=approx_pos_m,
            meta=out_meta,
            code_sigma_m=cube(code_sig),
            phase_sigma_cyc=cube(phase_sig),
        )
    )
