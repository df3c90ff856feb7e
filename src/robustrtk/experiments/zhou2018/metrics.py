"""Statistics and claims of the Zhou et al. (2018) reproduction, computed from the per-run
arrays saved in ``runs.npz`` (so that the tests can recount them independently).

``err[scenario][filter/mode]`` has shape ``(R, T, 3)``: node 2's ECEF error (m) per run and
epoch, NaN where not solved. The paper's Table 2 statistic is the RMS per ECEF axis,
``RMS_j = sqrt(mean over solved epochs of all runs of e_j²)``; we add the 3D RMS
``sqrt(RMS_X² + RMS_Y² + RMS_Z²)``, the solved fraction, and the per-run 3D RMS (median and
2.5/97.5 percentiles over runs).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from robustrtk.core import FloatArray

FILTERS = ("ls", "ekf", "ukf", "pf")
MODES = ("off", "traditional", "improved")
SCENARIOS = ("clean", "degraded")
#: Filters also run with both nodes cooperating (``mutual``, clean sessions).
MUTUAL_FILTERS = ("ekf", "ukf", "pf")

#: Zhou et al. Table 2, RMS (m) of node 2 per ECEF axis.
PAPER_TABLE2: dict[str, tuple[float, float, float]] = {
    "ekf/traditional": (1.6253, 6.1874, 5.9892),
    "ekf/improved": (1.5069, 5.9032, 5.7957),
    "ukf/traditional": (1.5263, 4.8993, 5.8034),
    "ukf/improved": (1.4356, 4.7023, 5.6344),
    "pf/traditional": (0.3652, 2.3016, 1.9069),
    "pf/improved": (0.3078, 2.1831, 1.7849),
}


def axis_rms(err: FloatArray) -> FloatArray:
    """RMS per axis over all finite rows of ``err`` (..., 3) → (3,)."""
    e = np.asarray(err, float).reshape(-1, 3)
    e = e[np.all(np.isfinite(e), axis=1)]
    if e.shape[0] == 0:
        return np.full(3, np.nan)
    out: FloatArray = np.sqrt(np.mean(e**2, axis=0))
    return out


def cell_stats(err: FloatArray) -> dict[str, Any]:
    """Statistics of one (scenario, filter, mode) cell from ``err`` (R, T, 3)."""
    rms = axis_rms(err)
    solved = np.all(np.isfinite(err), axis=2)
    per_run = [float(np.linalg.norm(axis_rms(e))) for e in err]
    pr = np.array(per_run)
    fin = pr[np.isfinite(pr)]
    return {
        "rms_xyz_m": [float(v) for v in rms],
        "rms_3d_m": float(np.linalg.norm(rms)),
        "solved_fraction": float(solved.mean()),
        "per_run_rms_3d_m": per_run,
        "run_median_m": float(np.median(fin)) if fin.size else float("nan"),
        "run_p2_5_m": float(np.percentile(fin, 2.5)) if fin.size else float("nan"),
        "run_p97_5_m": float(np.percentile(fin, 97.5)) if fin.size else float("nan"),
    }


def all_stats(err: dict[str, dict[str, FloatArray]]) -> dict[str, dict[str, dict[str, Any]]]:
    """:func:`cell_stats` of every cell: ``stats[scenario]["filter/mode"]``."""
    return {sc: {key: cell_stats(e) for key, e in cells.items()} for sc, cells in err.items()}


def node1_and_mutual_stats(npz: Any) -> dict[str, Any]:
    """Node 1's 3D RMS alone per filter (clean, degraded, and over the fault epochs), and
    both nodes' 3D RMS when both cooperate (``mutual``), from the arrays of ``runs.npz``."""
    out: dict[str, Any] = {"node1": {}, "mutual": {}, "node1_sats_mean": float(np.mean(npz["clean/n_sats1"]))}
    fault = np.asarray(npz["degraded/fault1"], bool)  # (R, T)
    for f in FILTERS:
        e_c = npz[f"clean/{f}/off/pos1"] - npz["clean/truth1"][:, None, :]
        e_d = npz[f"degraded/{f}/off/pos1"] - npz["degraded/truth1"][:, None, :]
        out["node1"][f] = {
            "clean_rms_3d_m": float(np.linalg.norm(axis_rms(e_c))),
            "degraded_rms_3d_m": float(np.linalg.norm(axis_rms(e_d))),
            "degraded_fault_epochs_rms_3d_m": float(np.linalg.norm(axis_rms(e_d[fault]))),
        }
    for f in MUTUAL_FILTERS:
        for m in ("traditional", "improved"):
            e1 = npz[f"mutual/{f}/{m}/pos1"] - npz["clean/truth1"][:, None, :]
            e2 = npz[f"mutual/{f}/{m}/pos2"] - npz["clean/truth2"][:, None, :]
            out["mutual"][f"{f}/{m}"] = {
                "node1_rms_3d_m": float(np.linalg.norm(axis_rms(e1))),
                "node2_rms_3d_m": float(np.linalg.norm(axis_rms(e2))),
            }
    return out


