"""Google Smartphone Decimeter Challenge ``device_gnss.csv`` files into an ObsBatch.

GSDC 2022/2023 ``device_gnss.csv`` holds one row per measurement: the Android
``GnssMeasurement`` fields (``TimeNanos``, ``FullBiasNanos``, ``Svid``, ``State``,
``ReceivedSvTimeNanos``, ``AccumulatedDeltaRange*``, ``CarrierFrequencyHz``, ``CodeType``,
...) plus Google's derived columns (``utcTimeMillis``, ``ArrivalTimeNanosSinceGpsEpoch``,
``RawPseudorangeMeters``, ``RawPseudorangeUncertaintyMeters``, ``SignalType``, satellite
states). The result is laid out exactly as :func:`robustrtk.io.gnsslogger.read_gnsslogger`
does (signals, phase, LLI, sigmas; see there), with these differences:

* epochs are the groups of rows with the same ``utcTimeMillis``; the tag ``t_s`` is
  ``TimeNanos - FullBiasNanos - BiasNanos`` when those are exact integers, else
  ``ArrivalTimeNanosSinceGpsEpoch`` (files saved with ``1.378E+018`` lose the last digits of
  the nanoseconds), else ``utcTimeMillis`` plus the leap seconds;
* ``code_m`` is Google's ``RawPseudorangeMeters``, kept where the ``State`` bits allow it
  (as for the GnssLogger reader). Those pseudoranges use the ``FullBiasNanos`` of the first
  epoch of the drive, so they carry the free-running hardware clock (the same clock as the
  ADR and the pseudorange rate; the receiver clock estimate absorbs it);
* ``code_sigma_m`` is ``RawPseudorangeUncertaintyMeters`` (else ``c *
  ReceivedSvTimeUncertaintyNanos``).

Malformed rows raise :class:`~robustrtk.core.InputError` with file, line and column.
"""

from __future__ import annotations

import csv
import math
import os
import re
from pathlib import Path

import numpy as np

from robustrtk.core import CLIGHT, InputError, ObsBatch
from robustrtk.io.android_raw import (
    AndroidRows,
    android_signal,
    batch_from_rows,
    code_usable,
    skip_reason,
    time_window,
    tx_id,
)
from robustrtk.io.rinex_file import check_regular_file
from robustrtk.timeutil import leap_seconds_at_utc

__all__ = ["GSDC_REQUIRED", "is_device_gnss", "read_device_gnss"]

#: Columns a ``device_gnss.csv`` must have.
GSDC_REQUIRED = ("utcTimeMillis", "Svid", "ConstellationType", "RawPseudorangeMeters")

_INT_RE = re.compile(r"^-?\d+$")
_NS = 1_000_000_000
#: Milliseconds from 1970-01-01 (Unix) to 1980-01-06 (GPS epoch), both UTC.
_UNIX_TO_GPS_MS = 315_964_800_000


def is_device_gnss(head: bytes) -> bool:
    """True when ``head`` starts with a ``device_gnss.csv`` header line."""
    first = head.split(b"\n", 1)[0].decode("utf-8", "replace")
    cols = {c.strip() for c in first.split(",")}
    return all(c in cols for c in GSDC_REQUIRED)


def _float(row: dict[str, str], name: str, path: str, line: int) -> float:
    t = (row.get(name) or "").strip()
    if not t:
        return math.nan
    try:
        v = float(t)
    except ValueError:
        raise InputError(f"column {name}: {t!r} is not a number", path, line) from None
    if math.isinf(v):
        raise InputError(f"column {name}: {t!r} is not a finite number", path, line)
    return v


def _int(row: dict[str, str], name: str, path: str, line: int, default: int | None = None) -> int:
    t = (row.get(name) or "").strip()
    if not t:
        if default is None:
            raise InputError(f"column {name} is empty; expected an integer", path, line)
        return default
    if _INT_RE.match(t):
        k = int(t)
        if not -(2**63) <= k < 2**63:
            raise InputError(f"column {name}: {t!r} does not fit a 64-bit integer", path, line)
        return k
    try:
        v = float(t)
    except ValueError:
        raise InputError(f"column {name}: {t!r} is not an integer", path, line) from None
    if not math.isfinite(v) or v != int(v) or abs(v) >= 2.0**53:
        raise InputError(f"column {name}: {t!r} is not an integer (exact, below 2**53)", path, line)
    return int(v)


