"""What is in an observation batch or a navigation file: summary dicts and their text
(``robustrtk info``).

Definitions
-----------
* A transmitter is *seen* in an epoch when any of its cells has a finite code or phase.
* ``interval_s`` is the median of the epoch time differences; ``n_gaps`` counts differences
  larger than 1.5 intervals.
* ``phase_fraction`` = (cells with a finite phase) / (cells with a finite code or phase),
  overall and per system: how much of what is tracked also has carrier phase.
* Navigation files: records read and skipped per kind (``EPH G LNAV``, ``ION E IFNV`` ...),
  satellites with ephemerides per system, and the time span of the ephemeris reference
  epochs (``toc``/``tb``, GPST).
"""

from __future__ import annotations

import math
import os
from typing import Any

import numpy as np
import numpy.typing as npt

from robustrtk.core import ObsBatch
from robustrtk.geometry.navdata import KEPLER_SYSTEMS, NavData
from robustrtk.gnss import SYSTEMS
from robustrtk.io.readers import detect_format, read_observations
from robustrtk.io.rinex_nav import read_rinex_nav
from robustrtk.timeutil import gpst_text

__all__ = [
    "format_nav_summary",
    "format_summary",
    "summarize",
    "summarize_file",
    "summarize_nav",
    "summarize_nav_file",
]


def _gpst_text(t_s: float) -> str:
    return gpst_text(t_s, 6, date_sep="-", trim_zero_fraction=False) + " GPST"


def summarize(batch: ObsBatch) -> dict[str, Any]:
    """Summary statistics of ``batch``.

    Parameters
    ----------
    batch : ObsBatch
        Observations, shape ``(T, N, K)``.

    Returns
    -------
    dict
        ``epochs`` (T), ``t_start_s``, ``t_end_s``, ``duration_s``, ``start``/``end``
        (calendar text, GPST), ``interval_s`` (median step), ``n_gaps``,
        ``systems`` {letter: satellites seen}, ``signals`` {letter: signals with any data},
        ``sats_per_epoch`` {``min``, ``median``, ``max``}, ``phase_fraction`` (float) and
        ``phase_fraction_by_system`` {letter: float}, plus ``receiver``, ``file``,
        ``rinex_version``, ``receiver_type``, ``approx_pos_m`` when known,
        ``decode_counts`` (frames decoded and skipped by kind) for UBX and RTCM 3 logs, and
        ``read_notes`` (the reader's sentences on the oddities it tolerated; may be empty).
        Fractions are NaN when nothing is tracked.
    """
    T = len(batch)
    t = np.asarray(batch.t_s, dtype=float)
    has_code = np.isfinite(batch.code_m)
    has_phase = np.isfinite(batch.phase_cyc)
    tracked: npt.NDArray[np.bool_] = has_code | has_phase  # (T, N, K)
    seen = np.asarray(tracked.any(axis=2), dtype=bool)  # (T, N)
    dt = np.diff(t)
    interval = float(np.median(dt)) if dt.size else math.nan
    n_gaps = int(np.count_nonzero(dt > 1.5 * interval)) if dt.size else 0
    system = np.asarray(batch.system)
    systems: dict[str, int] = {}
    signals: dict[str, list[str]] = {}
    frac_sys: dict[str, float] = {}
    for s in dict.fromkeys(batch.system):
        rows = system == s
        any_t = seen[:, rows].any(axis=0)
        n_seen = int(np.count_nonzero(any_t))
        if n_seen == 0:
            continue
        systems[s] = n_seen
        sig_any: list[bool] = np.asarray(tracked[:, rows].any(axis=(0, 1))).tolist()
        signals[s] = [sig for sig, a in zip(batch.signals, sig_any, strict=True) if a]
        n_tr = int(np.count_nonzero(tracked[:, rows]))
        frac_sys[s] = int(np.count_nonzero(has_phase[:, rows])) / n_tr
    n_tracked = int(np.count_nonzero(tracked))
    per_epoch = seen.sum(axis=1)
    out: dict[str, Any] = {
        "file": batch.meta.get("file", ""),
        "receiver": batch.receiver,
        "receiver_type": batch.meta.get("receiver_type", ""),
        "rinex_version": batch.meta.get("rinex_version"),
        "approx_pos_m": None if batch.approx_pos_m is None else list(map(float, batch.approx_pos_m)),
        "epochs": T,
        "t_start_s": float(t[0]) if T else math.nan,
        "t_end_s": float(t[-1]) if T else math.nan,
        "duration_s": float(t[-1] - t[0]) if T else 0.0,
        "start": _gpst_text(float(t[0])) if T else "",
        "end": _gpst_text(float(t[-1])) if T else "",
        "interval_s": interval,
        "n_gaps": n_gaps,
        "systems": systems,
        "signals": signals,
        "sats_per_epoch": {
            "min": int(per_epoch.min()) if T else 0,
            "median": float(np.median(per_epoch)) if T else math.nan,
            "max": int(per_epoch.max()) if T else 0,
        },
        "phase_fraction": int(np.count_nonzero(has_phase)) / n_tracked if n_tracked else math.nan,
        "phase_fraction_by_system": frac_sys,
    }
    counts = batch.meta.get("decode_counts")
    if isinstance(counts, dict):
        out["decode_counts"] = dict(counts)
    notes = batch.meta.get("read_notes")
    out["read_notes"] = [str(n) for n in notes] if isinstance(notes, list) else []
    return out


