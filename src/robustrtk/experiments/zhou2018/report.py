"""Figures and ``report.md`` of the Zhou et al. (2018) reproduction."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from robustrtk.experiments.zhou2018.metrics import FILTERS, PAPER_TABLE2, Claim
from robustrtk.io.tables import markdown_table

_COLORS = {"ls": "tab:gray", "ekf": "tab:blue", "ukf": "tab:orange", "pf": "tab:green"}


def make_figures(npz: Any, out: Path) -> dict[str, str]:
    """Error series of node 2 (first seed) per axis, traditional vs improved (the paper's
    Figs. 11–13); node 2's satellite counts (Fig. 8); the degraded session's 3D error.
    Returns ``{name: file name}``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figs: dict[str, str] = {}
    truth = npz["clean/truth2"][0]
    fig, axes = plt.subplots(3, 2, figsize=(11, 8), sharex=True)
    for c, mode in enumerate(("traditional", "improved")):
        for f in FILTERS:
            e = npz[f"clean/{f}/{mode}/pos2"][0] - truth
            for j, ax_name in enumerate("XYZ"):
                axes[j, c].plot(e[:, j], color=_COLORS[f], label=f.upper())
                axes[j, c].set_ylabel(f"{ax_name} error (m)")
        axes[0, c].set_title(f"node 2, {mode}")
        axes[2, c].set_xlabel("epoch")
    axes[0, 0].legend(loc="best", fontsize=8)
    fig.tight_layout()
    figs["errors_xyz"] = "errors_xyz.png"
    fig.savefig(out / figs["errors_xyz"], dpi=110)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(8, 3))
    ax.step(np.arange(npz["clean/n_gps2"].shape[1]), npz["clean/n_gps2"][0], where="mid", label="GPS")
    ax.step(np.arange(npz["clean/n_bds2"].shape[1]), npz["clean/n_bds2"][0], where="mid", label="BeiDou")
    ax.set_xlabel("epoch")
    ax.set_ylabel("satellites")
    ax.set_title("node 2 (windowsill): satellites seen, first seed")
    ax.legend()
    fig.tight_layout()
    figs["node2_satellites"] = "node2_satellites.png"
    fig.savefig(out / figs["node2_satellites"], dpi=110)
    plt.close(fig)

    fig, axes2 = plt.subplots(1, 3, figsize=(13, 3.5), sharey=True)
    fault = npz["degraded/fault1"][0]
    k = np.flatnonzero(fault)
    for ax, f in zip(axes2, ("ekf", "ukf", "pf"), strict=True):
        for mode, ls in (("traditional", "--"), ("improved", "-")):
            e = np.linalg.norm(npz[f"degraded/{f}/{mode}/pos2"][0] - truth, axis=1)
            ax.plot(e, ls, color=_COLORS[f], label=f"node 2 {mode}")
        e1 = np.linalg.norm(npz[f"degraded/{f}/off/pos1"][0] - npz["degraded/truth1"][0], axis=1)
        ax.plot(e1, ":", color="k", label="node 1")
        if k.size:
            ax.axvspan(k[0], k[-1] + 1, color="tab:red", alpha=0.1, label="node 1 fault")
        ax.set_title(f"{f.upper()}, node 1 degraded")
        ax.set_xlabel("epoch")
    axes2[0].set_ylabel("3D error (m)")
    axes2[0].legend(fontsize=7)
    fig.tight_layout()
    figs["degraded_3d"] = "degraded_3d.png"
    fig.savefig(out / figs["degraded_3d"], dpi=110)
    plt.close(fig)
    return figs


def _cell(s: dict[str, Any]) -> str:
    x, y, z = s["rms_xyz_m"]
    return f"{x:.2f} / {y:.2f} / {z:.2f}"


