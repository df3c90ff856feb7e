"""Scaling of ``robustrtk batch``: the same eight RTK jobs on one worker and on two.

The jobs are the shared datasets (geonet, mosaicx5, kamakura) cycled to eight, each writing
its own ``.pos``; each campaign is a whole ``robustrtk batch JOBS --workers N`` process (so
the engine's start-up — a Dask local cluster or a process pool — is counted), repeated
``--repeats`` times, alternating 1 and 2 workers. Printed: the median wall time of each
campaign, the speed-up (1-worker time / 2-worker time; target ≥ 1.6 on a 2-core machine),
the sum of the jobs' own wall times (from ``--summary``) and the engine's overhead
(campaign wall minus the jobs' wall over the workers). The machine's load average is printed
too: other processes on the two cores cut the speed-up.

The robustrtk process is this checkout's ``src`` with its bytecode cached in a temporary
folder (as after ``pip install``).

Usage::

    python bench/bench_batch.py [--engine auto|dask|local] [--jobs 8] [--repeats 3]
                                [--workers 1,2] [--data DIR]
"""

from __future__ import annotations

import argparse
import csv
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SRC = REPO / "src"

#: folder, rover, base, nav, base ECEF (m) of the shared datasets.
DATASETS = (
    ("geonet_0759_3040_static_3km", "07590920.05o", "30400920.05o", "30400920.05n",
     "-3978241.958,3382840.234,3649900.853"),
    ("mosaicx5_static_1m", "rover.obs", "base.obs", "base.nav", "-3817681.1213,3562839.4311,3650159.1593"),
    ("kamakura_kinematic_5km", "SEPT265G.21O", "3034265G.21O", "SEPT2650.21P",
     "-3959400.631,3385704.533,3667523.111"),
)  # fmt: skip


def _default_data() -> Path:
    env = os.environ.get("ROBUSTRTK_SHARED_DATA")
    return Path(env) if env else REPO.parent / "shared" / "data"


def write_jobs(path: Path, data: Path, n_jobs: int, out_dir: Path) -> list[str]:
    """A TOML job list of ``n_jobs`` jobs cycling over the datasets present; their names."""
    present = [ds for ds in DATASETS if (data / ds[0] / ds[1]).is_file()]
    if not present:
        return []
    lines, names = [], []
    for i in range(n_jobs):
        folder, rover, base, nav, pos = present[i % len(present)]
        d = data / folder
        name = f"{i + 1:02d}_{folder.split('_')[0]}"
        names.append(name)
        lines.append(
            f'[[job]]\nname = "{name}"\nrover = "{d / rover}"\nbase = "{d / base}"\nnav = "{d / nav}"\n'
            f'base_pos = "{pos}"\nmode = "rtk"\nout = "{out_dir / (name + ".pos")}"\n'
        )
    path.write_text("\n".join(lines))
    return names


def campaign(
    jobs: Path, workers: int, engine: str, summary: Path, env: dict[str, str]
) -> tuple[float, float]:
    """(campaign wall s, sum of the jobs' wall s) of one ``robustrtk batch`` process."""
    cmd = [sys.executable, "-m", "robustrtk", "batch", str(jobs), "--engine", engine]
    cmd += ["--workers", str(workers), "--quiet", "--summary", str(summary)]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env, check=False)
    dt = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"batch failed (exit {proc.returncode}): {proc.stdout[-800:]}{proc.stderr[-800:]}")
    with summary.open() as fh:
        job_s = sum(float(r["wall_s"]) for r in csv.DictReader(fh))
    return dt, job_s


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--engine", default="auto", choices=("auto", "dask", "local"))
    ap.add_argument("--jobs", type=int, default=8, help="jobs per campaign [8]")
    ap.add_argument("--repeats", type=int, default=3, help="campaigns per worker count (median) [3]")
    ap.add_argument("--workers", default="1,2", help="worker counts to compare [1,2]")
    ap.add_argument("--data", type=Path, default=_default_data())
    args = ap.parse_args(argv)
    counts = [int(w) for w in args.workers.split(",") if w.strip()]
    if args.repeats < 1 or args.jobs < 1 or not counts or min(counts) < 1:
        ap.error("--repeats, --jobs and --workers must be positive")
    if not args.data.is_dir():
        print(f"shared data not found at {args.data}; skipped")
        return 0
    with tempfile.TemporaryDirectory() as tmp_s:
        tmp = Path(tmp_s)
        names = write_jobs(tmp / "jobs.toml", args.data, args.jobs, tmp / "out")
        if not names:
            print(f"no shared dataset under {args.data}; skipped")
            return 0
        env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
        env["PYTHONPATH"] = os.pathsep.join(p for p in (str(SRC), os.environ.get("PYTHONPATH", "")) if p)
        env["PYTHONPYCACHEPREFIX"] = str(tmp / "pycache")
        campaign(tmp / "jobs.toml", max(counts), args.engine, tmp / "warm.csv", env)  # warm-up, not recorded
        walls: dict[int, list[float]] = {w: [] for w in counts}
        jobs_s: dict[int, list[float]] = {w: [] for w in counts}
        load0 = os.getloadavg()[0]
        for _ in range(args.repeats):
            for w in counts:  # alternating
                dt, js = campaign(tmp / "jobs.toml", w, args.engine, tmp / f"s{w}.csv", env)
                walls[w].append(dt)
                jobs_s[w].append(js)
        load1 = os.getloadavg()[0]
    kinds = ", ".join(sorted({n.split("_", 1)[1] for n in names}))
    print(
        f"{args.jobs} RTK jobs ({kinds}), engine {args.engine}, "
        f"{os.cpu_count()} CPUs, load average {load0:.1f} -> {load1:.1f}; median of {args.repeats} campaigns"
    )
    head = f"{'workers':>7} {'campaign s':>10} {'jobs sum s':>10} {'overhead s':>10} {'speed-up':>8}"
    print(head)
    print("-" * len(head))
    base = statistics.median(walls[counts[0]])
    for w in counts:
        wall, js = statistics.median(walls[w]), statistics.median(jobs_s[w])
        print(f"{w:7d} {wall:10.2f} {js:10.2f} {wall - js / w:10.2f} {base / wall:8.2f}")
    print(
        "speed-up = campaign time with the first worker count / with this one (target >= 1.6 for 2 workers)"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
