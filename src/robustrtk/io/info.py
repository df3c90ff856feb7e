"""What is in an observation batch: a summary dict and its text table (``robustrtk info``).

Definitions
-----------
* A transmitter is *seen* in an epoch when any of its cells has a finite code or phase.
* ``interval_s`` is the median of the epoch time differences; ``n_gaps`` counts differences
  larger than 1.5 intervals.
* ``phase_fraction`` = (cells with a finite phase) / (cells with a finite code or phase),
  overall and per system: how much of what is tracked also has carrier phase.
"""

from __future__ import annotations

import math
import os
from typing import Any

import numpy as np
import numpy.typing as npt

from robustrtk.core import ObsBatch
from robustrtk.gnss import SYSTEMS
from robustrtk.io.readers import detect_format, read_observations
from robustrtk.timeutil import gpst_text

__all__ = ["summarize", "summarize_file", "format_summary"]


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
        ``rinex_version``, ``receiver_type``, ``approx_pos_m`` when known. Fractions are NaN
        when nothing is tracked.
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
