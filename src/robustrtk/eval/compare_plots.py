"""Figure of a solution comparison: ENU error time series and horizontal scatter."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.figure import Figure

from robustrtk.core import InputError
from robustrtk.eval.comparison import SolutionComparison
from robustrtk.eval.plots import figure
from robustrtk.timeutil import gpst_text

__all__ = ["Q_STYLE", "plot_comparison"]

#: Colour and legend name of each ``Q`` (RTKLIB's rtkplot colours).
Q_STYLE = {
    1: ("tab:green", "fixed (Q=1)"),
    2: ("orange", "float (Q=2)"),
    3: ("tab:purple", "SBAS (Q=3)"),
    4: ("tab:blue", "DGPS (Q=4)"),
    5: ("tab:red", "single (Q=5)"),
    6: ("tab:brown", "PPP (Q=6)"),
}
_FONT = 9


def plot_comparison(
    results: Sequence[SolutionComparison],
    *,
    title: str = "Position error against truth",
    range_m: float | None = None,
) -> Figure:
    """ENU error time series (three panels) and horizontal error scatter, one row per
    solution, points coloured by ``Q``.

    Parameters
    ----------
    results : sequence of SolutionComparison
        Only epochs with a truth (and in the window) are drawn.
    title : str
    range_m : float, optional
        Symmetric axis limit ±range_m (m) for all error axes; points beyond are not drawn
        (counted as "off-scale" in the panel title). Default: each panel's full range.
    """
    if not results:
        raise InputError("plot_comparison needs at least one solution")
    t_all = [r.t_s[np.all(np.isfinite(r.enu_err_m), axis=1)] for r in results]
    starts = [float(t.min()) for t in t_all if t.size]
    t0 = min(starts) if starts else 0.0
    n = len(results)
    fig = figure(15.0, 2.7 * n + 0.9)
    axes = fig.subplots(n, 4, squeeze=False, gridspec_kw={"width_ratios": [1.0, 1.0, 1.0, 0.8]})
    comp = ("East", "North", "Up")
    for i, r in enumerate(results):
        has = np.all(np.isfinite(r.enu_err_m), axis=1)
        tt = r.t_s - t0
        for k in range(4):
            ax = axes[i, k]
            for qv in sorted(set(r.q[has].tolist())):
                sel = has & (r.q == qv)
                colour, name = Q_STYLE.get(qv, ("k", f"Q={qv}"))
                name = f"{name}: {int(sel.sum())}"
                if k < 3:
                    ax.plot(tt[sel], r.enu_err_m[sel, k], ".", ms=3, color=colour, label=name)
                else:
                    ax.plot(r.enu_err_m[sel, 0], r.enu_err_m[sel, 1], ".", ms=3, color=colour, label=name)
            outside = 0
            if range_m is not None:
                cols = [k] if k < 3 else [0, 1]
                outside = int(np.sum(np.any(np.abs(r.enu_err_m[has][:, cols]) > range_m, axis=1)))
                ax.set_ylim(-range_m, range_m)
                if k == 3:
                    ax.set_xlim(-range_m, range_m)
            extra = f" ({outside} off-scale)" if outside else ""
            if k < 3:
                ax.set_title(f"{r.label}: {comp[k]} error{extra}", fontsize=_FONT + 1)
                ax.set_ylabel(f"{comp[k]} error (m)", fontsize=_FONT)
                ax.set_xlabel(f"Time since {gpst_text(t0)} GPST (s)", fontsize=_FONT)
            else:
                ax.set_title(f"{r.label}: E-N error{extra}", fontsize=_FONT + 1)
                ax.set_xlabel("East error (m)", fontsize=_FONT)
                ax.set_ylabel("North error (m)", fontsize=_FONT)
                ax.axvline(0.0, color="k", lw=0.5)
                ax.set_aspect("equal", adjustable="datalim")
            ax.axhline(0.0, color="k", lw=0.5)
            ax.grid(True, alpha=0.3)
            if not np.any(has):
                ax.text(0.5, 0.5, "no epochs with truth", transform=ax.transAxes, ha="center", va="center")
            if k in (0, 3):
                ax.legend(fontsize=_FONT - 1, markerscale=2.5, loc="best")
    fig.suptitle(title, fontsize=_FONT + 3)
    return fig
