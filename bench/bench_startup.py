"""Start-up cost of the ``robustrtk`` command and of a solve's imports.

Each measurement is a fresh interpreter (``sys.executable``, with this checkout's ``src``
first on ``PYTHONPATH`` and its bytecode cached in a temporary folder after one unrecorded
warm-up, as after ``pip install``), repeated ``--repeats`` times; printed: the median and min wall
time (s) of

1. ``python -c pass`` (the interpreter alone, for reference);
2. ``robustrtk --help`` through the console entry point (:func:`robustrtk.cli.entry.main`);
3. ``robustrtk solve --help``;
4. the imports of a RINEX RTK solve: the CLI plus :mod:`robustrtk.pipeline.rtk_gnss`,
   :mod:`robustrtk.cli.gnss`, the RINEX readers and the ``.pos`` writer (nothing solved);

then, from one ``python -X importtime`` run of item 4, the top-level packages by cumulative
import time. Target: items 2 and 4 at most 0.25 s (median of 5).

Usage::

    python bench/bench_startup.py [--repeats 5] [--top 12]
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src"

SOLVE_IMPORTS = (  # as the console entry does it: one BLAS thread is asked for before numpy loads
    "from robustrtk.cli.entry import single_threaded_blas; single_threaded_blas(); "
    "import robustrtk.cli.main, robustrtk.cli.gnss, robustrtk.pipeline.rtk_gnss, "
    "robustrtk.io.rinex_obs, robustrtk.io.rinex_nav, robustrtk.io.solution_pos, robustrtk.io.atomic"
)

CASES: tuple[tuple[str, list[str]], ...] = (
    ("python -c pass", ["-c", "pass"]),
    (
        "robustrtk --help",
        ["-c", "import sys; from robustrtk.cli.entry import main; sys.argv[1:] = ['--help']; main()"],
    ),
    (
        "robustrtk solve --help",
        [
            "-c",
            "import sys; from robustrtk.cli.entry import main; sys.argv[1:] = ['solve', '--help']; main()",
        ],
    ),
    ("RTK solve imports", ["-c", SOLVE_IMPORTS]),
)


#: Bytecode cache of the measured processes (set by :func:`main`): as after ``pip install``.
_PYCACHE: list[str] = []


def _env() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(SRC), env.get("PYTHONPATH", "")) if p)
    if _PYCACHE:
        env["PYTHONPYCACHEPREFIX"] = _PYCACHE[0]
    return env


def wall_s(args: list[str]) -> tuple[float, float]:
    """(wall s, CPU s = user + system) of one ``python ARGS`` run; raises if it fails.

    The CPU time of the child (``os.wait4``) is what the start-up costs on an idle core;
    the wall time adds whatever other processes take from it."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(
        [sys.executable, *args], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=_env()
    )
    assert proc.stderr is not None
    err = proc.stderr.read()
    _pid, status, usage = os.wait4(proc.pid, 0)
    dt = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise RuntimeError(f"{args}: exit {proc.returncode}: {err.decode()[-400:]}")
    return dt, usage.ru_utime + usage.ru_stime


def import_tree(code: str) -> list[tuple[float, str]]:
    """(cumulative ms, package) of ``python -X importtime -c code``: each package's imports
    counted where another package (or the script) first pulls them in."""
    proc = subprocess.run(
        [sys.executable, "-X", "importtime", "-c", code],
        capture_output=True,
        text=True,
        env=_env(),
        check=True,
    )
    rows = []
    for line in proc.stderr.splitlines():
        m = re.match(r"import time:\s+(\d+) \|\s+(\d+) \| (\s*)(\S+)", line)
        if m:
            rows.append((len(m.group(3)), m.group(4), int(m.group(2)) / 1e3))
    per_pkg: dict[str, float] = {}
    parents: list[tuple[int, str]] = []  # enclosing imports; a parent is printed after its children
    for indent, name, cum_ms in reversed(rows):
        while parents and parents[-1][0] >= indent:
            parents.pop()
        pkg = name.split(".")[0]
        parent_pkg = parents[-1][1] if parents else ""
        if pkg != parent_pkg:
            per_pkg[pkg] = per_pkg.get(pkg, 0.0) + cum_ms
        parents.append((indent, pkg))
    return sorted(((ms, pkg) for pkg, ms in per_pkg.items()), reverse=True)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5, help="runs per case (median) [5]")
    ap.add_argument("--top", type=int, default=12, help="packages listed from -X importtime [12]")
    args = ap.parse_args(argv)
    if args.repeats < 1:
        ap.error("--repeats must be at least 1")
    times: dict[str, list[float]] = {name: [] for name, _ in CASES}
    cpu: dict[str, list[float]] = {name: [] for name, _ in CASES}
    with tempfile.TemporaryDirectory() as cache:
        _PYCACHE[:] = [cache]
        for _name, case in CASES:  # warm-up: compile the bytecode once, not recorded
            wall_s(case)
        for _ in range(args.repeats):  # interleaved, so a busy spell hits every case alike
            for name, case in CASES:
                w, c = wall_s(case)
                times[name].append(w)
                cpu[name].append(c)
        tree = import_tree(SOLVE_IMPORTS)
    print(
        f"python {sys.version.split()[0]}, {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f}, "
        f"median of {args.repeats} fresh interpreters"
    )
    head = f"{'case':<24} {'median s':>9} {'min s':>7} {'CPU s':>7} {'target':>7}"
    print(head)
    print("-" * len(head))
    for name, _ in CASES:
        target = "-" if name.startswith("python") or "solve --help" in name else "0.25"
        print(
            f"{name:<24} {statistics.median(times[name]):9.3f} {min(times[name]):7.3f} "
            f"{statistics.median(cpu[name]):7.3f} {target:>7}"
        )
    print("median s, min s: wall time; CPU s: median user + system time of the process")
    print(
        f"\nRTK solve imports by package where first pulled in (python -X importtime, one run, "
        f"cumulative, so robustrtk includes the others; top {args.top}):"
    )
    for ms, pkg in tree[: args.top]:
        print(f"  {ms:8.1f} ms  {pkg}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
