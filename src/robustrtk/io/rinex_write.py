"""RINEX 3.04 observation files from an :class:`~robustrtk.core.ObsBatch`.

The header declares, per system, the types ``C L D S`` of each signal that holds data for
that system (code ``C1C``, phase ``L1C``, Doppler ``D1C``, C/N0 ``S1C``), in the batch's
signal order. Each epoch record (``>`` line, flag 0) lists the transmitters with any value;
values are written as ``F14.3`` (m, cycles, Hz, dB-Hz), absent ones as blanks. The
loss-of-lock digit of a phase is ``lli`` (bit 0 loss of lock, bit 1 half-cycle ambiguity);
it is left blank when 0. Values that do not fit ``F14.3`` are left blank and counted.

Time tags are written in GPS time with 7 decimals of a second (100 ns), so a round trip
through :func:`robustrtk.io.rinex_obs.read_rinex_obs` gives the same observations to the
resolution of the format (1 mm, 0.001 cycle, 0.001 Hz, 0.001 dB-Hz). GLONASS channels
(``GLONASS SLOT / FRQ #``) come from ``meta["glonass_channels"]`` or, failing that, from the
wavelengths. The file is written atomically.
"""

from __future__ import annotations

import math
import os
from datetime import UTC, datetime

import numpy as np

from robustrtk.core import CLIGHT, ObsBatch
from robustrtk.gnss import GLO_FDMA_HZ
from robustrtk.io.atomic import atomic_path
from robustrtk.timeutil import calendar_from_gpst
from robustrtk.version import __version__

__all__ = ["obs_types_by_system", "rinex_obs_text", "write_rinex_obs"]

_SYSTEM_ORDER = "GRECJSI"
_FIELDS = ("C", "L", "D", "S")
_MAX_F14 = 9_999_999_999.999


def _label(text: str, label: str) -> str:
    return f"{text:<60.60}{label:<20}"


def obs_types_by_system(batch: ObsBatch) -> dict[str, list[tuple[str, str, int]]]:
    """Observation types to write: system -> ``[(type, field, signal index), ...]``.

    ``type`` is the RINEX 3 code (``"C1C"``), ``field`` one of ``C L D S``; only types
    with at least one finite value on that system are listed.
    """
    arrays = {"C": batch.code_m, "L": batch.phase_cyc, "D": batch.doppler_hz, "S": batch.cn0_dbhz}
    sys_arr = np.asarray(batch.system)
    out: dict[str, list[tuple[str, str, int]]] = {}
    for s in sorted(set(batch.system), key=lambda x: _SYSTEM_ORDER.index(x) if x in _SYSTEM_ORDER else 99):
        if s not in _SYSTEM_ORDER:
            continue
        rows = np.flatnonzero(sys_arr == s)
        types = []
        for k, sig in enumerate(batch.signals):
            for f in _FIELDS:
                if np.isfinite(arrays[f][:, rows, k]).any():
                    types.append((f + sig, f, k))
        if types:
            out[s] = types
    return out


def _glo_channels(batch: ObsBatch) -> dict[str, int]:
    meta = batch.meta.get("glonass_channels")
    chans: dict[str, int] = {}
    if isinstance(meta, dict):
        chans.update({str(k): int(v) for k, v in meta.items() if v is not None})
    f0, df = GLO_FDMA_HZ["1"]
    for n, tid in enumerate(batch.tx_ids):
        if tid[0] != "R" or tid in chans:
            continue
        for k, sig in enumerate(batch.signals):
            wl = batch.wavelength_m[n, k]
            if sig[:1] == "1" and math.isfinite(wl):
                chans[tid] = int(round((CLIGHT / wl - f0) / df))
                break
    return dict(sorted(chans.items()))


