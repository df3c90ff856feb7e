"""Speed and memory of the robust batch smoother (``solve --mode spp --fgo``).

Two tracks, each solved in its own process (peak RSS = that process's ``ru_maxrss``):

* ``pixel5``: the shared Pixel 5 GSDC 2021 drive (1985 epochs at 1 Hz, GPS L1+L5).
* ``sim-1h``: one hour at 1 Hz (3600 epochs) of the same satellites, simulated from the
  drive's broadcast navigation file: a receiver driving a 600-m circle at 12 m/s, code
  with 3 m white noise plus a 1.5 m Gauss–Markov multipath term (60 s), carrier phase with
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
from dataclasses import replace
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
PIXEL = "gsdc2021_mtv1_pixel5_phone/Pixel5/supplemental"


def _default_data() -> Path:
    env = os.environ.get("ROBUSTRTK_SHARED_DATA")
    return Path(env) if env else REPO.parent / "shared" / "data"


def _simulated_hour(batch: object, eph: object, seconds: int = 3600) -> object:
    """The drive's batch layout filled with one simulated hour (module docstring)."""
    from robustrtk.core import CLIGHT
    from robustrtk.geometry.frames import ecef2enu_rotation, ecef2geodetic
    from robustrtk.geometry.los import geometric_range

    b = batch
    rng = np.random.default_rng(0)
    T, N, S = seconds, len(b.tx_ids), len(b.signals)  # type: ignore[attr-defined]
    t = float(b.t_s[0]) + np.arange(T, dtype=float)  # type: ignore[attr-defined]
    centre = np.nanmedian(
        np.asarray(b.approx_pos_m if b.approx_pos_m is not None else [np.nan] * 3)[None], axis=0
    )  # type: ignore[attr-defined]
    if not np.all(np.isfinite(centre)):
        centre = np.array([-2694685.473, -4293642.366, 3857878.924])  # Mountain View
    lat, lon, _ = ecef2geodetic(centre)
    rot = ecef2enu_rotation(float(lat), float(lon))
    ang = t - t[0]
    ang = ang * 12.0 / 600.0
    enu = np.column_stack([600.0 * np.cos(ang), 600.0 * np.sin(ang), np.zeros(T)])
    pos = centre + enu @ rot
    vel = np.gradient(pos, axis=0)
    clk = 3.0e4 + 100.0 * (t - t[0])
    wl = b.wavelength_m  # type: ignore[attr-defined]
    code = np.full((T, N, S), np.nan)
    phase = np.full((T, N, S), np.nan)
    dop = np.full((T, N, S), np.nan)
    cn0 = np.full((T, N, S), np.nan)
    a = np.exp(-1.0 / 60.0)
    mp = np.zeros((N, S))
    offs = rng.integers(-(10**6), 10**6, size=(N, S)).astype(float)
    ids = list(b.tx_ids)  # type: ignore[attr-defined]
    for k in range(T):
        sp, sclk = eph.positions(float(t[k]), ids)  # type: ignore[attr-defined]
        sp1, sclk1 = eph.positions(float(t[k]) + 0.5, ids)  # type: ignore[attr-defined]
        sp0, sclk0 = eph.positions(float(t[k]) - 0.5, ids)  # type: ignore[attr-defined]
        sat_rate = sp1 - sp0  # m/s: central difference over 1 s
        clk_rate = sclk1 - sclk0
        ok = np.all(np.isfinite(sp), axis=1) & np.isfinite(sclk)
        r, u = geometric_range(np.where(ok[:, None], sp, 0.0), pos[k])
        up = (np.where(ok[:, None], sp, 0.0) - pos[k]) @ rot.T
        el = np.arcsin(np.clip(up[:, 2] / np.linalg.norm(up, axis=1), -1, 1))
        vis = ok & (el > np.deg2rad(10.0))
        mp = a * mp + np.sqrt(1 - a * a) * 1.5 * rng.normal(size=(N, S))
        for s in range(S):
            have = vis & np.isfinite(wl[:, s]) & np.isfinite(b.code_m[:, :, s]).any(axis=0)  # type: ignore[attr-defined]
            if not have.any():
                continue
            rho = r[have] + clk[k] - sclk[have]
            code[k, have, s] = rho + 3.0 * rng.normal(size=have.sum()) + mp[have, s]
            phase[k, have, s] = (rho + 0.005 * rng.normal(size=have.sum())) / wl[have, s] + offs[have, s]
            rate = np.sum(u[have] * (sat_rate[have] - vel[k]), axis=1) + 100.0 - clk_rate[have]
            dop[k, have, s] = -(rate + 0.1 * rng.normal(size=have.sum())) / wl[have, s]
            cn0[k, have, s] = 25.0 + 20.0 * np.sin(el[have])
    del CLIGHT
    return replace(
        b,  # type: ignore[type-var]
        t_s=t,
        code_m=code,
        phase_cyc=phase,
        doppler_hz=dop,
        cn0_dbhz=cn0,
        lli=np.zeros((T, N, S), np.int8),
        code_sigma_m=None,
        phase_sigma_cyc=None,
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
