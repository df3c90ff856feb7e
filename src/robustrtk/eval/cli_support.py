"""What ``robustrtk evaluate`` and ``robustrtk demo`` print and plot.

Kept out of the CLI so the same text can be produced (and tested) from Python.
"""

from __future__ import annotations

import csv
import os
from pathlib import Path

import numpy as np

from robustrtk.core import FloatArray, InputError
from robustrtk.eval.metrics import error_stats, position_errors, sigma_coverage
from robustrtk.eval.report import format_table
from robustrtk.eval.situations import epoch_situations, situation_counts, situation_mean_abs_errors
from robustrtk.eval.truth import read_truth_file
from robustrtk.io.solution import (
    DiagTable,
    SolutionTable,
    read_diagnostics_csv,
    read_pos,
    read_solution_csv,
    write_diagnostics_csv,
    write_solution_csv,
)


def read_truth_csv(path: str | os.PathLike[str]) -> tuple[FloatArray, FloatArray]:
    """Read ``time,x,y,z`` (m) → ``(t_s (T,), pos_m (T, 3))``."""
    p = Path(path)
    t: list[float] = []
    xyz: list[list[float]] = []
    with p.open(newline="", encoding="utf-8") as fh:
        reader = csv.reader(fh)
        header = next(reader, None)
        want = ["time", "x", "y", "z"]
        if header is None or [h.strip() for h in header[:4]] != want:
            raise InputError(f"expected header 'time,x,y,z', got {header!r}", str(p), 1)
        for i, row in enumerate(reader, start=2):
            if not row:
                continue
            try:
                vals = [float(v) for v in row[:4]]
            except ValueError:
                raise InputError(f"expected 4 numbers (time,x,y,z), got {row!r}", str(p), i) from None
            if len(vals) != 4:
                raise InputError(f"expected 4 numbers (time,x,y,z), got {row!r}", str(p), i)
            t.append(vals[0])
            xyz.append(vals[1:])
    if not t:
        raise InputError("no truth rows", str(p))
    return np.array(t), np.array(xyz)


def read_solution(path: str | os.PathLike[str]) -> SolutionTable:
    """Our CSV or an RTKLIB ``.pos`` file, by extension."""
    return read_pos(path) if str(path).lower().endswith(".pos") else read_solution_csv(path)


def contaminated_epochs(faults_path: str | os.PathLike[str]) -> dict[str, FloatArray]:
    """Epoch times of the simulated faults: ``{"large": t, "small": t, "phase": t}``.

    Code errors of 5 m and more are "large", smaller code errors "small" (bursts).
    """
    out: dict[str, list[float]] = {"large": [], "small": [], "phase": []}
    with Path(faults_path).open(newline="", encoding="utf-8") as fh:
        for row in csv.DictReader(fh):
            if row.get("kind", "gross") != "gross":
                continue
            t = float(row["time"])
            if row["observable"] == "phase":
                out["phase"].append(t)
            elif abs(float(row["size"])) >= 5.0:
                out["large"].append(t)
            else:
                out["small"].append(t)
    return {k: np.unique(np.array(v, float)) for k, v in out.items()}


def _stats_rows(name: str, err: FloatArray) -> list[list[object]]:
    s = error_stats(err)
    return [
        [
            name,
            int(s["n"]),
            s["mean_abs_x_m"],
            s["mean_abs_y_m"],
            s["mean_abs_z_m"],
            s["rms_3d_m"],
            s["p95_3d_m"],
            s["max_3d_m"],
        ]
    ]


STAT_HEADERS = ["solution", "epochs", "mean|x| m", "mean|y| m", "mean|z| m", "3D RMS m", "3D p95 m", "max m"]


ENU_STAT_HEADERS = [
    "solution",
    "epochs",
    "mean|E| m",
    "mean|N| m",
    "mean|U| m",
    "3D RMS m",
    "3D p95 m",
    "max m",
]


def frame_errors(sol: SolutionTable, truth_path: str | os.PathLike[str]) -> FloatArray:
    """Errors (T, 3) of ``sol`` against a truth file in the solution's own frame (ECEF for
    GNSS), the frame of its ``std_m``: what the σ coverage compares (ENU errors against ECEF
    σ would mix the axes)."""
    with open(truth_path, encoding="utf-8", errors="replace") as fh:
        first = fh.readline()
    if [h.strip() for h in first.split(",")[:4]] == ["time", "x", "y", "z"]:
        t_truth, p_truth = read_truth_csv(truth_path)
        return position_errors(sol, t_truth, p_truth)
    return read_truth_file(truth_path).frame_errors(sol.t_s, sol.pos_m)


