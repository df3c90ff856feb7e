"""Speed and memory of the robust batch smoother (``solve --mode spp --fgo``).

Two tracks, each solved in its own process (peak RSS = that process's ``ru_maxrss``):

* ``pixel5``: the shared Pixel 5 GSDC 2021 drive (1985 epochs at 1 Hz, GPS L1+L5).
* ``sim-1h``: one hour at 1 Hz (3600 epochs) of the same satellites, simulated from the
  drive's broadcast navigation file by the software receiver of :mod:`robustrtk.sim.drive`
  (broadcast clocks, group delays and atmosphere): a receiver driving a 600-m circle at
  12 m/s, code with 3 m white noise plus a 1.5 m Gauss–Markov multipath term (60 s), carrier phase with
  5 mm noise and an arbitrary integer offset per satellite and band, Doppler (receiver and
  satellite motion, satellite clock drift) with 0.1 m/s noise, a receiver clock drifting
  100 m/s; satellites below 10° are absent. The Doppler agrees with the phase, so the arcs
  run unbroken and the TDCP rows are in the problem.

Printed: the TDCP rows, wall time of the smoother (reading excluded), its Gauss–Newton iterations and the
peak RSS of the process. No timing is asserted anywhere; this is a measurement.

Usage::

    python bench/bench_fgo.py [--data DIR] [--track pixel5|sim-1h|all]
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
PIXEL = "gsdc2021_mtv1_pixel5_phone/Pixel5/supplemental"


def _default_data() -> Path:
    env = os.environ.get("ROBUSTRTK_SHARED_DATA")
    return Path(env) if env else REPO.parent / "shared" / "data"


def _simulated_hour(batch: object, eph: object, seconds: int = 3600) -> object:
    """The drive's batch layout filled with one simulated hour (module docstring)."""
    from robustrtk.geometry.frames import ecef2enu_rotation, ecef2geodetic
    from robustrtk.sim.drive import simulate_drive

    b = batch
    t = float(b.t_s[0]) + np.arange(seconds, dtype=float)  # type: ignore[attr-defined]
    centre = np.array([-2694685.473, -4293642.366, 3857878.924])  # Mountain View
    lat, lon, _ = ecef2geodetic(centre)
    rot = ecef2enu_rotation(float(lat), float(lon))
    ang = (t - t[0]) * 12.0 / 600.0
    enu = np.column_stack([600.0 * np.cos(ang), 600.0 * np.sin(ang), np.zeros(seconds)])
    return simulate_drive(
        b,  # type: ignore[arg-type]
        eph,  # type: ignore[arg-type]
        t,
        centre + enu @ rot,
        code_sigma_m=3.0,
        multipath_sigma_m=1.5,
        multipath_tau_s=60.0,
        phase_sigma_m=0.005,
        doppler_sigma_m_s=0.1,
        clock_drift_m_s=100.0,
    )


def _one(track: str, data: Path) -> None:
    from robustrtk.geometry.ephemeris import EphemerisSource
    from robustrtk.io.rinex_nav import read_rinex_nav
    from robustrtk.io.rinex_obs import read_rinex_obs
    from robustrtk.pipeline.config import preset
    from robustrtk.pipeline.spp_fgo import FgoDiagnostics, solve_spp_fgo

    b = read_rinex_obs(data / PIXEL / "Pixel5_GnssLog.21o")
    eph = EphemerisSource(read_rinex_nav(data / PIXEL / "hour1180.21n"))
    if track == "sim-1h":
        b = _simulated_hour(b, eph)  # type: ignore[assignment]
    diag: list[FgoDiagnostics] = []
    t0 = time.perf_counter()
    sols = solve_spp_fgo(b, eph, preset("spp").updated(filter="ekf"), diagnostics=diag)
    wall = time.perf_counter() - t0
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    solved = sum(s.status == "single" for s in sols)
    n_l = int(diag[0].rows["L"].sum())
    print(
        f"| {track} | {len(b)} | {solved} | {n_l} | {wall:.1f} | {diag[0].iterations} | {rss:.0f} |",
        flush=True,
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=_default_data())
    ap.add_argument("--track", choices=("pixel5", "sim-1h", "all"), default="all")
    ap.add_argument("--one", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one:
        _one(args.one, args.data)
        return
    if not (args.data / PIXEL).is_dir():
        print(f"{args.data / PIXEL} not found: nothing to time")
        return
    print("| track | epochs | solved | TDCP rows | smoother wall (s) | iterations | peak RSS (MiB) |")
    print("|---|---|---|---|---|---|---|")
    for track in ("pixel5", "sim-1h") if args.track == "all" else (args.track,):
        subprocess.run([sys.executable, __file__, "--data", str(args.data), "--one", track], check=True)


if __name__ == "__main__":
    main()