def summarize_file(path: str | os.PathLike[str], **kw: Any) -> dict[str, Any]:
    """:func:`summarize` of the observations of a file of any format
    :func:`robustrtk.io.readers.read_observations` reads (detected from the content).

    Parameters
    ----------
    path : path-like
    **kw
        Passed to the reader (e.g. ``systems="GE"`` for RINEX, ``receiver="rover"`` for a
        pseudolite observation table).

    Returns
    -------
    dict
        The :func:`summarize` keys plus ``format`` (the detected format name).

    Raises
    ------
    InputError
        Unrecognised content or a file without observations (names the file and the
        formats expected).
    """
    fmt = detect_format(path)
    out = summarize(read_observations(path, **kw))
    out["format"] = fmt
    if not out.get("file"):
        out["file"] = os.path.basename(os.fspath(path))
    return out


def format_summary(summary: dict[str, Any]) -> str:
    """Readable multi-line text of a :func:`summarize` result."""
    s = summary
    lines = []
    name = s.get("file") or "(observations)"
    lines.append(f"{name}")
    meta = []
    if s.get("rinex_version") is not None:
        meta.append(f"RINEX {s['rinex_version']:.2f}")
    if s.get("receiver"):
        meta.append(f"marker {s['receiver']}")
    if s.get("receiver_type"):
        meta.append(f"receiver {s['receiver_type']}")
    if meta:
        lines.append("  " + ", ".join(meta))
    for note in s.get("read_notes", []):
        lines.append(f"  note: {note}")
    if s.get("approx_pos_m") is not None:
        x, y, z = s["approx_pos_m"]
        lines.append(f"  approx position (ECEF m): {x:.4f} {y:.4f} {z:.4f}")
    lines.append(f"  epochs      {s['epochs']}")
    if s["epochs"]:
        lines.append(f"  start       {s['start']}  (t = {s['t_start_s']:.3f} s)")
        lines.append(f"  end         {s['end']}  (t = {s['t_end_s']:.3f} s)")
        lines.append(f"  duration    {s['duration_s']:.3f} s")
        lines.append(f"  interval    {s['interval_s']:.3f} s, {s['n_gaps']} gap(s)")
        spe = s["sats_per_epoch"]
        lines.append(f"  sats/epoch  min {spe['min']}  median {spe['median']:g}  max {spe['max']}")
        lines.append(f"  with phase  {100 * s['phase_fraction']:.1f} % of tracked cells")
    dc = s.get("decode_counts")
    if dc:
        framing = ("bad_checksum", "bad_crc", "bad_length", "skipped_bytes", "truncated")
        bad = ", ".join(f"{k} {dc[k]}" for k in framing if dc.get(k))
        lines.append(f"  frames      {dc.get('frames', 0)} valid" + (f"; {bad}" if bad else ""))
        msgs = {k: v for k, v in dc.items() if k != "frames" and k not in framing and v}
        if msgs:
            lines.append("  messages    " + ", ".join(f"{k} {v}" for k, v in sorted(msgs.items())))
    lines.append("")
    head = f"  {'system':<10} {'sats':>4} {'phase %':>8}  signals"
    lines.append(head)
    lines.append("  " + "-" * (len(head) - 2))
    for sys_letter, n in s["systems"].items():
        name = SYSTEMS.get(sys_letter, sys_letter)
        frac = s["phase_fraction_by_system"].get(sys_letter, math.nan)
        sigs = " ".join(s["signals"].get(sys_letter, []))
        lines.append(f"  {name:<10} {n:>4} {100 * frac:>8.1f}  {sigs}")
    return "\n".join(lines)