def solution_errors(sol: SolutionTable, truth_path: str | os.PathLike[str]) -> tuple[FloatArray, list[str]]:
    """Errors (T, 3) of ``sol`` against a truth file and the table headers that name their axes.

    A ``time,x,y,z`` CSV (the simulator's ``truth.csv``) gives errors in the solution's own
    frame, matched within 5 ms; any other truth that :func:`robustrtk.eval.truth.read_truth_file`
    reads (a point, a ``.pos``, GSDC ``ground_truth.csv``, NMEA GGA, ``time,lat,lon,h``) gives
    ECEF solutions' errors in East, North, Up at the truth.
    """
    with open(truth_path, encoding="utf-8", errors="replace") as fh:
        first = fh.readline()
    if [h.strip() for h in first.split(",")[:4]] == ["time", "x", "y", "z"]:
        t_truth, p_truth = read_truth_csv(truth_path)
        return position_errors(sol, t_truth, p_truth), STAT_HEADERS
    truth = read_truth_file(truth_path)
    return truth.enu_errors(sol.t_s, sol.pos_m), ENU_STAT_HEADERS


def evaluate_files(
    sol_path: str,
    truth_path: str,
    diag_path: str | None = None,
    faults_path: str | None = None,
    plots_dir: str | None = None,
) -> str:
    """Text report of one solution against the truth (and its diagnostics)."""
    sol = read_solution(sol_path)
    err, headers = solution_errors(sol, truth_path)
    lines = [format_table(_stats_rows(Path(sol_path).name, err), headers)]
    status, counts = np.unique(sol.status, return_counts=True)
    lines.append("status: " + ", ".join(f"{s} {c}" for s, c in zip(status, counts, strict=True)))
    cov = coverage_text(sol, frame_errors(sol, truth_path))
    if cov:
        lines += ["", cov]
    diag: DiagTable | None = read_diagnostics_csv(diag_path) if diag_path else None
    if diag is not None and len(diag):
        lines.append("")
        lines.append(_situation_text(diag, {Path(sol_path).name: (sol.t_s, err)}))
    if faults_path:
        lines.append("")
        lines.append(_fault_text(faults_path, sol.t_s, {Path(sol_path).name: err}))
    if plots_dir:
        written = _plots(plots_dir, {Path(sol_path).name: (sol.t_s, err)}, diag)
        lines.append("")
        lines.append("plots: " + ", ".join(str(p) for p in written))
    return "\n".join(lines)


COVERAGE_HEADERS = ["status", "epochs", "|x| ≤ 3σx %", "|y| ≤ 3σy %", "|z| ≤ 3σz %", "all three %"]


def coverage_text(sol: SolutionTable, err: FloatArray) -> str:
    """The σ-coverage table: per status, the share of epochs whose error is within 3σ
    on each axis of the solution's frame (ECEF for GNSS) and on all three
    (:func:`~robustrtk.eval.metrics.sigma_coverage`); empty when the file gives no σ."""
    rows: list[list[object]] = []
    for st in [*dict.fromkeys(sol.status.tolist()), "all"]:
        sel = np.ones(len(sol), bool) if st == "all" else sol.status == st
        c = sigma_coverage(err[sel], sol.std_m[sel])
        if c["n"] > 0:
            rows.append([st, int(c["n"]), *(100.0 * c[k] for k in ("axis0", "axis1", "axis2", "all"))])
    if not rows:
        return ""
    return "σ coverage (reported σ against the error)\n" + format_table(rows, COVERAGE_HEADERS)


def _situation_text(diag: DiagTable, errors: dict[str, tuple[FloatArray, FloatArray]]) -> str:
    counts = situation_counts(diag)
    rows = [[lab, *c] for lab, c in counts.items()]
    out = [
        "Epochs per situation (Li et al. Table 1: #1 normal, #2 down-weighted, #3 rejected)",
        format_table(rows, ["DD", "#1", "#2", "#3"]),
    ]
    et, es = epoch_situations(diag)
    mae = situation_mean_abs_errors(et, es, errors)
    rows2 = []
    for name, by in mae.items():
        for sit in (1, 2, 3):
            v = by.get(sit)
            if v is not None and np.all(np.isfinite(v)):
                rows2.append([name, f"#{sit}", *v])
    out += [
        "",
        "Mean |error| per situation (Li et al. Fig. 6)",
        format_table(rows2, ["solution", "situation", "|x| m", "|y| m", "|z| m"]),
    ]
    return "\n".join(out)


def _fault_text(faults_path: str, t_s: FloatArray, errors: dict[str, FloatArray]) -> str:
    groups = contaminated_epochs(faults_path)
    contaminated = np.isin(t_s, np.concatenate(list(groups.values())))
    rows = []
    for name, err in errors.items():
        e3 = np.linalg.norm(err, axis=1)
        clean = e3[~contaminated & np.isfinite(e3)]
        row: list[object] = [name, float(np.percentile(clean, 95)) if clean.size else float("nan")]
        for key in ("large", "small", "phase"):
            sel = np.isin(t_s, groups[key])
            if not sel.any():
                row += [float("nan"), float("nan")]
                continue
            row += [float(np.percentile(e3[sel], 95)), _extra_on(e3, contaminated, sel)]
        rows.append(row)
    return (
        "3D errors on the epochs with injected faults (sim/faults.csv): large = code faults of 5 m "
        "or more, small = smaller code faults, phase = carrier-phase faults; p95 = 95th percentile "
        "of the 3D error (m); extra = mean of the 3D error minus that at the last fault-free epoch "
        "before it (m): what the faults added\n"
        + format_table(
            rows,
            [
                "solution",
                "p95 clean m",
                "p95 large-fault m",
                "extra large-fault m",
                "p95 small-fault m",
                "extra small-fault m",
                "p95 phase-fault m",
                "extra phase-fault m",
            ],
        )
    )