def read_device_gnss(
    path: str | os.PathLike[str],
    *,
    systems: str | None = None,
    t_start_s: float | None = None,
    t_end_s: float | None = None,
) -> ObsBatch:
    """Read a GSDC ``device_gnss.csv``.

    Parameters
    ----------
    path : path-like
    systems : str, optional
        System letters to keep; all when None.
    t_start_s, t_end_s : float, optional
        Keep epochs with ``t_start_s <= t_s <= t_end_s`` (GPST s).

    Returns
    -------
    ObsBatch
        ``meta["format"] == "gsdc_device_gnss"``; ``approx_pos_m`` is the first finite
        ``WlsPosition*EcefMeters`` (Google's weighted least squares), if present.

    Raises
    ------
    InputError
        Missing columns, a non-numeric field, rows whose ``utcTimeMillis`` goes backwards.
    """
    p = os.fspath(path)
    check_regular_file(str(p))
    try:
        fh = open(p, newline="", encoding="utf-8", errors="replace")
    except FileNotFoundError:
        raise InputError("file not found", p) from None
    except OSError as exc:
        raise InputError(f"cannot read file ({exc.strerror})", p) from None
    rows = AndroidRows()
    rejected: dict[str, int] = {}
    skipped: dict[str, int] = {}
    approx: list[float] | None = None
    with fh:
        reader = csv.DictReader(fh)
        header = [c.strip() for c in (reader.fieldnames or [])]
        missing = [c for c in GSDC_REQUIRED if c not in header]
        if missing:
            raise InputError(
                f"header lacks column(s) {', '.join(missing)}; expected a GSDC device_gnss.csv", p, 1
            )
        reader.fieldnames = header
        ms_prev: int | None = None
        for r0, row in enumerate(reader):
            line = r0 + 2
            if None in row:  # more fields than the header
                raise InputError(f"row has more fields than the header's {len(header)}", p, line)
            if any(v is None for v in row.values()):
                raise InputError(f"row has fewer fields than the header's {len(header)}", p, line)
            if row.get("MessageType", "Raw").strip() not in ("Raw", ""):
                continue
            ms = _int(row, "utcTimeMillis", p, line)
            const = _int(row, "ConstellationType", p, line)
            svid = _int(row, "Svid", p, line)
            if ms != ms_prev:
                if ms_prev is not None and ms < ms_prev:
                    raise InputError(
                        f"utcTimeMillis {ms} is earlier than the previous row's {ms_prev}; expected "
                        "rows in time order",
                        p,
                        line,
                    )
                tn, fb = row.get("TimeNanos", "").strip(), row.get("FullBiasNanos", "").strip()
                bias = _float(row, "BiasNanos", p, line)
                bias = 0.0 if math.isnan(bias) else bias
                if _INT_RE.match(tn) and _INT_RE.match(fb):
                    t_int = int(tn) - int(fb)
                    sec, rem = divmod(t_int, _NS)
                    t_s = sec + (rem - bias) * 1e-9
                    t_ns = t_int - int(round(bias))
                else:
                    arr = _float(row, "ArrivalTimeNanosSinceGpsEpoch", p, line)
                    if math.isfinite(arr):
                        t_s, t_ns = arr * 1e-9, int(arr)
                    else:
                        t_utc = (ms - _UNIX_TO_GPS_MS) * 1e-3
                        t_s = t_utc + float(leap_seconds_at_utc(t_utc))
                        t_ns = int(round(t_s * _NS))
                if not (math.isfinite(t_s) and abs(t_ns) < 2**62):
                    raise InputError(
                        "TimeNanos/FullBiasNanos/ArrivalTimeNanosSinceGpsEpoch: epoch time out of range "
                        "(expected GPS nanoseconds of a calendar date)",
                        p,
                        line,
                    )
                if rows.t_s and t_s <= rows.t_s[-1]:
                    raise InputError(
                        f"epoch time {t_s:.9f} s does not increase; expected rows in time order", p, line
                    )
                rows.t_s.append(t_s)
                rows.t_ns.append(t_ns)
                rows.clock_count.append(_int(row, "HardwareClockDiscontinuityCount", p, line, 0))
                ms_prev = ms
            tid = tx_id(const, svid)
            if tid is None:
                skipped[skip_reason(const, svid)] = skipped.get(skip_reason(const, svid), 0) + 1
                continue
            if systems is not None and tid[0] not in systems:
                continue
            sig, ch = android_signal(
                tid[0], _float(row, "CarrierFrequencyHz", p, line), row.get("CodeType", "")
            )
            if sig is None:
                skipped["carrier frequency matches no band"] = (
                    skipped.get("carrier frequency matches no band", 0) + 1
                )
                continue
            if ch is not None:
                rows.glo_channel.setdefault(tid, ch)
            code = _float(row, "RawPseudorangeMeters", p, line)
            sigma = _float(row, "RawPseudorangeUncertaintyMeters", p, line)
            if math.isnan(sigma):
                sigma = _float(row, "ReceivedSvTimeUncertaintyNanos", p, line) * 1e-9 * CLIGHT
            state = _int(row, "State", p, line, -1)
            why = "" if state < 0 else code_usable(tid[0], state)
            if math.isnan(code):
                why = why or "no RawPseudorangeMeters"
            if why:
                rejected[why] = rejected.get(why, 0) + 1
                code = math.nan
            locked = state < 0 or code_usable(tid[0], state) != "no code lock"
            rows.epoch.append(len(rows.t_s) - 1)
            rows.tx.append(tid)
            rows.signal.append(sig)
            rows.code_m.append(code)
            rows.code_sigma_m.append(sigma)
            rows.adr_m.append(_float(row, "AccumulatedDeltaRangeMeters", p, line))
            rows.adr_sigma_m.append(_float(row, "AccumulatedDeltaRangeUncertaintyMeters", p, line))
            rows.adr_state.append(_int(row, "AccumulatedDeltaRangeState", p, line, 0))
            prr = _float(row, "PseudorangeRateMetersPerSecond", p, line)
            rows.prr_m_s.append(prr if locked else math.nan)
            rows.cn0_dbhz.append(_float(row, "Cn0DbHz", p, line))
            rows.line.append(line)
            if approx is None:
                xyz = [_float(row, f"WlsPosition{a}EcefMeters", p, line) for a in "XYZ"]
                if all(math.isfinite(x) for x in xyz):
                    approx = xyz
    meta: dict[str, object] = {
        "file": Path(p).name,
        "path": p,
        "format": "gsdc_device_gnss",
        "n_code_rejected": rejected,
        "rows_skipped": skipped,
        "time_system": "GPS",
    }
    batch = batch_from_rows(
        rows, meta, receiver="android", approx_pos_m=None if approx is None else np.asarray(approx)
    )
    return time_window(batch, t_start_s, t_end_s)
