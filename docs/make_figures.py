"""Figures of the README, made from a shared dataset.

Runs RTK (the ``rtk`` preset for RINEX, as ``robustrtk solve --mode rtk`` does) on
``kamakura_kinematic_5km`` (a car, 4 laps of a ~125 m loop, 5.36 km baseline) and writes
``docs/img/kamakura_rtk.png``: the ground track coloured by status, and the horizontal and
vertical errors of robustrtk and of RTKLIB's fix-and-hold run (``rtklib/fh.pos``) against
RTKLIB's forward-backward trajectory (``rtklib/pseudoref_comb_fh_traj.txt``, not
independent).

Usage::

    python docs/make_figures.py [--data ../shared/data] [--out docs/img/kamakura_rtk.png]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from robustrtk.eval.comparison import Q_OF_STATUS, compare_solution, load_solution
from robustrtk.eval.plots import Q_STYLE, figure, save_figure
from robustrtk.eval.truth import read_truth_file
from robustrtk.geometry.frames import ecef2enu_rotation, ecef2geodetic
from robustrtk.io.solution import SolutionTable
from robustrtk.pipeline.config import preset
from robustrtk.pipeline.rtk_gnss import solve_rtk

ROOT = Path(__file__).resolve().parents[1]


def _base_xyz(path: Path) -> np.ndarray:
    for line in path.read_text().splitlines():
        if line.startswith("base_xyz"):
            return np.array([float(v) for v in line.split()[1:4]])
    raise SystemExit(f"{path}: no base_xyz line")


def kamakura_figure(data: Path, out: Path) -> Path:
    """Solve kamakura with RTK and write the figure; returns its path."""
    d = data / "kamakura_kinematic_5km"
    base = _base_xyz(d / "truth_and_base.txt")
    res = solve_rtk(d / "SEPT265G.21O", d / "3034265G.21O", d / "SEPT2650.21P", base, preset("rtk", "gnss"))
    ours = SolutionTable.from_solutions(s for s in res.solutions if s.status != "none")
    q_ours = np.array([Q_OF_STATUS[str(s)] for s in ours.status])
    theirs, q_theirs = load_solution(d / "rtklib" / "fh.pos")
    truth = read_truth_file(d / "rtklib" / "pseudoref_comb_fh_traj.txt")
    runs = [("robustrtk RTK", ours, q_ours), ("RTKLIB fix-and-hold", theirs, q_theirs)]
    cmps = [compare_solution(tb, q, truth, label=lab) for lab, tb, q in runs]

    fig = figure(11.0, 4.6)
    grid = fig.add_gridspec(2, 2, width_ratios=(1.0, 1.35))
    a_track = fig.add_subplot(grid[:, 0])
    a_h = fig.add_subplot(grid[0, 1])
    a_v = fig.add_subplot(grid[1, 1], sharex=a_h)
    origin = np.median(ours.pos_m, axis=0)
    lat, lon, _ = ecef2geodetic(origin)
    rot = ecef2enu_rotation(float(lat), float(lon))
    pos = ours.pos_m[np.argsort(ours.t_s)]
    enu = (pos - origin) @ rot.T
    a_track.plot(enu[:, 0], enu[:, 1], "-", lw=0.4, color="0.7")
    for qv, (colour, name) in Q_STYLE.items():
        sel = cmps[0].q == qv
        if np.any(sel):
            a_track.plot(
                enu[sel, 0], enu[sel, 1], ".", ms=3, color=colour, label=f"{name} ({int(sel.sum())})"
            )
    a_track.set_aspect("equal", adjustable="datalim")
    a_track.set_xlabel("East (m)")
    a_track.set_ylabel("North (m)")
    a_track.set_title("robustrtk RTK: ground track by status", fontsize=10)
    a_track.legend(fontsize=8, markerscale=3)
    a_track.grid(True, alpha=0.3)
    t0 = float(min(c.t_s[0] for c in cmps))
    for c, style in zip(cmps, ("-", "--"), strict=True):
        e = c.enu_err_m * 100.0
        fixed = c.fix_rate_pct_of_solved
        a_h.plot(c.t_s - t0, np.hypot(e[:, 0], e[:, 1]), style, lw=0.9,
                 label=f"{c.label}: {fixed:.1f} % fixed, first fix {c.ttff_s:.0f} s")  # fmt: skip
        a_v.plot(c.t_s - t0, e[:, 2], style, lw=0.9)
    a_h.set_ylim(0, 20)
    a_v.set_ylim(-20, 20)
    a_h.set_ylabel("horizontal (cm)")
    a_v.set_ylabel("vertical (cm)")
    a_v.set_xlabel("Time since start (s)")
    a_h.set_title("Error against RTKLIB's forward-backward trajectory", fontsize=10)
    a_h.legend(fontsize=8)
    for ax in (a_h, a_v):
        ax.grid(True, alpha=0.3)
    fig.suptitle("kamakura_kinematic_5km: a car, 5.36 km baseline, GPS+Galileo+QZSS L1/L2, 1 Hz", fontsize=11)
    return save_figure(fig, out, dpi=80)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data")
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "img" / "kamakura_rtk.png")
    args = ap.parse_args()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    path = kamakura_figure(args.data, args.out)
    print(f"wrote {path} ({path.stat().st_size / 1024:.0f} kB)")


if __name__ == "__main__":
    main()