def _extra_on(e3: FloatArray, contaminated: np.ndarray, sel: np.ndarray) -> float:
    """Mean of ``e3[i] − e3[last clean before i]`` over the epochs ``sel``."""
    vals = []
    last = -1
    for i in range(e3.size):
        if not contaminated[i]:
            last = i
        elif sel[i] and last >= 0:
            vals.append(e3[i] - e3[last])
    return float(np.mean(vals)) if vals else float("nan")


def _plots(
    plots_dir: str, errors: dict[str, tuple[FloatArray, FloatArray]], diag: DiagTable | None
) -> list[Path]:
    from robustrtk.eval.plots import plot_dd_diagnostics, plot_error_series, save_figure

    d = Path(plots_dir)
    d.mkdir(parents=True, exist_ok=True)
    written = [save_figure(plot_error_series(errors, title="Positioning error"), d / "errors.png")]
    if diag is not None and len(diag):
        written.append(save_figure(plot_dd_diagnostics(diag), d / "residuals_dv.png"))
    return written


def run_demo(out_dir: str, seed: int = 1) -> str:
    """Simulate the ``demo`` room, solve it with SUKF and RUKF, compare, plot."""
    from robustrtk.eval.plots import plot_dd_diagnostics, plot_error_series, save_figure
    from robustrtk.pipeline.config import Config
    from robustrtk.pipeline.solve import solve_pseudolite
    from robustrtk.sim.files import run_simulate

    out = Path(out_dir)
    sim_dir = out / "sim"
    run_simulate("demo", seed, sim_dir)
    t_truth, p_truth = read_truth_csv(sim_dir / "truth.csv")
    lines = [f"simulated the 'demo' room (seed {seed}) into {sim_dir}", ""]
    errors: dict[str, tuple[FloatArray, FloatArray]] = {}
    err_only: dict[str, FloatArray] = {}
    rows: list[list[object]] = []
    diag_rukf: DiagTable | None = None
    for mode in ("dpl", "rtk"):
        for name, robust, ar in (("SUKF", "none", "lambda"), ("RUKF", "igg3", "par")):
            label = f"{mode.upper()} {name}" + ("+PAR" if mode == "rtk" and ar == "par" else "")
            cfg = Config.of(mode=mode, robust=robust, ar=ar, dynamics="kinematic")
            res = solve_pseudolite(sim_dir / "obs.csv", sim_dir / "site.toml", cfg)
            stem = label.lower().replace(" ", "_").replace("+", "_")
            write_solution_csv(res.solutions, out / f"{stem}.csv")
            diag_rows = [
                (d.t_s, d.dd, d.innovation, d.residual, d.std_residual, d.dv, d.factor, d.situation)
                for d in res.diagnostics
            ]
            write_diagnostics_csv(diag_rows, out / f"{stem}_diag.csv")
            sol = SolutionTable.from_solutions(res.solutions)
            err = position_errors(sol, t_truth, p_truth)
            errors[label] = (sol.t_s, err)
            err_only[label] = err
            rows += _stats_rows(label, err)
            if mode == "dpl" and robust == "igg3":
                diag_rukf = read_diagnostics_csv(out / f"{stem}_diag.csv")
    lines.append("Kinematic solutions of a static rover (every epoch counts), errors vs truth:")
    lines.append(format_table(rows, STAT_HEADERS))
    lines.append("")
    lines.append(
        _fault_text(
            str(sim_dir / "faults.csv"),
            errors["DPL SUKF"][0],
            {k: v for k, v in err_only.items() if k.startswith("DPL")},
        )
    )
    plots = out / "plots"
    plots.mkdir(parents=True, exist_ok=True)
    written = [
        save_figure(
            plot_error_series(
                {k: v for k, v in errors.items() if k.startswith("DPL")}, title="DPL: SUKF vs RUKF error"
            ),
            plots / "dpl_errors.png",
        ),
        save_figure(
            plot_error_series(
                {k: v for k, v in errors.items() if k.startswith("RTK")}, title="RTK: SUKF vs RUKF+PAR error"
            ),
            plots / "rtk_errors.png",
        ),
    ]
    if diag_rukf is not None:
        written.append(
            save_figure(
                plot_dd_diagnostics(diag_rukf, title="DPL RUKF: residuals and Δv̄"),
                plots / "dpl_rukf_residuals_dv.png",
            )
        )
    lines.append("")
    lines.append("plots: " + ", ".join(str(p) for p in written))
    return "\n".join(lines)