def _calendar(batch: ObsBatch, i: int) -> tuple[int, int, int, int, int, float]:
    """Calendar GPST of epoch ``i`` to 100 ns: from ``meta["t_ns"]`` when the batch says
    those are its exact tags (``meta["t_ns_exact"]``, binary decoders; a float ``t_s`` of
    ~1e9 s resolves only ~0.2 us), else from ``t_s``."""
    t_ns = batch.meta.get("t_ns")
    if batch.meta.get("t_ns_exact") and isinstance(t_ns, np.ndarray) and t_ns.shape == batch.t_s.shape:
        ticks = (int(t_ns[i]) + 50) // 100  # 100 ns units, rounded
        y, mo, d, h, mi, s = calendar_from_gpst(float(ticks // 10_000_000))
        return y, mo, d, h, mi, s + (ticks % 10_000_000) * 1e-7
    return calendar_from_gpst(round(float(batch.t_s[i]) * 1e7) / 1e7)


def _time_line(batch: ObsBatch, i: int, label: str) -> str:
    y, mo, d, h, mi, s = _calendar(batch, i)
    return _label(f"{y:6d}{mo:6d}{d:6d}{h:6d}{mi:6d}{s:13.7f}     GPS", label)


def _header(batch: ObsBatch, types: dict[str, list[tuple[str, str, int]]], keep: list[int]) -> list[str]:
    now = datetime.now(UTC).strftime("%Y%m%d %H%M%S UTC")
    systems = list(types)
    file_sys = systems[0] if len(systems) == 1 else "M"
    lines = [
        _label(f"{'3.04':>9}{'':11}{'OBSERVATION DATA':<20}{file_sys:<20}", "RINEX VERSION / TYPE"),
        _label(f"{'robustrtk ' + __version__:<20}{'':<20}{now:<20}", "PGM / RUN BY / DATE"),
    ]
    src = batch.meta.get("file")
    if src:
        lines.append(_label(f"converted from {src}", "COMMENT"))
    lines += [
        _label(batch.receiver or "UNKNOWN", "MARKER NAME"),
        _label("NON_GEODETIC", "MARKER TYPE"),
        _label(f"{'':<20}{'':<40}", "OBSERVER / AGENCY"),
        _label(
            f"{'':<20}{str(batch.meta.get('receiver_type', '') or ''):<20}{'':<20}", "REC # / TYPE / VERS"
        ),
        _label(f"{'':<20}{str(batch.meta.get('antenna_type', '') or ''):<20}", "ANT # / TYPE"),
    ]
    pos = batch.approx_pos_m
    xyz = (0.0, 0.0, 0.0) if pos is None or not np.all(np.isfinite(pos)) else tuple(float(x) for x in pos)
    lines.append(_label("".join(f"{x:14.4f}" for x in xyz), "APPROX POSITION XYZ"))
    lines.append(_label(f"{0.0:14.4f}{0.0:14.4f}{0.0:14.4f}", "ANTENNA: DELTA H/E/N"))
    for s, tl in types.items():
        codes = [c for c, _, _ in tl]
        for i in range(0, len(codes), 13):
            chunk = " ".join(f"{c:3}" for c in codes[i : i + 13])
            head = f"{s:1}  {len(codes):3d}" if i == 0 else " " * 6
            lines.append(_label(f"{head} {chunk}", "SYS / # / OBS TYPES"))
    if "R" in types:
        chans = _glo_channels(batch)
        items = list(chans.items())
        if not items:
            lines.append(_label(f"{0:3d}", "GLONASS SLOT / FRQ #"))
        for i in range(0, len(items), 8):
            head = f"{len(items):3d} " if i == 0 else " " * 4
            body = "".join(f"{tid} {ch:2d} " for tid, ch in items[i : i + 8])
            lines.append(_label(head + body, "GLONASS SLOT / FRQ #"))
    for s in types:
        lines.append(_label(f"{s}", "SYS / PHASE SHIFT"))
    if "R" in types:
        lines.append(_label("", "GLONASS COD/PHS/BIS"))
    if len(keep) > 1:
        dt = np.diff(batch.t_s[keep])
        lines.append(_label(f"{float(np.median(dt)):10.3f}", "INTERVAL"))
    if keep:
        lines.append(_time_line(batch, keep[0], "TIME OF FIRST OBS"))
        lines.append(_time_line(batch, keep[-1], "TIME OF LAST OBS"))
    lines.append(_label("", "END OF HEADER"))
    return lines


def _f14(v: float) -> str | None:
    if not math.isfinite(v) or abs(v) > _MAX_F14:
        return None
    return f"{v:14.3f}"


def rinex_obs_text(batch: ObsBatch) -> tuple[str, dict[str, int]]:
    """RINEX 3.04 observation text of ``batch`` and counts (``epochs``, ``records``,
    ``values``, ``values_not_fitting``)."""
    types = obs_types_by_system(batch)
    arrays = {"C": batch.code_m, "L": batch.phase_cyc, "D": batch.doppler_hz, "S": batch.cn0_dbhz}
    tx_order = sorted(
        (n for n, t in enumerate(batch.tx_ids) if t[0] in types),
        key=lambda n: (_SYSTEM_ORDER.index(batch.tx_ids[n][0]), batch.tx_ids[n]),
    )
    body: list[str] = []
    keep: list[int] = []
    n_rec = n_val = n_bad = 0
    for i in range(len(batch)):
        recs: list[str] = []
        for n in tx_order:
            tid = batch.tx_ids[n]
            parts = [tid]
            any_val = False
            for _, f, k in types[tid[0]]:
                v = float(arrays[f][i, n, k])
                txt = _f14(v)
                if txt is None:
                    if math.isfinite(v):
                        n_bad += 1
                    parts.append(" " * 16)
                    continue
                any_val = True
                n_val += 1
                lli = int(batch.lli[i, n, k]) & 7 if f == "L" else 0
                parts.append(txt + (str(lli) if lli else " ") + " ")
            if any_val:
                recs.append("".join(parts).rstrip())
        if not recs:
            continue
        keep.append(i)
        y, mo, d, h, mi, s = _calendar(batch, i)
        body.append(f"> {y:4d} {mo:02d} {d:02d} {h:02d} {mi:02d}{s:11.7f}  0{len(recs):3d}")
        body.extend(recs)
        n_rec += len(recs)
    lines = _header(batch, types, keep) + body
    stats = {"epochs": len(keep), "records": n_rec, "values": n_val, "values_not_fitting": n_bad}
    return "\n".join(lines) + "\n", stats


def write_rinex_obs(batch: ObsBatch, path: str | os.PathLike[str]) -> dict[str, int]:
    """Write ``batch`` as a RINEX 3.04 observation file (atomically).

    Parameters
    ----------
    batch : ObsBatch
        Observations (GNSS systems ``G R E C J S I``; other rows are not written).
    path : path-like
        Output file (plain text).

    Returns
    -------
    dict
        Counts: ``epochs``, ``records`` (satellite lines), ``values`` and
        ``values_not_fitting`` (finite values too large for ``F14.3``, left blank).

    Raises
    ------
    InputError
        The output directory does not exist.
    """
    text, stats = rinex_obs_text(batch)
    with atomic_path(path) as tmp:
        with open(tmp, "w", encoding="ascii", newline="\n") as fh:
            fh.write(text)
    return stats
