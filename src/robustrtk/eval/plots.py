"""Figures of the paper's kind, built on :class:`matplotlib.figure.Figure` (Agg canvas,
no global pyplot state). Every function returns the Figure; :func:`save_figure` writes it.

* :func:`plot_error_series` — position error per axis over time for several solutions
  (Fig. 5);
* :func:`plot_dd_diagnostics` — post-fit residuals and the discriminant statistic Δv̄ per
  DD with the k0/k1 lines (Fig. 4);
* :func:`plot_situation_bars` — mean |error| per axis in each situation (Fig. 6);
* :func:`plot_trajectory` — horizontal trajectories.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from robustrtk.core import FloatArray, InputError
from robustrtk.io.atomic import atomic_path
from robustrtk.io.solution import DiagTable

_FONT = 10


def figure(width_in: float, height_in: float) -> Figure:
    """A new Figure with constrained layout and an Agg canvas (no pyplot state).

    Parameters
    ----------
    width_in, height_in : float
        Size in inches.

    Returns
    -------
    Figure
    """
    fig = Figure(figsize=(width_in, height_in), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _rel_time(t: FloatArray, t0: float) -> FloatArray:
    return np.asarray(t, dtype=float) - t0


def plot_error_series(
    series: Mapping[str, tuple[npt.ArrayLike, npt.ArrayLike]],
    *,
    axis_names: Sequence[str] = ("X", "Y", "Z"),
    title: str = "Positioning error",
    t0_s: float | None = None,
) -> Figure:
    """Error per axis against time, one panel per axis, one line per solution.

    Parameters
    ----------
    series : mapping name -> (t_s (T,), err_m (T, 3))
    axis_names : three str
        Axis names for the panel labels ("X", "Y", "Z" or "E", "N", "U").
    title : str
    t0_s : float, optional
        Time origin of the x axis (default: the earliest epoch).
    """
    if not series:
        raise InputError("plot_error_series needs at least one series")
    t0 = min(float(np.min(np.asarray(t, float))) for t, _ in series.values()) if t0_s is None else t0_s
    fig = figure(9.0, 7.0)
    axes = fig.subplots(3, 1, sharex=True)
    for name, (t, err) in series.items():
        e = np.asarray(err, dtype=float).reshape(-1, 3)
        tt = _rel_time(np.asarray(t, float), t0)
        for k, ax in enumerate(axes):
            ax.plot(tt, e[:, k], lw=0.8, label=name)
    for k, ax in enumerate(axes):
        ax.set_ylabel(f"{axis_names[k]} error (m)", fontsize=_FONT)
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize=_FONT - 1)
    axes[-1].set_xlabel("Time since start (s)", fontsize=_FONT)
    fig.suptitle(title, fontsize=_FONT + 2)
    return fig


def plot_dd_diagnostics(
    diag: DiagTable,
    *,
    k0: float = 2.0,
    k1: float = 8.0,
    residual_unit: str = "m",
    title: str = "Post-fit residuals and discriminant statistic per DD",
    max_rows: int = 6,
) -> Figure:
    """Posterior residuals (left) and Δv̄ (right) of each DD, with ±k0 and ±k1 lines.

    With more than ``max_rows`` DDs all DDs share one panel per quantity.
    """
    t_ep, labels, res = diag.pivot("residual")
    _, _, dv = diag.pivot("dv")
    if not labels:
        raise InputError("plot_dd_diagnostics needs a non-empty DiagTable")
    tt = t_ep - t_ep[0]
    per_row = len(labels) <= max_rows
    nrow = len(labels) if per_row else 1
    fig = figure(11.0, max(3.0, 1.9 * nrow + 0.8))
    axes = np.atleast_2d(fig.subplots(nrow, 2, sharex=True, squeeze=False))
    for j, lab in enumerate(labels):
        r = j if per_row else 0
        axes[r, 0].plot(tt, res[:, j], ".", ms=2, label=lab)
        axes[r, 1].plot(tt, dv[:, j], ".", ms=2, label=lab)
    for r in range(nrow):
        a_res, a_dv = axes[r]
        for val, style, name in ((k0, "--", "k0"), (k1, ":", "k1")):
            a_dv.axhline(val, color="k", ls=style, lw=0.9, label=f"±{name} = {val:g}")
            a_dv.axhline(-val, color="k", ls=style, lw=0.9)
        a_res.set_ylabel(f"Residual ({residual_unit})", fontsize=_FONT)
        a_dv.set_ylabel("Δv̄ (-)", fontsize=_FONT)
        for ax in (a_res, a_dv):
            ax.grid(True, alpha=0.3)
            ax.legend(loc="upper right", fontsize=_FONT - 2, markerscale=4)
    axes[-1, 0].set_xlabel("Time since start (s)", fontsize=_FONT)
    axes[-1, 1].set_xlabel("Time since start (s)", fontsize=_FONT)
    fig.suptitle(title, fontsize=_FONT + 2)
    return fig


def plot_situation_bars(
    mean_abs: Mapping[str, Mapping[int, npt.ArrayLike]],
    *,
    situations: Sequence[int] = (2, 3),
    axis_names: Sequence[str] = ("X", "Y", "Z"),
    title: str = "Mean absolute positioning error by situation",
) -> Figure:
    """Grouped bars: one panel per situation, axes on x, one bar per solution.

    Parameters
    ----------
    mean_abs : mapping name -> {situation: (3,) mean |error| (m)}
        As returned by :func:`robustrtk.eval.situations.situation_mean_abs_errors`.
    """
    if not mean_abs:
        raise InputError("plot_situation_bars needs at least one solution")
    names = list(mean_abs)
    fig = figure(4.2 * len(situations) + 1.0, 4.2)
    axes = np.atleast_1d(fig.subplots(1, len(situations), squeeze=False)[0])
    x = np.arange(3)
    width = 0.8 / len(names)
    for ax, k in zip(axes, situations, strict=True):
        for i, name in enumerate(names):
            v = np.asarray(mean_abs[name].get(k, np.full(3, np.nan)), dtype=float)
            bars = ax.bar(x + (i - (len(names) - 1) / 2) * width, v, width, label=name)
            ax.bar_label(bars, fmt="%.3f", fontsize=_FONT - 2)
        ax.set_xticks(x, [f"{a}" for a in axis_names])
        ax.set_xlabel("Axis", fontsize=_FONT)
        ax.set_ylabel("Mean |error| (m)", fontsize=_FONT)
        ax.set_title(f"Situation #{k}", fontsize=_FONT + 1)
        ax.grid(True, axis="y", alpha=0.3)
        ax.legend(fontsize=_FONT - 1)
    fig.suptitle(title, fontsize=_FONT + 2)
    return fig


def plot_trajectory(
    tracks: Mapping[str, npt.ArrayLike],
    *,
    xlabel: str = "East (m)",
    ylabel: str = "North (m)",
    title: str = "Horizontal trajectory",
) -> Figure:
    """Horizontal tracks, equal axis scale.

    Parameters
    ----------
    tracks : mapping name -> positions (T, 2) or (T, 3) in a local horizontal frame (m)
        (ENU for GNSS, the room frame for pseudolites); only the first two columns are
        drawn.
    """
    if not tracks:
        raise InputError("plot_trajectory needs at least one track")
    fig = figure(7.0, 6.0)
    ax = fig.subplots()
    for name, p in tracks.items():
        a = np.asarray(p, dtype=float)
        ax.plot(a[:, 0], a[:, 1], "-", lw=0.8, marker=".", ms=2, label=name)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel(xlabel, fontsize=_FONT)
    ax.set_ylabel(ylabel, fontsize=_FONT)
    ax.set_title(title, fontsize=_FONT + 2)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=_FONT - 1)
    return fig


def save_figure(fig: Figure, path: str | os.PathLike[str], *, dpi: int = 150) -> Path:
    """Write ``fig`` (format from the suffix: .png, .pdf, .svg) atomically.

    Returns
    -------
    Path
        The written file.
    """
    target = Path(path)
    fmt = target.suffix.lstrip(".").lower() or "png"
    with atomic_path(target) as tmp:
        fig.savefig(tmp, format=fmt, dpi=dpi)
    return target


# ----------------------------------------------------------------------------- by solution status
#: Colour and name of each RTKLIB ``Q`` (as rtkplot draws them).
Q_STYLE: dict[int, tuple[str, str]] = {
    1: ("#00a000", "fixed"),
    2: ("#ff8c00", "float"),
    3: ("#c000c0", "sbas"),
    4: ("#1e64ff", "dgps"),
    5: ("#e00000", "single"),
    6: ("#00b0c0", "ppp"),
}
#: Colour of each satellite system letter.
SYSTEM_COLORS: dict[str, str] = {
    "G": "#1f77b4", "R": "#d62728", "E": "#2ca02c", "C": "#ff7f0e", "J": "#9467bd", "S": "#8c564b",
    "I": "#e377c2",
}  # fmt: skip


def _by_q(ax: Any, x: FloatArray, y: FloatArray, q: npt.ArrayLike, ms: float = 3.0) -> None:
    qa = np.asarray(q, dtype=np.int64)
    for qv, (colour, name) in Q_STYLE.items():
        sel = qa == qv
        if np.any(sel):
            ax.plot(x[sel], y[sel], ".", ms=ms, color=colour, label=f"{name} ({int(sel.sum())})")


def plot_status_tracks(
    tracks: Mapping[str, tuple[npt.ArrayLike, npt.ArrayLike]],
    *,
    xlabel: str = "East (m)",
    ylabel: str = "North (m)",
    title: str = "Ground track by solution status",
) -> Figure:
    """Horizontal tracks, one panel per solution side by side (shared axes), points coloured
    by RTKLIB ``Q`` (:data:`Q_STYLE`).

    Parameters
    ----------
    tracks : mapping name -> (enu_m (T, 2 or 3), q (T,))
    """
    if not tracks:
        raise InputError("plot_status_tracks needs at least one track")
    n = len(tracks)
    fig = figure(min(5.0 * n + 0.6, 15.0), 4.8 if n == 1 else 3.6 + 0.4 * max(0, 3 - n))
    axes = np.atleast_1d(fig.subplots(1, n, sharex=True, sharey=True, squeeze=False)[0])
    for ax, (name, (p, q)) in zip(axes, tracks.items(), strict=True):
        a = np.asarray(p, dtype=float).reshape(-1, np.asarray(p).shape[-1])
        ax.plot(a[:, 0], a[:, 1], "-", lw=0.4, color="0.7")
        _by_q(ax, a[:, 0], a[:, 1], q)
        ax.set_aspect("equal", adjustable="box")
        ax.set_xlabel(xlabel, fontsize=_FONT)
        ax.set_title(name, fontsize=_FONT + 1)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=_FONT - 2, markerscale=3, loc="best")
    axes[0].set_ylabel(ylabel, fontsize=_FONT)
    fig.suptitle(title, fontsize=_FONT + 2)
    return fig


def plot_status_series(
    series: Mapping[str, tuple[npt.ArrayLike, npt.ArrayLike, npt.ArrayLike]],
    *,
    axis_names: Sequence[str] = ("East", "North", "Up"),
    ylabel: str = "error (m)",
    title: str = "ENU error by solution status",
    t0_s: float | None = None,
    range_m: float | None = None,
) -> Figure:
    """Three rows (E, N, U) of values against time coloured by ``Q``, one column per
    solution (shared axes), and a last row with the status and ``ns`` over time.

    Parameters
    ----------
    series : mapping name -> (t_s (T,), values_m (T, 3), q (T,))
    range_m : float, optional
        Limit the y axes of the three value rows to ± this value.
    """
    if not series:
        raise InputError("plot_status_series needs at least one series")
    t0 = min(float(np.min(np.asarray(t, float))) for t, _, _ in series.values()) if t0_s is None else t0_s
    n = len(series)
    fig = figure(min(5.5 * n + 0.8, 15.0), 7.5)
    axes = np.atleast_2d(fig.subplots(3, n, sharex=True, sharey="row", squeeze=False))
    for j, (name, (t, v, q)) in enumerate(series.items()):
        tt = _rel_time(np.asarray(t, float), t0)
        e = np.asarray(v, dtype=float).reshape(-1, 3)
        for k in range(3):
            ax = axes[k, j]
            _by_q(ax, tt, e[:, k], q, ms=2.0)
            ax.grid(True, alpha=0.3)
            if range_m is not None:
                ax.set_ylim(-range_m, range_m)
            if j == 0:
                ax.set_ylabel(f"{axis_names[k]} {ylabel}", fontsize=_FONT)
        axes[0, j].set_title(name, fontsize=_FONT + 1)
        axes[0, j].legend(fontsize=_FONT - 2, markerscale=3, loc="upper right")
        axes[-1, j].set_xlabel("Time since start (s)", fontsize=_FONT)
    fig.suptitle(title, fontsize=_FONT + 2)
    return fig


def plot_status_timeline(
    series: Mapping[str, tuple[npt.ArrayLike, npt.ArrayLike, npt.ArrayLike]],
    *,
    t0_s: float | None = None,
    title: str = "Solution status and satellites per epoch",
) -> Figure:
    """Per solution: a status strip (one row per solution, coloured by ``Q``) and the
    number of satellites (``ns``) per epoch.

    Parameters
    ----------
    series : mapping name -> (t_s (T,), q (T,), ns (T,))
    """
    if not series:
        raise InputError("plot_status_timeline needs at least one series")
    t0 = min(float(np.min(np.asarray(t, float))) for t, _, _ in series.values()) if t0_s is None else t0_s
    fig = figure(10.0, 4.2)
    a_q, a_ns = fig.subplots(2, 1, sharex=True, height_ratios=(1, 2))
    names = list(series)
    for i, name in enumerate(names):
        t, q, ns = series[name]
        tt = _rel_time(np.asarray(t, float), t0)
        _by_q(a_q, tt, np.full(tt.shape, float(len(names) - 1 - i)), q, ms=4.0)
        nsa = np.asarray(ns, dtype=float)
        a_ns.step(tt, np.where(nsa >= 0, nsa, np.nan), where="post", lw=1.0, label=name)
    a_q.set_yticks(range(len(names)), names[::-1])
    a_q.set_ylim(-0.6, len(names) - 0.4)
    handles = {h.get_label().split(" ")[0]: h for h in a_q.get_legend_handles_labels()[0]}
    a_q.legend(list(handles.values()), list(handles), fontsize=_FONT - 2, markerscale=3, ncol=6,
               loc="upper right")  # fmt: skip
    a_ns.set_ylabel("ns (satellites)", fontsize=_FONT)
    a_ns.set_xlabel("Time since start (s)", fontsize=_FONT)
    a_ns.grid(True, alpha=0.3)
    a_ns.legend(fontsize=_FONT - 1)
    fig.suptitle(title, fontsize=_FONT + 2)
    return fig


def plot_sky(
    az_rad: Mapping[str, npt.ArrayLike],
    el_rad: Mapping[str, npt.ArrayLike],
    *,
    elev_mask_deg: float | None = None,
    title: str = "Sky plot",
) -> Figure:
    """Polar sky plot (north up, clockwise): one track per satellite, coloured by system.

    Parameters
    ----------
    az_rad, el_rad : mapping satellite id -> (T,) azimuth / elevation (rad); NaN where absent
    elev_mask_deg : float, optional
        Drawn as a dashed circle.
    """
    if not az_rad:
        raise InputError("plot_sky needs at least one satellite")
    fig = figure(5.6, 5.6)
    ax: Any = fig.add_subplot(projection="polar")
    ax.set_theta_zero_location("N")
    ax.set_theta_direction(-1)
    for sat, az in az_rad.items():
        a = np.asarray(az, dtype=float)
        zen = 90.0 - np.degrees(np.asarray(el_rad[sat], dtype=float))
        ok = np.isfinite(a) & np.isfinite(zen) & (zen <= 90.0)
        if not np.any(ok):
            continue
        colour = SYSTEM_COLORS.get(sat[:1], "k")
        ax.plot(a[ok], zen[ok], ".", ms=1.5, color=colour)
        last = np.flatnonzero(ok)[-1]
        ax.text(a[last], zen[last], sat, fontsize=_FONT - 3, color=colour)
    if elev_mask_deg is not None:
        th = np.linspace(0, 2 * np.pi, 181)
        ax.plot(th, np.full(th.shape, 90.0 - elev_mask_deg), "k--", lw=0.8)
    ax.set_ylim(0, 90)
    ax.set_yticks([0, 30, 60, 90], ["90°", "60°", "30°", "0°"], fontsize=_FONT - 2)
    present = sorted({s[:1] for s in az_rad})
    for s in present:
        ax.plot([], [], "o", ms=4, color=SYSTEM_COLORS.get(s, "k"), label=s)
    ax.legend(loc="upper right", bbox_to_anchor=(1.15, 1.1), fontsize=_FONT - 1)
    ax.set_title(title, fontsize=_FONT + 2)
    return fig


def plot_satellite_counts(
    t_s: npt.ArrayLike, counts: Mapping[str, npt.ArrayLike], *, title: str = "Satellites per epoch"
) -> Figure:
    """Stacked satellites per epoch by system.

    Parameters
    ----------
    t_s : (T,) epoch times (s)
    counts : mapping system letter -> (T,) counts
    """
    if not counts:
        raise InputError("plot_satellite_counts needs at least one system")
    t = np.asarray(t_s, dtype=float)
    fig = figure(10.0, 3.4)
    ax = fig.subplots()
    systems = list(counts)
    ax.stackplot(t - t[0], *[np.asarray(counts[s], dtype=float) for s in systems], step="post",
                 labels=systems, colors=[SYSTEM_COLORS.get(s, "0.5") for s in systems])  # fmt: skip
    ax.set_xlabel("Time since start (s)", fontsize=_FONT)
    ax.set_ylabel("Satellites", fontsize=_FONT)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=_FONT - 1, ncol=len(systems), loc="lower right")
    ax.set_title(title, fontsize=_FONT + 2)
    return fig


def plot_dd_by_satellite(
    diag: DiagTable, *, title: str = "Post-fit residuals and robust factors by satellite", max_sats: int = 12
) -> Figure:
    """Two panels against time: post-fit residuals and robust factors of every DD row,
    coloured by the DD's (non-reference) satellite; rejected rows marked with crosses.
    Beyond ``max_sats`` satellites the rest share one grey colour.
    """
    if len(diag) == 0:
        raise InputError("plot_dd_by_satellite needs a non-empty DiagTable")
    sats = np.array([dd_satellite(s) for s in diag.dd.tolist()])
    order = list(dict.fromkeys(sats.tolist()))
    t = diag.t_s - float(np.min(diag.t_s))
    fig = figure(10.0, 6.0)
    a_res, a_fac = fig.subplots(2, 1, sharex=True)
    cmap = [f"C{k % 10}" for k in range(max_sats)]
    for k, sat in enumerate(order):
        sel = sats == sat
        colour = cmap[k] if k < max_sats else "0.6"
        lab = sat if k < max_sats else ("others" if k == max_sats else None)
        a_res.plot(t[sel], diag.residual[sel], ".", ms=1.5, color=colour, label=lab)
        a_fac.plot(t[sel], diag.factor[sel], ".", ms=2.0, color=colour)
    rej = diag.situation == 3
    if np.any(rej):
        fin = diag.factor[np.isfinite(diag.factor)]
        top = float(np.max(fin)) if fin.size else 1.0
        y = np.where(np.isfinite(diag.factor[rej]), diag.factor[rej], top)  # rejected: infinite factor
        a_fac.plot(t[rej], y, "kx", ms=4, label=f"rejected ({int(rej.sum())}; at the top if infinite)")
        a_fac.legend(fontsize=_FONT - 1)
    a_res.set_ylabel("Post-fit residual", fontsize=_FONT)
    a_fac.set_ylabel("Robust factor", fontsize=_FONT)
    a_fac.set_yscale("log")
    a_fac.set_xlabel("Time since start (s)", fontsize=_FONT)
    for ax in (a_res, a_fac):
        ax.grid(True, alpha=0.3)
    a_res.legend(fontsize=_FONT - 2, ncol=7, markerscale=4, loc="upper right")
    fig.suptitle(title, fontsize=_FONT + 2)
    return fig


def dd_satellite(label: str) -> str:
    """The non-reference transmitter of a DD label: ``"G05:L1-G15:L1"`` → ``"G05"``,
    ``"PL4-PL6"`` → ``"PL4"``, ``"G05-G12/1C"`` → ``"G05"``."""
    head = label.split("-", 1)[0]
    return head.split(":", 1)[0].split("/", 1)[0]


def figure_png(fig: Figure, *, dpi: int = 90) -> bytes:
    """The PNG bytes of ``fig``."""
    import io

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return buf.getvalue()
