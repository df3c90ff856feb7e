"""Figures of the Li et al. (2019) reproduction (analogues of the paper's Figs. 4-11),
drawn from the first seed's raw solutions."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import numpy.typing as npt
from matplotlib.figure import Figure

from robustrtk.eval.plots import (
    figure,
    plot_dd_diagnostics,
    plot_error_series,
    plot_situation_bars,
    save_figure,
)
from robustrtk.eval.situations import epoch_situations, situation_mean_abs_errors
from robustrtk.experiments.li2019.metrics import (
    AR_MODES_015,
    AR_MODES_RAIL,
    dd_series,
    diag_table,
    error_3d_m,
    fault_epochs,
    pos_error_m,
)
from robustrtk.experiments.li2019.schemes import K0, K1, RAIL_FAULT_EPOCH, STATIC_FAULT_EPOCH, Raw
from robustrtk.sim.scenario import load_scenario


def _fig_rtk_dv(orig: Raw, err: Raw, faulty: npt.NDArray[np.bool_]) -> Figure:
    fig = figure(11.0, 5.5)
    axes = fig.subplots(2, 2, sharex=True)
    for j, (raw, name) in enumerate(((orig, "Original"), (err, "With 5 cm errors"))):
        ep = np.arange(raw["t_s"].size)
        res = dd_series(raw, "PL4-PL1", "residual") * 1e3
        dv = dd_series(raw, "PL4-PL1", "dv")
        axes[0, j].plot(ep, res, ".-", ms=3, lw=0.6, label="PL4-PL1 residual")
        axes[1, j].plot(ep, dv, ".-", ms=3, lw=0.6, label="PL4-PL1 Δv̄")
        if j == 1 and faulty.any():
            axes[1, j].plot(ep[faulty], dv[faulty], "rx", ms=6, label="epochs with 5 cm error")
        for s_, ls in ((K0, "--"), (K1, ":")):
            axes[1, j].axhline(s_, color="k", ls=ls, lw=0.8)
            axes[1, j].axhline(-s_, color="k", ls=ls, lw=0.8)
        axes[0, j].set_title(name)
        axes[0, j].set_ylabel("Post-fit residual (mm)")
        axes[1, j].set_ylabel("Δv̄ (-)  [k0 = 2 dashed, k1 = 8 dotted]")
        axes[1, j].set_xlabel("Epoch")
        for ax in axes[:, j]:
            ax.grid(True, alpha=0.3)
            ax.legend(loc="upper right", fontsize=8)
    fig.suptitle("Fig. 7 analogue: RUKF residuals and Δv̄ of PL4-PL1 (RTK static)")
    return fig


def _fig_status_errors(raws: Mapping[str, Raw], title: str) -> Figure:
    fig = figure(10.0, 6.0)
    ax, ax2 = fig.subplots(2, 1, sharex=True, height_ratios=[3, 1])
    code = {"fixed": 3, "partial": 2, "float": 1, "code": 0, "none": -1}
    for i, (name, raw) in enumerate(raws.items()):
        ep = np.arange(raw["t_s"].size)
        ax.plot(ep, error_3d_m(raw), lw=1.0, label=name)
        ax2.plot(ep, [code.get(s, -1) + 0.08 * (i - 1) for s in raw["status"]], ".", ms=3, label=name)
    ax.axvline(STATIC_FAULT_EPOCH, color="r", ls="--", lw=0.8, label="0.15 m error (epoch 100)")
    ax.set_ylabel("3D error (m)")
    ax.set_yscale("log")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    ax2.set_yticks([3, 2, 1], ["fixed", "partial", "float"])
    ax2.set_ylabel("AR status")
    ax2.set_xlabel("Epoch")
    ax2.grid(True, alpha=0.3)
    ax2.legend(fontsize=7, ncol=3)
    fig.suptitle(title)
    return fig


def _fig_x_error(raws: Mapping[str, Raw], faulty: npt.NDArray[np.bool_]) -> Figure:
    fig = figure(10.0, 4.5)
    ax = fig.subplots()
    for name, raw in raws.items():
        ax.plot(np.arange(raw["t_s"].size), pos_error_m(raw)[:, 0] * 100, lw=1.0, label=name)
    for e in np.flatnonzero(faulty):
        ax.axvspan(e - 0.5, e + 0.5, color="r", alpha=0.15, lw=0)
    ax.set_xlabel("Epoch (red bands: 0.1 m error on PL4)")
    ax.set_ylabel("X error (cm)")
    ax.grid(True, alpha=0.3)
    ax.legend()
    ax.set_title("Fig. 10 analogue: kinematic rail, X error, SUKF vs RUKF")
    return fig


def _fig_rail_track(
    raws: Mapping[str, Raw], start: Sequence[float], end: Sequence[float], title: str
) -> Figure:
    fig = figure(10.0, 5.0)
    ax = fig.subplots()
    ax.plot([start[0], end[0]], [start[1], end[1]], "k-", lw=2, label="True rail")
    for name, raw in raws.items():
        p = raw["pos_m"]
        ax.plot(p[:, 0], p[:, 1], ".-", ms=2, lw=0.7, label=name)
        k = min(RAIL_FAULT_EPOCH, p.shape[0] - 1)
        ax.plot(p[k, 0], p[k, 1], "o", mfc="none", ms=8, color=ax.lines[-1].get_color())
    ax.set_xlabel("X (m)")
    ax.set_ylabel("Y (m)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, title="circle: epoch 50 (0.15 m error)", title_fontsize=8)
    ax.set_title(title)
    return fig


def make_figures(raws: Mapping[str, Raw], out: Path) -> dict[str, str]:
    """Draw every figure into ``out``; return ``{file name: path relative to out}``."""
    figs: dict[str, Figure] = {}
    sukf, rukf = raws["dpl/SUKF"], raws["dpl/RUKF"]
    figs["fig4_dpl_residuals_dv.png"] = plot_dd_diagnostics(
        diag_table(rukf),
        k0=K0,
        k1=K1,
        title="Fig. 4 analogue: RUKF post-fit residuals and Δv̄ of the DD codes (DPL static)",
    )
    figs["fig5_dpl_errors.png"] = plot_error_series(
        {"SUKF": (sukf["t_s"], pos_error_m(sukf)), "RUKF": (rukf["t_s"], pos_error_m(rukf))},
        title="Fig. 5 analogue: DPL static positioning error, SUKF vs RUKF",
    )
    et, es = epoch_situations(diag_table(rukf))
    figs["fig6_dpl_situations.png"] = plot_situation_bars(
        situation_mean_abs_errors(
            et, es, {"SUKF": (sukf["t_s"], pos_error_m(sukf)), "RUKF": (rukf["t_s"], pos_error_m(rukf))}
        ),
        title="Fig. 6 analogue: DPL mean |error| in situations #2 and #3",
    )
    faulty = fault_epochs(raws["static/RUKF"], raws["static/RUKF"]["t_s"].size)
    figs["fig7_rtk_pl4_dv.png"] = _fig_rtk_dv(raws["static_orig/RUKF"], raws["static/RUKF"], faulty)
    figs["fig8_rtk_static_errors.png"] = plot_error_series(
        {n: (raws[f"static/{n}"]["t_s"], pos_error_m(raws[f"static/{n}"])) for n in ("SUKF", "RUKF")},
        title="Fig. 8 analogue: RTK static error with 5 cm PL4 errors, SUKF vs RUKF",
    )
    labels = {"prior": "paper's scheme: previous coordinate as prior",
              "prior_lit": "paper's scheme, Δv̄ from posterior residuals",
              "prior_poly": "paper's scheme, default slip detectors", "hold": "fix-and-hold",
              "prior_kept": "paper's scheme, correlations kept (σ² added)",
              "cont": "continuous AR, no hold", "inst": "single-epoch AR",
              "prior_re": "paper's scheme, ambiguities re-estimated every epoch"}  # fmt: skip
    for h in AR_MODES_015:
        figs[f"fig9_rtk_015_{h}.png"] = _fig_status_errors(
            {n: raws[f"s015_{h}/{n}"] for n in ("SUKF", "RUKF", "RUKF+PAR")},
            f"Fig. 9 analogue: RTK static, 0.15 m on PL4 at epoch 100 only ({labels[h]})",
        )
    faulty = fault_epochs(raws["rail/SUKF"], raws["rail/SUKF"]["t_s"].size)
    figs["fig10_rail_x_error.png"] = _fig_x_error({n: raws[f"rail/{n}"] for n in ("SUKF", "RUKF")}, faulty)
    tr = load_scenario("li2019_rtk_rail_015").trajectory
    assert tr.end_m is not None
    for v in AR_MODES_RAIL:
        figs[f"fig11_rail_track_{v}.png"] = _fig_rail_track(
            {n: raws[f"rail015_{v}/{n}"] for n in ("SUKF", "RUKF+PAR")},
            tr.start_m,
            tr.end_m,
            f"Fig. 11 analogue: rail track, 0.15 m on PL4 at epoch 50 ({labels[v]})",
        )
    paths: dict[str, str] = {}
    for name, fig in figs.items():
        save_figure(fig, out / name, dpi=110)
        paths[name] = name
    return paths


__all__ = ["make_figures"]