def write_report(
    out: Path,
    stats: dict[str, dict[str, dict[str, Any]]],
    extra: dict[str, Any],
    claims: list[Claim],
    figs: dict[str, str],
    seeds: list[int],
    vis: dict[str, Any],
    elapsed_s: float,
    quick: bool,
    nav_path: Path,
) -> Path:
    """Write ``report.md`` (setup, Table 2 beside ours, all cells, claims, figures)."""
    L: list[str] = []
    L.append("# Zhou et al. (2018): GNSS cooperative positioning of two static nodes, reproduced\n")
    L.append(
        f"Runs: {len(seeds)} seeds ({seeds[0]}..{seeds[-1]}){' — QUICK (shortened)' if quick else ''}; "
        f"{vis['n_epochs']} epochs at 1 s; wall time {elapsed_s:.0f} s.\n"
    )
    L.append("## Setup\n")
    L.append(
        f"- Geometry: real broadcast GPS and BeiDou orbits of `{nav_path.name}` "
        "(mosaicx5 dataset, 2024-06-24 from 08:20:00 GPST); the paper's 2016 Xi'an data are not public. "
        "Node 1 at the paper's ECEF (−1702129.484, 5010430.822, "
        "3549570.165) m, node 2 at the paper's ENU "
        "(−5.1861, −0.8038, −3.9173) m from it (6.549 m baseline).\n"
        f"- Node 1, open sky: {vis['node1_sats_mean']:.1f} "
        "GPS+BeiDou satellites on average. Node 2, windowsill "
        "(azimuth sector 125–275°, elevation ≤ 70°, at most "
        "3 GPS and 5 BeiDou, 10 % per-epoch dropouts, "
        f"10 dB loss, 2 m Gauss–Markov multipath τ = 20 s): GPS ≤ {vis['node2_gps_max']} (mean "
        f"{vis['node2_gps_mean']:.1f}), BeiDou {vis['node2_bds_min']}–{vis['node2_bds_max']} (mean "
        f"{vis['node2_bds_mean']:.1f}).\n"
        "- Pseudorange noise: eq. 25 scaled to metres, σ² = "
        "σ0² 10^(0.1 (45 − C/N0)) / sin² θ, σ0 = 1 m, C/N0 "
        "from elevation (48 dB-Hz at the zenith, −12 dB at "
        "the horizon, ±2 dB per satellite); the filters "
        "weight rows with the same eq. 25 variance. Receiver "
        "clocks: random walk 1 m/s per system, seeded "
        "BeiDou–GPS bias. Inter-node range (DD carrier baseline): truth + N(0, 2 cm²).\n"
        "- Degraded runs: +20 m on two seeded node-1 satellites at epochs 20–34 (same seed, same noise "
        "as the clean run).\n"
        "- Node 1 solves alone (as in the paper, node 2 is "
        "the one assisted); node 2 uses node 1's broadcast "
        "position with the range. `traditional`: range variance "
        "as measured; `improved`: eq. 24 with node 1's "
        "covariance reset to σ_set² I (eq. 29; eq. 30 for the UKF), σ_set from a 10-broadcast window "
        "(robustrtk.estimation.coop). `off`: node 2 alone.\n"
        "- Filters: LS (per-epoch Gauss–Newton), EKF, augmented UKF (α = 1, β = 2), PF "
        f"({'300' if quick else '1000'} particles, clocks by "
        "the linear proposal), σ_ẋ = 0.01 m/s, σ_ḃ = 10 m/s.\n"
    )
    L.append("## Table 2: node 2 RMS X / Y / Z (m), paper beside ours (clean runs)\n")
    s = stats["clean"]
    rows: list[list[str]] = []
    for f in ("ekf", "ukf", "pf"):
        for mode in ("traditional", "improved"):
            key = f"{f}/{mode}"
            p, c = PAPER_TABLE2[key], s[key]
            rows.append([
                f"{'' if mode == 'traditional' else 'improved '}{f.upper()}",
                f"{p[0]:.2f} / {p[1]:.2f} / {p[2]:.2f}", _cell(c),
                f"{c['run_median_m']:.2f} [{c['run_p2_5_m']:.2f}–{c['run_p97_5_m']:.2f}]",
                f"{100 * c['solved_fraction']:.0f} %",
            ])  # fmt: skip
    head = [
        "algorithm",
        "paper",
        "ours (pooled over runs)",
        "ours 3D, median over runs [2.5–97.5 %]",
        "solved",
    ]
    L.append(markdown_table(rows, head))
    L.append("")
    L.append("## Every cell: node 2 RMS X / Y / Z (m), 3D, solved\n")
    rows = []
    for f in FILTERS:
        for mode in ("off", "traditional", "improved"):
            c, d = stats["clean"][f"{f}/{mode}"], stats["degraded"][f"{f}/{mode}"]
            rows.append([
                f.upper(), mode, _cell(c), f"{c['rms_3d_m']:.2f}", _cell(d), f"{d['rms_3d_m']:.2f}",
                f"{100 * c['solved_fraction']:.0f} / {100 * d['solved_fraction']:.0f} %",
            ])  # fmt: skip
    head = ["filter", "mode", "clean", "clean 3D", "degraded", "degraded 3D", "solved clean / degraded"]
    L.append(markdown_table(rows, head))
    L.append("")
    L.append("## Claims\n")
    L.append(
        "A claim `A < B` holds when A's pooled 3D RMS is more than 1 % below B's (closer is a tie); "
        "the last column is the fraction of seeds in which A's 3D RMS is below B's.\n"
    )
    rows = [
        [cl.name, cl.paper, "yes" if cl.holds else "NO", cl.evidence,
         "—" if not np.isfinite(cl.win_fraction) else f"{100 * cl.win_fraction:.0f} %"]
        for cl in claims
    ]  # fmt: skip
    head = ["claim", "paper", "holds here", "evidence (pooled 3D RMS)", "runs in which it holds"]
    L.append(markdown_table(rows, head))
    L.append("")
    L.append("## Node 1, and both nodes cooperating\n")
    rows = [
        [f.upper(), f"{n1['clean_rms_3d_m']:.2f} m", f"{n1['degraded_rms_3d_m']:.2f} m",
         f"{n1['degraded_fault_epochs_rms_3d_m']:.2f} m"]
        for f, n1 in extra["node1"].items()
    ]  # fmt: skip
    L.append(markdown_table(rows, ["filter", "node 1 alone clean", "degraded", "over the fault epochs"]))
    L.append("")
    rows = [
        [key, f"{mu['node1_rms_3d_m']:.2f} m", f"{mu['node2_rms_3d_m']:.2f} m"]
        for key, mu in extra["mutual"].items()
    ]
    head = ["filter / mode, both cooperating (clean)", "node 1 3D RMS", "node 2 3D RMS"]
    L.append(markdown_table(rows, head))
    L.append("")
    L.append("## Reading\n")
    L.extend(_reading(stats, extra))
    L.append("## Figures\n")
    for name, fn in figs.items():
        L.append(f"![{name}]({fn})\n")
    path = out / "report.md"
    path.write_text("\n".join(L), encoding="utf-8")
    return path


