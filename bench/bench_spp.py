"""Whole-process single-point positioning side by side: RTKLIB demo5 ``rnx2rtkp -p 0``
against ``robustrtk solve --mode spp`` (least squares) and ``--filter ekf`` (the Kalman SPP).

On each shared dataset both programs read the same observation and navigation files,
alternating, ``--repeats`` times each after one unrecorded warm-up run:

* RTKLIB: ``rnx2rtkp -p 0 -o OUT.pos ROVER NAV`` (single point, its defaults otherwise);
* robustrtk: ``python -m robustrtk solve ROVER --nav NAV --mode spp --out OUT.pos --quiet``
  (least squares with FDE, ``preset("spp")``), and the same with ``--filter ekf``.

Each run is one process; its wall time, its CPU time (user + system) and its own peak
resident set size (``ru_maxrss``), all from ``os.wait4``, are recorded. Printed per dataset:
epochs written by each, the median wall and CPU s, the ratios to RTKLIB (1.0 = parity; on a
loaded machine the CPU ratio is the steadier), and the median peak RSS; the last table is Markdown for
docs/speed.md. Also, alternating with the others, ``python -c "import numpy"``: the least a
numpy program's process costs (the floor).

The robustrtk processes run this checkout's ``src`` (``PYTHONPATH``) with bytecode cached in
a temporary ``PYTHONPYCACHEPREFIX``, as after ``pip install``. RTKLIB binary: ``--rnx2rtkp``,
else ``../shared/tools/rtklib-demo5/rnx2rtkp`` beside the repository, else ``rnx2rtkp`` on
``PATH``; without one the bench says so and exits 0.

Usage::

    python bench/bench_spp.py [--repeats 7] [--data DIR] [--datasets pixel5,mosaicx5,...]
                              [--no-kalman] [--rnx2rtkp PATH]
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_vs_rtklib import SRC, _default_data, find_rnx2rtkp  # noqa: E402

#: name -> (observation file, navigation file) under the shared data folder.
DATASETS: dict[str, tuple[str, str]] = {
    "pixel5": (
        "gsdc2021_mtv1_pixel5_phone/Pixel5/supplemental/Pixel5_GnssLog.21o",
        "gsdc2021_mtv1_pixel5_phone/Pixel5/supplemental/hour1180.21n",
    ),
    "mosaicx5": ("mosaicx5_static_1m/rover.obs", "mosaicx5_static_1m/base.nav"),
    "kamakura": ("kamakura_kinematic_5km/SEPT265G.21O", "kamakura_kinematic_5km/SEPT2650.21P"),
    "geonet": ("geonet_0759_3040_static_3km/07590920.05o", "geonet_0759_3040_static_3km/30400920.05n"),
}


def run_timed(cmd: list[str], env: dict[str, str] | None, log: Path) -> tuple[float, float, float, int]:
    """Run ``cmd`` as one process: (wall s, CPU s (user + system), peak RSS MiB, exit status).
    On a loaded machine the CPU time is the steadier of the two."""
    with open(log, "wb") as fh:
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=fh, stderr=subprocess.STDOUT, env=env)
        _pid, status, usage = os.wait4(proc.pid, 0)
        dt = time.perf_counter() - t0
    return dt, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024.0, os.waitstatus_to_exitcode(status)


def pos_epochs(path: Path) -> int:
    """Data lines of a ``.pos`` file (0 when absent)."""
    if not path.is_file():
        return 0
    return sum(1 for line in path.read_text(errors="replace").splitlines() if line and line[0] != "%")


def _median(v: list[float]) -> float:
    return statistics.median(v) if v else float("nan")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--data", type=Path, default=_default_data())
    ap.add_argument("--datasets", default=",".join(DATASETS))
    ap.add_argument("--no-kalman", action="store_true", help="skip the Kalman SPP")
    ap.add_argument("--rnx2rtkp", default=None)
    args = ap.parse_args(argv)
    exe = find_rnx2rtkp(args.rnx2rtkp)
    if exe is None:
        print("rnx2rtkp not found (--rnx2rtkp PATH); skipped")
        return 0
    names = [n for n in args.datasets.split(",") if n]
    unknown = [n for n in names if n not in DATASETS]
    if unknown:
        print(f"--datasets: unknown {', '.join(unknown)} (expected {', '.join(DATASETS)})", file=sys.stderr)
        return 2
    progs = ["rtklib", "lsq"] + ([] if args.no_kalman else ["ekf"])
    rows: list[tuple[str, int, dict[str, float], dict[str, float], dict[str, float], dict[str, int]]] = []
    floor: list[float] = []
    with tempfile.TemporaryDirectory() as tmp_s:
        tmp = Path(tmp_s)
        env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
        env["PYTHONPATH"] = os.pathsep.join(p for p in (str(SRC), os.environ.get("PYTHONPATH", "")) if p)
        env["PYTHONPYCACHEPREFIX"] = str(tmp / "pycache")
        for name in names:
            obs, nav = (args.data / p for p in DATASETS[name])
            if not obs.is_file() or not nav.is_file():
                print(f"note: {name} skipped: {obs if not obs.is_file() else nav} not found")
                continue
            outs = {p: tmp / f"{name}.{p}.pos" for p in ("rtklib", "lsq", "ekf")}
            ours = [sys.executable, "-m", "robustrtk", "solve", str(obs), "--nav", str(nav), "--mode", "spp"]
            cmds = {
                "rtklib": [str(exe), "-p", "0", "-o", str(outs["rtklib"]), str(obs), str(nav)],
                "lsq": [*ours, "--out", str(outs["lsq"]), "--quiet"],
                "ekf": [*ours, "--filter", "ekf", "--out", str(outs["ekf"]), "--quiet"],
            }
            envs = {"rtklib": None, "lsq": env, "ekf": env}
            wall: dict[str, list[float]] = {p: [] for p in progs}
            cpu: dict[str, list[float]] = {p: [] for p in progs}
            rss: dict[str, list[float]] = {p: [] for p in progs}
            for p in progs:  # warm-up: bytecode, page cache
                _, _, _, rc = run_timed(cmds[p], envs[p], tmp / "log.txt")
                if rc != 0:
                    tail = (tmp / "log.txt").read_text(errors="replace").strip().splitlines()
                    print(f"note: {name}/{p} exited {rc}: {tail[-1] if tail else ''}")
            for _ in range(args.repeats):
                for p in progs:
                    dt, c, mib, _ = run_timed(cmds[p], envs[p], tmp / "log.txt")
                    wall[p].append(dt)
                    cpu[p].append(c)
                    rss[p].append(mib)
                dt, _, _, _ = run_timed([sys.executable, "-c", "import numpy"], env, tmp / "log.txt")
                floor.append(dt)
            med = {p: _median(wall[p]) for p in progs}
            med_cpu = {p: _median(cpu[p]) for p in progs}
            mem = {p: _median(rss[p]) for p in progs}
            n_ep = {p: pos_epochs(outs[p]) for p in progs}
            rows.append((name, max(n_ep.values()), med, med_cpu, mem, n_ep))
            ratio = "  ".join(
                f"{p} {med[p]:.3f} s ({med[p] / med['rtklib']:.2f}x; CPU {med_cpu[p]:.3f} s)" for p in progs
            )
            print(f"{name}: {ratio}", flush=True)
    if not rows:
        print("no dataset found; skipped")
        return 0
    print(
        f"\n{platform.machine()}, {os.cpu_count()} cores, load {os.getloadavg()[0]:.2f}; "
        f"median of {args.repeats}; floor (python -c 'import numpy') {_median(floor):.3f} s\n"
    )
    head = ["dataset", "epochs"]
    for p in progs:
        head += [f"{p} wall s"] + ([] if p == "rtklib" else [f"{p} / rtklib"])
    for p in progs:
        head += [f"{p} CPU s"] + ([] if p == "rtklib" else [f"{p} / rtklib CPU"])
    head += [f"{p} MiB" for p in progs]
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for name, n, med, med_cpu, mem, _ in rows:
        cells = [name, str(n)]
        for p in progs:
            cells.append(f"{med[p]:.3f}")
            if p != "rtklib":
                cells.append(f"{med[p] / med['rtklib']:.2f}")
        for p in progs:
            cells.append(f"{med_cpu[p]:.3f}")
            if p != "rtklib":
                cells.append(f"{med_cpu[p] / med_cpu['rtklib']:.2f}")
        cells += [f"{mem[p]:.1f}" for p in progs]
        print("| " + " | ".join(cells) + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
