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