@dataclass(frozen=True)
class Claim:
    """One claim of the paper, whether it holds here, and the numbers that say so."""

    name: str
    paper: str
    holds: bool
    evidence: str
    win_fraction: float


#: A claim ``A < B`` holds when A's pooled 3D RMS is below ``(1 − TIE) ×`` B's (a 1 % tie band).
TIE = 0.01


def _lt(stats: dict[str, dict[str, Any]], a: str, b: str) -> bool:
    ra, rb = stats[a]["rms_3d_m"], stats[b]["rms_3d_m"]
    return bool(np.isfinite(ra) and np.isfinite(rb) and ra < (1.0 - TIE) * rb)


def _wins(stats: dict[str, dict[str, Any]], a: str, b: str) -> float:
    ra = np.array(stats[a]["per_run_rms_3d_m"], float)
    rb = np.array(stats[b]["per_run_rms_3d_m"], float)
    ok = np.isfinite(ra) & np.isfinite(rb)
    return float(np.mean(ra[ok] < rb[ok])) if ok.any() else float("nan")


def _ev(stats: dict[str, dict[str, Any]], *keys: str) -> str:
    return ", ".join(f"{k} {stats[k]['rms_3d_m']:.2f} m" for k in keys)


def build_claims(stats: dict[str, dict[str, dict[str, Any]]], extra: dict[str, Any]) -> list[Claim]:
    """The paper's claims, each on the pooled 3D RMS of node 2 (``holds``) with the fraction
    of runs in which it holds (``win_fraction``, pairs of cells on the same seed); the
    reset claims of issue #12; and, with both nodes cooperating (``extra["mutual"]``), that
    the improved algorithm keeps node 1 closer to its solution alone than the traditional."""
    out: list[Claim] = []
    for sc in SCENARIOS:
        s = stats[sc]
        for mode in ("traditional", "improved"):
            pf, ekf, ukf = f"pf/{mode}", f"ekf/{mode}", f"ukf/{mode}"
            holds = _lt(s, pf, ekf) and _lt(s, pf, ukf)
            wins = min(_wins(s, pf, ekf), _wins(s, pf, ukf))
            out.append(Claim(f"PF best ({mode}, {sc})", "PF < UKF, EKF", holds, _ev(s, pf, ukf, ekf), wins))
            out.append(
                Claim(
                    f"UKF better than EKF ({mode}, {sc})",
                    "UKF < EKF",
                    _lt(s, ukf, ekf),
                    _ev(s, ukf, ekf),
                    _wins(s, ukf, ekf),
                )
            )
        for f in FILTERS:
            a, b = f"{f}/improved", f"{f}/traditional"
            out.append(
                Claim(
                    f"improved better than traditional ({f}, {sc})",
                    "improved < traditional",
                    _lt(s, a, b),
                    _ev(s, a, b),
                    _wins(s, a, b),
                )
            )
    for f in ("ekf", "ukf", "pf"):
        clean = stats["clean"][f"{f}/improved"]["rms_3d_m"]
        deg = stats["degraded"][f"{f}/improved"]["rms_3d_m"]
        tc = stats["clean"][f"{f}/traditional"]["rms_3d_m"]
        td = stats["degraded"][f"{f}/traditional"]["rms_3d_m"]
        ratio = deg / clean if clean > 0 else float("nan")
        out.append(
            Claim(
                f"reset protects node 2 from node 1's fault ({f})",
                "improved degraded ≤ 1.5 × improved clean (issue #12)",
                bool(np.isfinite(ratio) and ratio <= 1.5),
                f"improved {clean:.2f} → {deg:.2f} m (× {ratio:.2f}); "
                f"traditional {tc:.2f} → {td:.2f} m (× {td / tc:.2f})",
                float("nan"),
            )
        )
    for f in MUTUAL_FILTERS:
        tr = extra["mutual"][f"{f}/traditional"]["node1_rms_3d_m"]
        im = extra["mutual"][f"{f}/improved"]["node1_rms_3d_m"]
        alone = extra["node1"][f]["clean_rms_3d_m"]
        out.append(
            Claim(
                f"improved limits the mutual influence on node 1 ({f}, both cooperating)",
                "improved < traditional (node 1)",
                bool(im < (1.0 - TIE) * tr),
                f"node 1 alone {alone:.2f} m, traditional {tr:.2f} m, improved {im:.2f} m",
                float("nan"),
            )
        )
    return out


__all__ = [
    "FILTERS",
    "MODES",
    "MUTUAL_FILTERS",
    "PAPER_TABLE2",
    "SCENARIOS",
    "TIE",
    "Claim",
    "all_stats",
    "axis_rms",
    "build_claims",
    "cell_stats",
    "node1_and_mutual_stats",
]
