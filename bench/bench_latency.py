"""Per-epoch latency of real-time RTK: from an epoch's arrival to its written solution.

Each rover epoch is replayed at 1, 5 and 10 Hz (the recordings are 1 Hz: 1×, 5×, 10× real
time), its base epoch just before it, through :class:`robustrtk.pipeline.stream.StreamSolver`
and a ``.pos`` line written and flushed. The latency of an epoch is the wall time from its
hand-over to the written line:

* kamakura and mosaicx5 (RINEX): from the epoch's hand-over as an
  :class:`~robustrtk.core.ObsEpoch` (no bytes to decode: there is no UBX/RTCM 3 log of
  these receivers);
* galway s1 (u-blox UBX rover, RTCM 3 base): from the moment the 512-byte chunk holding the
  epoch's last byte is fed to the decoder (:class:`~robustrtk.io.epoch_source.StreamDecoder`),
  decoding included; only the epochs solved on arrival (this base has gaps of 1-4 s: an
  epoch in a gap waits for the base's next epoch or ``wait_s``, which is the base's
  latency, not the solver's).

Default RTK settings with ``code_sigma_from_data`` off (a whole-file estimate); the first
10 epochs (start-up, first compilations) are left out of the statistics. Run:
``python bench/bench_latency.py [--data ../shared/data] [--epochs N]``. Prints a Markdown table.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from robustrtk.core import ObsEpoch
from robustrtk.geometry.frames import geodetic2ecef
from robustrtk.io.epoch_source import StreamDecoder
from robustrtk.io.raw_file import read_binary_log
from robustrtk.io.readers import read_navigation
from robustrtk.io.rinex_obs import read_rinex_obs
from robustrtk.io.rtcm3 import reference_time_s
from robustrtk.io.solution_pos import pos_lines
from robustrtk.pipeline.config import Config, preset
from robustrtk.pipeline.stream import StreamSolver

WARM_UP = 10


def rinex_events(rover: Path, base: Path) -> Iterator[tuple[str, ObsEpoch]]:
    """Base and rover epochs in time order (a base epoch before the rover epoch of its tag)."""
    r = read_rinex_obs(rover)
    b = read_rinex_obs(base)
    ev = [(float(t), 0, k) for k, t in enumerate(b.t_s)] + [(float(t), 1, k) for k, t in enumerate(r.t_s)]
    for _, kind, k in sorted(ev):
        yield ("base", b.epoch(k)) if kind == 0 else ("rover", r.epoch(k))


def run_rinex(name: str, rover: Path, base: Path, navs: list[Path], base_pos: np.ndarray, cfg: Config,
              rate_hz: float, n_max: int) -> list[tuple[float, float]]:  # fmt: skip
    """Latencies (wall s, this thread's CPU s) of the rover epochs of a RINEX pair replayed
    at ``rate_hz``."""
    solver = StreamSolver(cfg, base_pos, read_navigation([str(n) for n in navs]))
    lat: list[tuple[float, float]] = []
    with tempfile.TemporaryDirectory() as tmp, open(Path(tmp) / f"{name}.pos", "w") as fh:
        t_next = time.perf_counter()
        n = 0
        for role, ep in rinex_events(rover, base):
            if role == "base":
                for sol in solver.on_base(ep):
                    fh.write("".join(pos_lines([sol])))
                    fh.flush()
                continue
            t_next += 1.0 / rate_hz
            delay = t_next - time.perf_counter()
            if delay > 0:
                time.sleep(delay)
            t_in, c_in = time.perf_counter(), time.thread_time()
            sols = solver.on_rover(ep)
            for sol in sols:
                fh.write("".join(pos_lines([sol])))
                fh.flush()
            if sols:
                lat.append((time.perf_counter() - t_in, time.thread_time() - c_in))
            n += 1
            if n >= n_max:
                break
    return lat[WARM_UP:]


def run_galway(s1: Path, cfg: Config, rate_hz: float, n_max: int) -> list[tuple[float, float]]:
    """Latencies (s) of the galway s1 UBX rover epochs, decoding included (RTCM 3 base)."""
    rover_b, _ = read_binary_log(s1 / "rover-20181004-1237.ubx.gz")
    base_b, _ = read_binary_log(s1 / "base-20181004-1236.rtcm3")
    base_path = s1 / "base-20181004-1236.rtcm3"
    bdec = StreamDecoder(t_ref_s=reference_time_s(str(base_path), base_b))
    base_events = [e for k in range(0, len(base_b), 4096) for e in bdec.feed(base_b[k : k + 4096])]
    base_epochs = [e for e in base_events if isinstance(e, ObsEpoch)]
    pos = np.asarray(bdec.station["arp_ecef_m"], float)
    solver = StreamSolver(
        cfg.updated(freqs="L1"), pos, read_navigation([str(s1 / "rover-20181004-1237.nav")])
    )
    lat: list[tuple[float, float]] = []
    i_base = 0
    n = 0
    with tempfile.TemporaryDirectory() as tmp, open(Path(tmp) / "galway.pos", "w") as fh:
        t_next = time.perf_counter()
        rdec = StreamDecoder(fmt="ubx")
        t_last = base_epochs[0].t_s
        for k in range(0, len(rover_b), 512):
            # the base epochs up to the next rover epoch arrive first (no base latency; their
            # own processing is not the rover's latency)
            while i_base < len(base_epochs) and base_epochs[i_base].t_s <= t_last + 1.5:
                for sol in solver.on_base(base_epochs[i_base]):
                    fh.write("".join(pos_lines([sol])))
                    fh.flush()
                i_base += 1
            t_fed = time.perf_counter(), time.thread_time()
            for ev in rdec.feed(rover_b[k : k + 512]):
                if not isinstance(ev, ObsEpoch):
                    continue
                t_last = ev.t_s
                sols = solver.on_rover(ev)
                for sol in sols:
                    fh.write("".join(pos_lines([sol])))
                    fh.flush()
                if any(sol.t_s == ev.t_s for sol in sols):  # solved at its arrival
                    lat.append((time.perf_counter() - t_fed[0], time.thread_time() - t_fed[1]))
                n += 1
                # pace the next epoch's bytes
                t_next += 1.0 / rate_hz
                delay = t_next - time.perf_counter()
                if delay > 0:
                    time.sleep(delay)
            if n >= n_max:
                break
    return lat[WARM_UP:]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    here = Path(__file__).resolve().parents[1]
    ap.add_argument(
        "--data",
        type=Path,
        default=Path(os.environ.get("ROBUSTRTK_SHARED_DATA", here.parent / "shared" / "data")),
    )
    ap.add_argument("--epochs", type=int, default=300, help="rover epochs per run (default 300)")
    ap.add_argument("--rates", default="1,5,10")
    args = ap.parse_args(argv)
    d: Path = args.data
    if not d.is_dir():
        print(f"no shared data at {d}", file=sys.stderr)
        return 2
    cfg = preset("rtk").updated(code_sigma_from_data=False).validate("rtk")
    rates = [float(r) for r in args.rates.split(",")]
    rows = []
    km = d / "kamakura_kinematic_5km"
    mx = d / "mosaicx5_static_1m"
    s1 = d / "galway_m8p_l1_lowcost" / "s1_static"
    n = args.epochs
    sets = {
        "kamakura (GPS+GAL+QZS L1/L2)": lambda r: run_rinex(
            "kamakura", km / "SEPT265G.21O", km / "3034265G.21O", [km / "SEPT2650.21P"], kamakura_base(km),
            cfg, r, n,
        ),
        "mosaicx5 (GPS+GAL+BDS+QZS L1/L2)": lambda r: run_rinex(
            "mosaicx5", mx / "rover.obs", mx / "base.obs", [mx / "base.nav"], mosaic_base(mx), cfg, r, n
        ),
        "galway s1 (UBX + RTCM 3, L1)": lambda r: run_galway(s1, cfg, r, n),
    }  # fmt: skip
    print(f"load average before: {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    print("| rover | rate | epochs | wall p50 (ms) | wall p99 (ms) | CPU p50 (ms) | CPU p99 (ms) |")
    print("|---|---|---|---|---|---|---|")
    for name, fn in sets.items():
        for r in rates:
            lat = np.asarray(fn(r)) * 1e3  # (n, 2): wall, CPU
            w50, w99 = np.percentile(lat[:, 0], [50, 99])
            c50, c99 = np.percentile(lat[:, 1], [50, 99])
            row = f"| {name} | {r:g} Hz | {len(lat)} | {w50:.1f} | {w99:.1f} | {c50:.1f} | {c99:.1f} |"
            rows.append(row)
            print(row, flush=True)
    return 0


def kamakura_base(folder: Path) -> np.ndarray:
    """The base ECEF of kamakura's ``truth_and_base.txt`` (line ``base_xyz``)."""
    for line in (folder / "truth_and_base.txt").read_text().splitlines():
        if line.startswith("base_xyz"):
            return np.asarray([float(v) for v in line.split()[1:4]])
    raise SystemExit("kamakura truth_and_base.txt: no base_xyz line")


def mosaic_base(folder: Path) -> np.ndarray:
    """The base ECEF from mosaicx5's ``base_position.txt`` (lat, lon in deg, height in m)."""
    lat, lon, h = (float(v) for v in (folder / "base_position.txt").read_text().split()[:3])
    return np.asarray(geodetic2ecef(np.radians(lat), np.radians(lon), h), float).reshape(3)


if __name__ == "__main__":
    raise SystemExit(main())