def _ratio(d: dict[str, Any], c: dict[str, Any], f: str, mode: str) -> str:
    return f"{d[f + '/' + mode]['rms_3d_m'] / c[f + '/' + mode]['rms_3d_m']:.2f}"


def _reading(stats: dict[str, dict[str, dict[str, Any]]], extra: dict[str, Any]) -> list[str]:
    """The report's reading of the numbers (each sentence computed from them)."""
    c = stats["clean"]
    r3 = {k: v["rms_3d_m"] for k, v in c.items()}
    spread = {k: v["run_p97_5_m"] - v["run_p2_5_m"] for k, v in c.items()}
    out = []
    ks = ("ekf/improved", "ukf/improved", "pf/improved")
    lo, hi = min(r3[k] for k in ks), max(r3[k] for k in ks)
    out.append(
        f"- Filters: the improved EKF, UKF and PF give node-2 3D RMS between {lo:.2f} and {hi:.2f} m, "
        f"while one filter's run-to-run 95 % range is {min(spread[k] for k in ks):.1f}–"
        f"{max(spread[k] for k in ks):.1f} m. With Gaussian "
        "pseudorange noise and an almost linear range "
        "model the three filters approximate the same posterior, so the paper's PF advantage (Table 2: "
        "3–6× lower RMS than EKF and UKF) is not a property "
        "of the algorithms on this data; it came from "
        "the paper's real indoor errors, which are not available.\n"
    )
    gain = {f: r3[f"{f}/off"] / r3[f"{f}/improved"] for f in ("ekf", "ukf", "pf")}
    out.append(
        "- Cooperation: node 2 alone vs improved cooperation, 3D RMS ratio "
        + ", ".join(f"{f.upper()} {g:.1f}×" for f, g in gain.items())
        + "; the range to node 1 removes the error along the baseline, the error across it stays "
        "(node 2's few satellites), which is why Y and Z dominate as in the paper's Table 2.\n"
    )
    n1 = extra["node1"]
    d = stats["degraded"]
    kf = ("ekf", "ukf", "pf")
    out.append(
        f"- Node 1's fault (+20 m on two of its {extra['node1_sats_mean']:.0f} satellites, 15 epochs) raises "
        "node 1's 3D RMS over the fault epochs to "
        + ", ".join(f"{f.upper()} {n1[f]['degraded_fault_epochs_rms_3d_m']:.2f} m" for f in kf)
        + " (clean: "
        + ", ".join(f"{n1[f]['clean_rms_3d_m']:.2f}" for f in kf)
        + " m), yet node 2's 3D RMS changes by a factor "
        + ", ".join(
            f"{f.upper()} {_ratio(d, c, f, 'traditional')} / {_ratio(d, c, f, 'improved')}" for f in kf
        )
        + " (traditional / improved)"
        + ": node 2's own error, from its few satellites, is larger than node 1's fault, and the range only "
        "fixes node 2 along the baseline. The issue's 1.5× line is met, but in both modes, so this fault "
        "does not show what the reset protects against; the next point does.\n"
    )
    mu = extra["mutual"]
    out.append(
        "- Where the reset matters: with both nodes "
        "cooperating, node 1 under `traditional` trusts a 2 cm "
        "range to node 2's broadcast position, which is wrong by metres; its 3D RMS goes from "
        + ", ".join(
            f"{f.upper()} {n1[f]['clean_rms_3d_m']:.2f} → {mu[f + '/traditional']['node1_rms_3d_m']:.2f} m"
            for f in ("ekf", "ukf", "pf")
        )
        + "; `improved` (range σ̂² = σ² + tr(P_reset)) gives "
        + ", ".join(f"{mu[f + '/improved']['node1_rms_3d_m']:.2f}" for f in ("ekf", "ukf", "pf"))
        + " m. σ_set comes from the scatter of the peer's broadcasts in a short window, not from its bias, "
        "so the protection is partial: node 1 is still worse than alone.\n"
    )
    out.append(
        "- UKF, traditional vs improved: "
        f"{c['ukf/traditional']['rms_3d_m']:.2f} vs {c['ukf/improved']['rms_3d_m']:.2f} m. With α = 1 the "
        "sigma points sit ±√n σ from the prior mean; while node 2's σ is metres and the baseline 6.5 m, the "
        "spread of the predicted range over the sigma points is far above either range variance (2 cm or "
        "σ̂ ≈ 1 m), so the innovation covariance S, and with it the correction, hardly depends on it.\n"
    )
    ls = c["ls/improved"]
    out.append(
        "- LS with the range row is solved at "
        f"{100 * ls['solved_fraction']:.0f} % of the epochs: per-epoch "
        "Gauss–Newton with a 2 cm range to a point 6.5 m away "
        "and metre-level pseudorange residuals does not "
        "converge (the range sphere's curvature is large "
        "against the residuals); the filters, which carry the "
        "prior, do not have this problem.\n"
    )
    return out


__all__ = ["make_figures", "write_report"]
