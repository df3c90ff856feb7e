"""Throughput of SPP (least squares + FDE, Kalman) and code DGNSS on the shared datasets.

Usage: ``python bench/bench_gnss.py [DATA_DIR]`` (default ``../shared/data``). Prints a
table of epochs per second (wall time of the solver, files already read).
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.geometry.frames import geodetic2ecef_deg
from robustrtk.io.rinex_nav import read_rinex_nav
from robustrtk.io.rinex_obs import read_rinex_obs
from robustrtk.pipeline.gnss import dgnss_config, solve_dgnss
from robustrtk.pipeline.spp import select_band1, solve_spp, solve_spp_kalman

DATASETS = {
    "geonet": (
        "geonet_0759_3040_static_3km",
        "07590920.05o",
        "30400920.05o",
        ["30400920.05n"],
        np.array([-3978241.958, 3382840.234, 3649900.853]),
        {},
    ),
    "mosaicx5": (
        "mosaicx5_static_1m",
        "rover.obs",
        "base.obs",
        ["base.nav"],
        geodetic2ecef_deg(35.134707705, 136.977577939, 104.853),
        {},
    ),
    "kamakura": (
        "kamakura_kinematic_5km",
        "SEPT265G.21O",
        "3034265G.21O",
        ["SEPT2650.21P"],
        np.array([-3959400.631, 3385704.533, 3667523.111]),
        {"dynamics": "kinematic", "sigma_vel_m_s": 10.0},
    ),
    "pixel5": (
        "gsdc2021_mtv1_pixel5_phone/Pixel5/supplemental",
        "Pixel5_GnssLog.21o",
        None,
        ["hour1180.21n"],
        None,
        {},
    ),
}


def _rate(n: int, fn: Callable[..., object], *args: object) -> float:
    t0 = time.perf_counter()
    fn(*args)
    return n / (time.perf_counter() - t0)


def main(root: Path) -> None:
    print(f"{'dataset':10s} {'epochs':>6s} {'SPP-WLS ep/s':>13s} {'SPP-KF ep/s':>12s} {'DGNSS ep/s':>11s}")
    for name, (folder, rov, base, navs, base_pos, kw) in DATASETS.items():
        d = root / folder
        rover = read_rinex_obs(d / rov)
        eph = EphemerisSource(read_rinex_nav([d / n for n in navs]))
        one = select_band1(rover)
        n = len(rover)
        wls = _rate(n, solve_spp, one, eph)
        kf = _rate(n, solve_spp_kalman, one, eph)
        dg = float("nan")
        if base is not None:
            b = read_rinex_obs(d / base)
            dg = _rate(n, solve_dgnss, rover, b, eph, base_pos, dgnss_config(**kw))
        print(f"{name:10s} {n:6d} {wls:13.0f} {kf:12.0f} {dg:11.0f}")


if __name__ == "__main__":
    default = Path(__file__).resolve().parents[1].parent / "shared" / "data"
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else default)