def _ephemeris_epochs(nav: NavData, system: str) -> tuple[np.ndarray, np.ndarray]:
    """Satellite ids and reference epochs (GPST s) of the ephemerides of ``system``."""
    if system == "R":
        return nav.glonass.sat_id, nav.glonass.toe_s
    if system == "S":
        return nav.sbas.sat_id, nav.sbas.toe_s
    k = nav.kepler[system]
    return k.sat_id, k.toc_s


def summarize_nav(nav: NavData, systems: str | None = None) -> dict[str, Any]:
    """Summary of broadcast navigation data.

    Parameters
    ----------
    nav : NavData
    systems : str, optional
        System letters to report (default: all).

    Returns
    -------
    dict
        ``files``, ``versions``, ``records`` {kind: count read}, ``skipped`` {kind: count},
        ``satellites`` {letter: satellites with ephemerides}, ``ephemerides`` {letter:
        records}, ``t_start_s``/``t_end_s`` (earliest and latest ephemeris reference epoch,
        GPST s; NaN without ephemerides), ``start``/``end`` (calendar text), ``iono`` (list
        of ``"model (satellite message)"``), ``leap_s``.
    """
    keep = systems.upper() if systems else None

    def wanted(kind: str) -> bool:
        return keep is None or kind.split()[1] in keep

    sats: dict[str, int] = {}
    recs: dict[str, int] = {}
    times = []
    for s in (*KEPLER_SYSTEMS, "R", "S"):
        if keep is not None and s not in keep:
            continue
        ids, t = _ephemeris_epochs(nav, s)
        if len(ids):
            sats[s] = len(set(ids.tolist()))
            recs[s] = len(ids)
            times.append(np.asarray(t, dtype=float))
    t_all = np.concatenate(times) if times else np.zeros(0)
    t0 = float(t_all.min()) if t_all.size else math.nan
    t1 = float(t_all.max()) if t_all.size else math.nan
    iono = [
        f"{m.model} ({m.sat_id} {m.message})" for m in nav.iono_models if keep is None or m.sat_id[0] in keep
    ]
    return {
        "files": [os.path.basename(f) for f in nav.files],
        "versions": list(nav.versions),
        "records": {k: v for k, v in nav.record_counts.items() if wanted(k)},
        "skipped": {k: v for k, v in nav.skipped_records.items() if wanted(k)},
        "satellites": sats,
        "ephemerides": recs,
        "t_start_s": t0,
        "t_end_s": t1,
        "start": _gpst_text(t0) if t_all.size else "",
        "end": _gpst_text(t1) if t_all.size else "",
        "iono": iono,
        "leap_s": nav.leap_s,
    }


def summarize_nav_file(path: str | os.PathLike[str], systems: str | None = None) -> dict[str, Any]:
    """:func:`summarize_nav` of a RINEX 2, 3 or 4 navigation file (plain or gzip).

    Raises
    ------
    InputError
        Unreadable or malformed file (names the file and line).
    """
    return summarize_nav(read_rinex_nav(path), systems)


def format_nav_summary(summary: dict[str, Any]) -> str:
    """Readable multi-line text of a :func:`summarize_nav` result."""
    s = summary
    versions = ", ".join(f"{v:.2f}" for v in s["versions"])
    lines = [", ".join(s["files"]) or "(navigation data)", f"  RINEX {versions} navigation"]
    if s.get("leap_s") is not None:
        lines.append(f"  leap seconds {s['leap_s']}")
    if s["start"]:
        lines.append(f"  first ephemeris  {s['start']}  (t = {s['t_start_s']:.3f} s)")
        lines.append(f"  last ephemeris   {s['end']}  (t = {s['t_end_s']:.3f} s)")
    lines.append("")
    head = f"  {'system':<10} {'sats':>4} {'records':>8}"
    lines += [head, "  " + "-" * (len(head) - 2)]
    for letter, n in s["satellites"].items():
        lines.append(f"  {SYSTEMS.get(letter, letter):<10} {n:>4} {s['ephemerides'][letter]:>8}")
    lines.append("")
    head = f"  {'record':<14} {'read':>6} {'skipped':>8}"
    lines += [head, "  " + "-" * (len(head) - 2)]
    kinds = list(dict.fromkeys([*sorted(s["records"]), *sorted(s["skipped"])]))
    for kind in kinds:
        lines.append(f"  {kind:<14} {s['records'].get(kind, 0):>6} {s['skipped'].get(kind, 0):>8}")
    if s["iono"]:
        lines.append("")
        lines.append("  ionosphere  " + "; ".join(s["iono"]))
    return "\n".join(lines)
