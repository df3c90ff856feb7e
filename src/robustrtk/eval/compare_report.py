"""Plain-text tables and the JSON report of a solution comparison."""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from typing import Any

from robustrtk.eval.comparison import ERR_3D_THRESHOLD_M, GROUPS, SolutionComparison
from robustrtk.eval.truth import MATCH_TOL_S, PathLike, Truth
from robustrtk.io.atomic import atomic_path
from robustrtk.io.tables import format_table
from robustrtk.timeutil import gpst_text

__all__ = [
    "DETAIL_HEADERS",
    "SUMMARY_HEADERS",
    "comparison_report",
    "detail_table",
    "summary_table",
    "write_json",
]


def _cm(v: float | None) -> str:
    return "-" if v is None or not math.isfinite(v) else f"{100.0 * v:.2f}"


def _pct(v: float | None) -> str:
    return "-" if v is None or not math.isfinite(v) else f"{v:.2f}"


def _label_left(headers: Sequence[str]) -> str:
    """The label column left-aligned, the numbers right-aligned (``-`` cells too)."""
    return "l" + "r" * (len(headers) - 1)


_HV_KEYS = ("H_rms_m", "H_95_m", "V_rms_m", "V_95_m")


def _q_text(hist: Mapping[int, int]) -> str:
    return " ".join(f"{k}:{v}" for k, v in sorted(hist.items()))


SUMMARY_HEADERS = (
    "solution", "solved", "Q hist", "fix %", "fix % rover", "TTFF s",
    "fix n", "fix H rms", "fix H 95", "fix V rms", "fix V 95",
    "all n", "all H rms", "all H 95", "all V rms", "all V 95", "3D>10cm",
)  # fmt: skip


def summary_table(results: Sequence[SolutionComparison]) -> str:
    """One row per solution: epochs, Q histogram, fix rates (%), time to first fix (s),
    fixed-epoch and all-epoch H/V RMS and 95 % (cm), all-epoch count of 3-D errors > 10 cm."""
    rows = []
    for r in results:
        fx, al = r.groups.get("fixed"), r.groups.get("all")
        ttff = r.ttff_s
        rows.append([
            r.label, str(r.epochs_solved), _q_text(r.q_hist), _pct(r.fix_rate_pct_of_solved),
            _pct(r.fix_rate_pct_of_rover_epochs), "-" if ttff is None else f"{ttff:.0f}",
            str(fx["n"]) if fx else "0", *(_cm(fx[k] if fx else None) for k in _HV_KEYS),
            str(al["n"]) if al else "0", *(_cm(al[k] if al else None) for k in _HV_KEYS),
            str(al["n_3d_err_gt_0.10m"]) if al else "-",
        ])  # fmt: skip
    return format_table(rows, SUMMARY_HEADERS, align=_label_left(SUMMARY_HEADERS)) + (
        "\n(errors in cm; fix % of solved and of rover epochs)"
    )


DETAIL_HEADERS = ("solution", "epochs", "n", "H rms", "H 95", "V rms", "V 95", "mean E", "mean N",
                  "mean U", "H max", "V max", "3D>10cm")  # fmt: skip


def detail_table(results: Sequence[SolutionComparison]) -> str:
    """Rows per solution and group (fixed, float, all): n, H/V RMS and 95 %, mean ENU, H/V
    max (cm) and the count of 3-D errors above 10 cm."""
    rows = []
    for r in results:
        for name, _ in GROUPS:
            g = r.groups.get(name)
            if g is None:
                rows.append([r.label, name, "0", *("-" for _ in range(10))])
                continue
            rows.append([
                r.label, name, str(g["n"]),
                *(_cm(g[k]) for k in _HV_KEYS),
                *(_cm(v) for v in g["mean_enu_m"]), _cm(g["H_max_m"]), _cm(g["V_max_m"]),
                str(g["n_3d_err_gt_0.10m"]),
            ])  # fmt: skip
    return format_table(rows, DETAIL_HEADERS, align=_label_left(DETAIL_HEADERS)) + "\n(cm)"


def comparison_report(
    results: Sequence[SolutionComparison],
    truth: Truth | None,
    window_s: tuple[float, float] | None = None,
    tol_s: float = MATCH_TOL_S,
) -> dict[str, Any]:
    """Machine-readable summary: truth description, window, tolerances and one entry per
    solution (:meth:`SolutionComparison.to_dict`; full precision, metres, NaN as null)."""
    truth_d: dict[str, Any] | None = None
    if truth is not None:
        truth_d = {"source": truth.source, "kind": "point" if truth.is_point else "trajectory",
                   "frame": "ecef" if truth.ecef else "local", "note": truth.note}  # fmt: skip
        if truth.is_point:
            truth_d["pos_m"] = [float(v) for v in truth.pos_m.reshape(3)]
        else:
            truth_d["epochs"] = int(truth.pos_m.shape[0])
    return {
        "truth": truth_d,
        "truth_window": None if window_s is None else [gpst_text(window_s[0]), gpst_text(window_s[1])],
        "truth_window_s": None if window_s is None else [float(window_s[0]), float(window_s[1])],
        "match_tol_s": tol_s,
        "err_3d_threshold_m": ERR_3D_THRESHOLD_M,
        "percentile_method": "linear",
        "solutions": [r.to_dict() for r in results],
    }


def write_json(report: Mapping[str, Any], path: PathLike) -> None:
    """Write ``report`` as indented JSON (temporary file, then rename)."""
    text = json.dumps(report, indent=1, allow_nan=False)
    with atomic_path(path) as tmp, open(tmp, "w", encoding="utf-8") as fh:
        fh.write(text + "\n")
