"""Android GnssLogger logs (``Raw`` rows of ``GnssMeasurement`` fields) into an ObsBatch.

A GnssLogger text log has comment lines ``# Raw,<column names>`` (and ``# Fix,...``) that
name the columns, then one ``Raw,...`` row per measurement. Rows of one ``GnssClock``
callback share ``TimeNanos``; they form one epoch.

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

``Fix`` rows give ``approx_pos_m`` (ECEF of the median fix) and ``meta["fixes"]``.
Malformed rows raise :class:`~robustrtk.core.InputError` naming file, line and field.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from robustrtk.core import CLIGHT, FloatArray, InputError, ObsBatch
from robustrtk.geometry.frames import geodetic2ecef_deg
from robustrtk.gnss import FREQ_HZ, GLO_FDMA_HZ, wavelength_m
from robustrtk.io.obs_checks import mask_impossible
from robustrtk.io.rinex_file import check_regular_file
from robustrtk.timeutil import BDT_GPST_OFFSET_S, DAY_S, GLONASS_UTC_OFFSET_S, WEEK_S, leap_seconds_at_gpst

__all__ = [
    "ADR_STATE",
    "CONSTELLATIONS",
    "DEFAULT_ATTRIBUTE",
    "STATE",
    "AndroidRows",
    "android_signal",
    "batch_from_rows",
    "code_usable",
    "is_gnsslogger",
    "pseudorange_m",
    "read_gnsslogger",
    "skip_reason",
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

_NS = 1_000_000_000
_WEEK_NS = int(WEEK_S) * _NS
_DAY_NS = int(DAY_S) * _NS
_CODE_LOCKS = STATE["CODE_LOCK"] | STATE["GAL_E1BC_CODE_LOCK"] | STATE["2ND_CODE_LOCK"]
_TOW = STATE["TOW_DECODED"] | STATE["TOW_KNOWN"]
_TOD = STATE["GLO_TOD_DECODED"] | STATE["GLO_TOD_KNOWN"]
#: Plausible pseudorange range (m).
_RANGE_MIN_M, _RANGE_MAX_M = 1.0e6, 1.0e8

_REQUIRED = (
    "TimeNanos",
    "FullBiasNanos",
    "Svid",
    "State",
    "ReceivedSvTimeNanos",
    "ConstellationType",
)
_INT_COLUMNS = frozenset(
    {
        "TimeNanos",
        "FullBiasNanos",
        "Svid",
        "State",
        "ReceivedSvTimeNanos",
        "ConstellationType",
        "AccumulatedDeltaRangeState",
        "HardwareClockDiscontinuityCount",
    }
)


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
    if not state & _CODE_LOCKS:
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
            leap_s = float(leap_seconds_at_gpst(t_int / _NS))
        period = _DAY_NS
        t_rx = t_int + int(GLONASS_UTC_OFFSET_S) * _NS - int(round(leap_s)) * _NS
    else:
        period = _WEEK_NS
        t_rx = t_int - (int(BDT_GPST_OFFSET_S) * _NS if system == "C" else 0)
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


def _time_window(batch: ObsBatch, t_start_s: float | None, t_end_s: float | None) -> ObsBatch:
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


# --------------------------------------------------------------------------------------------
# text log


def is_gnsslogger(head: bytes) -> bool:
    """True when ``head`` looks like a GnssLogger log (a ``# Raw,`` header or ``Raw,`` row)."""
    try:
        text = head.decode("utf-8", "replace")
    except Exception:  # pragma: no cover - decode with replace does not raise
        return False
    for ln in text.split("\n")[:400]:
        s = ln.strip()
        if s.startswith("#"):
            body = s.lstrip("#").strip()
            if body.startswith("Raw,") and "ReceivedSvTimeNanos" in body:
                return True
        elif s.startswith("Raw,"):
            return False  # rows before any header
    return False


def _columns(body: str) -> list[str]:
    return [c.strip() for c in body.split(",")]


def _num(text: str, name: str, integer: bool, path: str, line: int) -> float | int | None:
    t = text.strip()
    if not t:
        return None
    if integer:
        try:
            k = int(t)
        except ValueError:
            pass
        else:
            if -(2**63) <= k < 2**63:
                return k
            raise InputError(f"Raw row field {name}: {t!r} does not fit a 64-bit integer", path, line)
    try:
        v = float(t)
    except ValueError:
        kind = "an integer" if integer else "a number"
        raise InputError(f"Raw row field {name}: {t!r} is not {kind}", path, line) from None
    if not math.isfinite(v):
        raise InputError(f"Raw row field {name}: {t!r} is not a finite number", path, line)
    if integer:
        if not math.isfinite(v) or v != int(v):
            raise InputError(f"Raw row field {name}: {t!r} is not an integer", path, line)
        if abs(v) >= 2.0**53:
            raise InputError(
                f"Raw row field {name}: {t!r} has lost digits (exponent notation); expected "
                "the exact integer nanoseconds",
                path,
                line,
            )
        return int(v)
    return v


def _getter(v: dict[str, float | int | None]) -> Callable[[str], float]:
    def flt(name: str) -> float:
        x = v.get(name)
        return math.nan if x is None else float(x)

    return flt


def _fix_position(fixes: list[tuple[float, float, float]]) -> FloatArray | None:
    if not fixes:
        return None
    a = np.asarray(fixes, float)
    lat, lon, h = np.median(a, axis=0)
    return np.asarray(geodetic2ecef_deg(lat, lon, h), float).reshape(3)


def read_gnsslogger(
    path: str | os.PathLike[str],
    *,
    systems: str | None = None,
    t_start_s: float | None = None,
    t_end_s: float | None = None,
    max_sv_time_unc_ns: float = 500.0,
    clock: str = "epoch",
) -> ObsBatch:
    """Read an Android GnssLogger text log.

    Parameters
    ----------
    path : path-like
        GnssLogger ``.txt`` log (``# Raw,...`` header and ``Raw,...`` rows).
    systems : str, optional
        System letters to keep (``"GE"``); all read systems when None.
    t_start_s, t_end_s : float, optional
        Keep epochs with ``t_start_s <= t_s <= t_end_s`` (GPST s).
    max_sv_time_unc_ns : float
        Codes with ``ReceivedSvTimeUncertaintyNanos`` above this (ns) are rejected.
    clock : {"epoch", "first"}
        ``"epoch"``: pseudoranges use each epoch's ``FullBiasNanos + BiasNanos`` (the
        receiver's steered clock, as the time tags). ``"first"``: they use those of the
        first epoch after each hardware-clock discontinuity, so code, ADR and pseudorange
        rate share the free-running hardware clock (the convention of GSDC's
        ``RawPseudorangeMeters``); the tags are the same in both cases.

    Returns
    -------
    ObsBatch
        See the module docstring; ``meta["format"] == "gnsslogger"``.

    Raises
    ------
    InputError
        No ``# Raw`` header, a row with the wrong number of fields, a non-numeric field,
        a missing required field or an epoch time that goes backwards.
    """
    p = os.fspath(path)
    if clock not in ("epoch", "first"):
        raise InputError(f"clock: expected 'epoch' or 'first', got {clock!r}")
    check_regular_file(str(p))
    try:
        with open(p, encoding="utf-8", errors="replace") as fh:
            lines = fh.read().replace("\r", "").split("\n")
    except FileNotFoundError:
        raise InputError("file not found", p) from None
    except OSError as exc:
        raise InputError(f"cannot read file ({exc.strerror})", p) from None

    cols: list[str] | None = None
    fix_cols: list[str] | None = None
    rows = AndroidRows()
    fixes: list[tuple[float, float, float]] = []
    rejected: dict[str, int] = {}
    skipped: dict[str, int] = {}
    version = ""
    key_prev: tuple[int, int] | None = None
    t_prev: float | None = None
    ref: tuple[int, float, int] | None = None  # (FullBiasNanos, BiasNanos, clock count)

    def count(d: dict[str, int], why: str) -> None:
        d[why] = d.get(why, 0) + 1

    for ln0, raw in enumerate(lines):
        lineno = ln0 + 1
        s = raw.strip()
        if not s:
            continue
        if s.startswith("#"):
            body = s.lstrip("#").strip()
            if body.startswith("Raw,"):
                cols = _columns(body)
                missing = [c for c in _REQUIRED if c not in cols]
                if missing:
                    raise InputError(
                        f"'# Raw' header lacks column(s) {', '.join(missing)}; expected the "
                        "GnssMeasurement fields",
                        p,
                        lineno,
                    )
            elif body.startswith("Fix,"):
                fix_cols = _columns(body)
            elif body.startswith("Version:"):
                version = body[len("Version:") :].strip()
            continue
        kind = s.split(",", 1)[0]
        if kind == "Fix" and fix_cols is not None:
            f = s.split(",")
            d = dict(zip(fix_cols, f, strict=False))
            try:
                lat = float(d.get("LatitudeDegrees", d.get("Latitude", "nan")))
                lon = float(d.get("LongitudeDegrees", d.get("Longitude", "nan")))
                alt = float(d.get("AltitudeMeters", d.get("Altitude", "nan")) or "nan")
            except ValueError:
                continue  # fixes are advisory
            if math.isfinite(lat) and math.isfinite(lon) and math.isfinite(alt):
                fixes.append((lat, lon, alt))
            continue
        if kind != "Raw":
            continue
        if cols is None:
            raise InputError(
                "Raw row before any '# Raw,...' header line; expected a GnssLogger log", p, lineno
            )
        f = s.split(",")
        if len(f) != len(cols):
            raise InputError(f"Raw row has {len(f)} fields, the '# Raw' header names {len(cols)}", p, lineno)
        v: dict[str, float | int | None] = {}
        for name, text in zip(cols[1:], f[1:], strict=True):
            if name in _INT_COLUMNS or name in _FLOAT_COLUMNS:
                v[name] = _num(text, name, name in _INT_COLUMNS, p, lineno)
        for name in ("TimeNanos", "Svid", "State", "ReceivedSvTimeNanos", "ConstellationType"):
            if v.get(name) is None:
                raise InputError(f"Raw row field {name} is empty; expected an integer", p, lineno)
        if v.get("FullBiasNanos") is None:
            count(skipped, "no FullBiasNanos (no GPS time)")
            continue
        tid = tx_id(int(v["ConstellationType"] or 0), int(v["Svid"] or 0))
        if tid is None:
            count(skipped, skip_reason(int(v["ConstellationType"] or 0), int(v["Svid"] or 0)))
            continue
        sys_ = tid[0]
        if systems is not None and sys_ not in systems:
            continue
        code_type = ""
        if "CodeType" in cols:
            code_type = f[cols.index("CodeType")].strip()
        fc = v.get("CarrierFrequencyHz")
        sig, ch = android_signal(sys_, None if fc is None else float(fc), code_type)
        if sig is None:
            count(skipped, f"carrier frequency {fc} Hz of {tid} matches no band")
            continue
        if ch is not None:
            rows.glo_channel.setdefault(tid, ch)

        time_nanos = int(v["TimeNanos"] or 0)
        full_bias = int(v["FullBiasNanos"] or 0)
        bias = float(v.get("BiasNanos") or 0.0)
        clock_count = int(v.get("HardwareClockDiscontinuityCount") or 0)
        if not abs(bias) < 1e9 or not abs(time_nanos - full_bias) < 2**62:
            raise InputError(
                "TimeNanos - FullBiasNanos - BiasNanos out of range; expected GPS time in nanoseconds "
                "(BiasNanos below one second)",
                p,
                lineno,
            )
        key = (time_nanos, clock_count)
        if key != key_prev:
            t_int = time_nanos - full_bias
            sec, rem = divmod(t_int, _NS)
            t_s = sec + (rem - bias) * 1e-9
            if t_prev is not None and t_s <= t_prev:
                raise InputError(
                    f"epoch time {t_s:.9f} s (TimeNanos - FullBiasNanos - BiasNanos) does not "
                    f"increase (previous {t_prev:.9f} s); expected rows in time order",
                    p,
                    lineno,
                )
            rows.t_s.append(t_s)
            rows.t_ns.append(t_int - int(round(bias)))
            rows.clock_count.append(clock_count)
            key_prev, t_prev = key, t_s
            if clock == "epoch" or ref is None or ref[2] != clock_count:
                ref = (full_bias, bias, clock_count)
        epoch_i = len(rows.t_s) - 1

        state = int(v["State"] or 0)
        why = code_usable(sys_, state)
        unc = v.get("ReceivedSvTimeUncertaintyNanos")
        unc_ns = math.nan if unc is None else float(unc)
        code = math.nan
        if not why and unc_ns == unc_ns and unc_ns > max_sv_time_unc_ns:
            why = f"ReceivedSvTimeUncertaintyNanos above {max_sv_time_unc_ns:g}"
        if not why:
            leap = v.get("LeapSecond")
            assert ref is not None
            code = pseudorange_m(
                sys_,
                time_nanos,
                ref[0],
                ref[1],
                float(v.get("TimeOffsetNanos") or 0.0),
                int(v["ReceivedSvTimeNanos"] or 0),
                None if leap is None else float(leap),
            )
            if not _RANGE_MIN_M <= code <= _RANGE_MAX_M:
                why, code = "pseudorange outside 1,000-100,000 km", math.nan
        if why:
            count(rejected, why)
        locked = bool(state & _CODE_LOCKS)

        flt = _getter(v)

        rows.epoch.append(epoch_i)
        rows.tx.append(tid)
        rows.signal.append(sig)
        rows.code_m.append(code)
        rows.code_sigma_m.append(unc_ns * 1e-9 * CLIGHT)
        rows.adr_m.append(flt("AccumulatedDeltaRangeMeters"))
        rows.adr_sigma_m.append(flt("AccumulatedDeltaRangeUncertaintyMeters"))
        rows.adr_state.append(int(v.get("AccumulatedDeltaRangeState") or 0))
        rows.prr_m_s.append(flt("PseudorangeRateMetersPerSecond") if locked else math.nan)
        rows.cn0_dbhz.append(flt("Cn0DbHz"))
        rows.line.append(lineno)

    if cols is None:
        raise InputError("no '# Raw,...' header line; expected an Android GnssLogger log", p)
    meta: dict[str, object] = {
        "file": Path(p).name,
        "path": p,
        "format": "gnsslogger",
        "logger_version": version,
        "n_code_rejected": rejected,
        "rows_skipped": skipped,
        "fixes": len(fixes),
        "time_system": "GPS",
    }
    batch = batch_from_rows(rows, meta, receiver="android", approx_pos_m=_fix_position(fixes))
    return _time_window(batch, t_start_s, t_end_s)


_FLOAT_COLUMNS = frozenset(
    {
        "BiasNanos",
        "TimeOffsetNanos",
        "ReceivedSvTimeUncertaintyNanos",
        "Cn0DbHz",
        "PseudorangeRateMetersPerSecond",
        "AccumulatedDeltaRangeMeters",
        "AccumulatedDeltaRangeUncertaintyMeters",
        "CarrierFrequencyHz",
        "LeapSecond",
    }
)
