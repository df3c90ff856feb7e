"""Android GnssLogger text logs (``Raw`` rows of ``GnssMeasurement`` fields) into an ObsBatch.

A GnssLogger text log has comment lines ``# Raw,<column names>`` (and ``# Fix,...``) that
name the columns, then one ``Raw,...`` row per measurement. Rows of one ``GnssClock``
callback share ``TimeNanos``; they form one epoch. The measurement model (time tags,
pseudoranges, phases, signals) is :mod:`robustrtk.io.android_raw`'s; its public names are
importable from here too.

``Fix`` rows give ``approx_pos_m`` (ECEF of the median fix) and ``meta["fixes"]``.
Malformed rows raise :class:`~robustrtk.core.InputError` naming file, line and field.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from pathlib import Path

import numpy as np

from robustrtk.core import CLIGHT, FloatArray, InputError, ObsBatch
from robustrtk.geometry.frames import geodetic2ecef_deg
from robustrtk.io.android_raw import (
    ADR_STATE,
    CODE_LOCKS,
    CONSTELLATIONS,
    DEFAULT_ATTRIBUTE,
    NS_PER_S,
    RANGE_MAX_M,
    RANGE_MIN_M,
    STATE,
    AndroidRows,
    android_signal,
    batch_from_rows,
    code_usable,
    pseudorange_m,
    skip_reason,
    time_window,
    tx_id,
)
from robustrtk.io.rinex_file import check_regular_file

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

_REQUIRED = (
    "TimeNanos",
    "FullBiasNanos",
    "Svid",
    "State",
    "ReceivedSvTimeNanos",
    "ConstellationType",
)
_INT_COLUMNS = frozenset({*_REQUIRED, "AccumulatedDeltaRangeState", "HardwareClockDiscontinuityCount"})


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
            sec, rem = divmod(t_int, NS_PER_S)
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
            if not RANGE_MIN_M <= code <= RANGE_MAX_M:
                why, code = "pseudorange outside 1,000-100,000 km", math.nan
        if why:
            count(rejected, why)
        locked = bool(state & CODE_LOCKS)

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
    return time_window(batch, t_start_s, t_end_s)


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
