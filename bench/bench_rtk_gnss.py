"""Speed of carrier-phase RTK on RINEX (:func:`robustrtk.pipeline.rtk_gnss.solve_rtk`) beside RTKLIB.

For each shared dataset (rover, base, broadcast nav, surveyed base position) the whole solve is
run ``--repeats`` times in this process with the default :func:`rtk_gnss_config` (forward
filter, fix-and-hold, 15° mask, L1+L2: the settings of RTKLIB's ``fh`` runs). Reading the
files is included, as in RTKLIB's whole-run wall time; writing the solution file is not (the
CLI column has it). Printed:

1. per dataset: epochs, fixed epochs, median wall s of the whole solve, epochs/s, RTKLIB's
   ``fh`` (and ``inst``) median wall s from ``shared/data/README.md``, the ratio ours / RTKLIB
   ``fh`` (1.0 = parity, above 1 = slower), and the median wall s of the whole CLI
   (``robustrtk solve ... --mode rtk --out X.pos`` in a subprocess: Python start-up, imports
   and the .pos write included) with its ratio to RTKLIB ``fh``;
2. the median split of the in-process solve: reading RINEX obs + nav, set-up (ephemeris
   tables, signal rows, SPP start, slip detectors) and the epoch loop (``run_dd``), with ms per
   epoch of the loop;
3. with ``--profile [DATASET]`` (default ``mosaicx5``): the top functions of one epoch loop by
   cumulative time and by own time (cProfile, which itself slows the loop).

RTKLIB's times (RTKLIB-EX 2.5.1 ``rnx2rtkp``, 2-core machine) are constants copied from the
data README; this machine's speed differs, so the ratios are indicative. RTKLIB's mosaicx5
run also used GLONASS (``navsys=61``); RTK here leaves GLONASS out (FDMA carriers).
Datasets whose files are absent are skipped with a note.

Usage::

    python bench/bench_rtk_gnss.py [--repeats 5] [--profile [DATASET]] [--no-cli]
                                   [--datasets geonet,mosaicx5,kamakura] [--data DIR]
"""

from __future__ import annotations

import argparse
import cProfile
import os
import platform
import pstats
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

import robustrtk.pipeline.gnss as rtk_mod  # run_rows calls run_dd through this module
from robustrtk.geometry.frames import geodetic2ecef_deg
from robustrtk.io.rinex_nav import read_rinex_nav
from robustrtk.io.rinex_obs import read_rinex_obs
from robustrtk.pipeline.rtk_gnss import rtk_gnss_config, solve_rtk


@dataclass(frozen=True)
class Dataset:
    """One shared dataset and RTKLIB's median whole-run wall times on it (s)."""

    folder: str
    rover: str
    base: str
    navs: tuple[str, ...]
    base_pos_file: str
    rtklib_fh_s: float
    rtklib_inst_s: float


# Nav files are those of RTKLIB's runs (the ``inp file`` lines of ``rtklib/fh.pos``): geonet
# uses the base's 30400920.05n, not the rover's 07590920.05n.
DATASETS: dict[str, Dataset] = {
    "geonet": Dataset(
        "geonet_0759_3040_static_3km",
        "07590920.05o",
        "30400920.05o",
        ("30400920.05n",),
        "truth_and_base.txt",
        0.12,
        0.05,
    ),
    "mosaicx5": Dataset(
        "mosaicx5_static_1m", "rover.obs", "base.obs", ("base.nav",), "base_position.txt", 2.39, 1.82
    ),
    "kamakura": Dataset(
        "kamakura_kinematic_5km",
        "SEPT265G.21O",
        "3034265G.21O",
        ("SEPT2650.21P",),
        "truth_and_base.txt",
        0.71,
        0.41,
    ),
}


def _default_data() -> Path:
    env = os.environ.get("ROBUSTRTK_SHARED_DATA")
    if env:
        return Path(env)
    return Path(__file__).resolve().parents[1].parent / "shared" / "data"


def base_position_ecef_m(path: Path) -> np.ndarray:
    """Base ECEF (m), shape (3,): a ``base_xyz X Y Z`` line, or a bare ``lat lon h`` line (deg, deg, m)."""
    for line in path.read_text().splitlines():
        words = line.split()
        if not words or words[0].startswith("#"):
            continue
        if words[0] == "base_xyz":
            return np.array([float(w) for w in words[1:4]])
        if len(words) == 3:
            lat_deg, lon_deg, h_m = (float(w) for w in words)
            return np.asarray(geodetic2ecef_deg(lat_deg, lon_deg, h_m), float).reshape(3)
    raise ValueError(f"{path}: no base_xyz line and no 'lat lon h' line")


def _missing(d: Path, ds: Dataset) -> list[str]:
    names = [ds.rover, ds.base, *ds.navs, ds.base_pos_file]
    return [n for n in names if not (d / n).is_file()]


@dataclass
class RunTimes:
    """Wall times (s) of one in-process solve, and its outcome."""

    read_s: float
    setup_s: float
    loop_s: float
    whole_s: float
    epochs: int
    fixed: int


class _LoopTimer:
    """Wraps ``run_dd`` as seen by :mod:`robustrtk.pipeline.rtk_gnss` to time (and optionally
    profile) the epoch loop alone, without changing what it computes."""

    def __init__(self, profiler: cProfile.Profile | None = None) -> None:
        self.loop_s = float("nan")
        self.profiler = profiler
        self._orig: Callable[..., Any] = rtk_mod.run_dd

    def __enter__(self) -> _LoopTimer:
        orig = self._orig

        def timed(*args: Any, **kwargs: Any) -> Any:
            if self.profiler is not None:
                self.profiler.enable()
            t0 = time.perf_counter()
            try:
                return orig(*args, **kwargs)
            finally:
                self.loop_s = time.perf_counter() - t0
                if self.profiler is not None:
                    self.profiler.disable()

        rtk_mod.run_dd = timed
        return self

    def __exit__(self, *exc: object) -> None:
        rtk_mod.run_dd = self._orig


def solve_once(
    d: Path, ds: Dataset, base_pos_m: np.ndarray, profiler: cProfile.Profile | None = None
) -> RunTimes:
    """One whole solve from the files, timed by phase."""
    with _LoopTimer(profiler) as lt:
        t0 = time.perf_counter()
        rover = read_rinex_obs(d / ds.rover)
        base = read_rinex_obs(d / ds.base)
        nav = read_rinex_nav([d / n for n in ds.navs])
        t1 = time.perf_counter()
        res = solve_rtk(rover, base, nav, base_pos_m, rtk_gnss_config())
        t2 = time.perf_counter()
    fixed = sum(1 for s in res.solutions if s.status in ("fixed", "partial"))  # Q=1 in .pos
    return RunTimes(t1 - t0, (t2 - t1) - lt.loop_s, lt.loop_s, t2 - t0, len(res.solutions), fixed)


def _cli_command() -> list[str] | None:
    exe = Path(sys.executable).parent / "robustrtk"
    if exe.is_file():
        return [str(exe)]
    found = shutil.which("robustrtk")
    return [found] if found else None


def cli_once(cmd: list[str], d: Path, ds: Dataset, base_pos_m: np.ndarray, out_dir: Path) -> float:
    """Wall time (s) of one whole CLI run in a subprocess; NaN (and a note) when it fails."""
    args = [*cmd, "solve", str(d / ds.rover), "--base", str(d / ds.base)]
    for n in ds.navs:
        args += ["--nav", str(d / n)]
    args += [
        "--base-pos",
        ",".join(f"{v:.4f}" for v in base_pos_m),
        "--mode",
        "rtk",
        "--out",
        str(out_dir / "bench.pos"),
        "--quiet",
    ]
    t0 = time.perf_counter()
    proc = subprocess.run(args, capture_output=True, text=True, check=False)
    dt = time.perf_counter() - t0
    if proc.returncode != 0:
        last = (proc.stderr.strip().splitlines() or ["(no message)"])[-1]
        print(f"  note: CLI failed on {ds.folder} (exit {proc.returncode}): {last}")
        return float("nan")
    return dt


def _fmt(v: float, spec: str) -> str:
    return format(v, spec) if np.isfinite(v) else format("-", f">{spec.split('.')[0]}")


def _where(fn: tuple[str, int, str]) -> str:
    file, line, name = fn
    if file == "~":  # built-ins
        return name
    parts = Path(file).parts
    short = "/".join(parts[parts.index("robustrtk") + 1 :]) if "robustrtk" in parts else Path(file).name
    return f"{short}:{line}({name})"


def print_profile(prof: cProfile.Profile, epochs: int, loop_s: float, top: int = 8) -> None:
    """Top ``top`` functions by cumulative and by own time of one profiled epoch loop."""
    st = pstats.Stats(prof)
    raw: dict[tuple[str, int, str], tuple[int, int, float, float, Any]] = st.stats  # type: ignore[attr-defined]
    rows = [(fn, nc, tt, ct) for fn, (_cc, nc, tt, ct, _callers) in raw.items()]
    total = max(ct for _fn, _nc, _tt, ct in rows)
    head = f"{'ncalls':>8} {'own s':>7} {'cum s':>7} {'cum %':>6} {'cum ms/ep':>9}  function"
    for title, key in (("cumulative time", 3), ("own time", 2)):
        print(f"\ntop {top} by {title} (loop {loop_s:.2f} s under the profiler, {epochs} epochs):")
        print(head)
        print("-" * len(head))
        for fn, nc, tt, ct in sorted(rows, key=lambda r: r[key], reverse=True)[:top]:
            print(
                f"{nc:8d} {tt:7.3f} {ct:7.3f} {100 * ct / total:6.1f} {1e3 * ct / max(epochs, 1):9.2f}  "
                f"{_where(fn)}"
            )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5, help="runs per dataset (median) [5]")
    ap.add_argument("--data", type=Path, default=_default_data())
    ap.add_argument("--datasets", default=",".join(DATASETS), help="comma-separated names")
    ap.add_argument("--no-cli", action="store_true", help="skip the whole-CLI subprocess runs")
    ap.add_argument(
        "--profile",
        nargs="?",
        const="mosaicx5",
        default=None,
        metavar="DATASET",
        help="profile one epoch loop of DATASET [mosaicx5]",
    )
    args = ap.parse_args(argv)
    names = [n.strip() for n in args.datasets.split(",") if n.strip()]
    unknown = [n for n in names if n not in DATASETS]
    if unknown or (args.profile is not None and args.profile not in DATASETS):
        ap.error(f"unknown dataset(s) {unknown or [args.profile]}; known: {', '.join(DATASETS)}")
    if args.repeats < 1:
        ap.error("--repeats must be at least 1")
    if not args.data.is_dir():
        print(f"shared data not found at {args.data}; nothing to measure")
        return 0
    cli = None if args.no_cli else _cli_command()
    if cli is None and not args.no_cli:
        print("note: no robustrtk console script found; CLI column skipped")

    print(
        f"python {platform.python_version()}, numpy {np.__version__}, {os.cpu_count()} CPUs, "
        f"{platform.machine()}; median of {args.repeats} runs; RTKLIB times from the data README "
        "(2-core machine)"
    )
    results: dict[str, tuple[list[RunTimes], list[float]]] = {}
    notes: list[str] = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in names:
            ds = DATASETS[name]
            d = args.data / ds.folder
            missing = _missing(d, ds)
            if missing:
                notes.append(f"{name}: skipped, missing {', '.join(missing)} in {d}")
                continue
            base_pos = base_position_ecef_m(d / ds.base_pos_file)
            runs = [solve_once(d, ds, base_pos) for _ in range(args.repeats)]
            clis = [cli_once(cli, d, ds, base_pos, Path(tmp)) for _ in range(args.repeats)] if cli else []
            results[name] = (runs, clis)

    head = (
        f"{'dataset':<9} {'epochs':>6} {'fixed':>5} {'whole s':>8} {'ep/s':>7} {'RTKLIB fh s':>11} "
        f"{'ratio':>6} {'(inst s)':>8} {'CLI s':>7} {'CLI ratio':>9}"
    )
    print()
    print(head)
    print("-" * len(head))
    for name, (runs, clis) in results.items():
        ds = DATASETS[name]
        whole = statistics.median(r.whole_s for r in runs)
        cli_s = statistics.median(clis) if clis else float("nan")
        print(
            f"{name:<9} {runs[0].epochs:6d} {runs[0].fixed:5d} {whole:8.3f} {runs[0].epochs / whole:7.1f} "
            f"{ds.rtklib_fh_s:11.2f} {whole / ds.rtklib_fh_s:6.2f} {ds.rtklib_inst_s:8.2f} "
            f"{_fmt(cli_s, '7.3f')} {_fmt(cli_s / ds.rtklib_fh_s, '9.2f')}"
        )
    print(
        "ratio = ours / RTKLIB fh (1.0 = parity, above 1 = slower); CLI includes Python start-up, "
        "imports and the .pos write"
    )

    head = (
        f"{'dataset':<9} {'read s':>7} {'setup s':>8} {'loop s':>7} {'loop %':>6} "
        f"{'loop ms/ep':>10} {'loop ep/s':>9}"
    )
    print()
    print(head)
    print("-" * len(head))
    for name, (runs, _clis) in results.items():
        rd = statistics.median(r.read_s for r in runs)
        su = statistics.median(r.setup_s for r in runs)
        lp = statistics.median(r.loop_s for r in runs)
        ep = runs[0].epochs
        print(
            f"{name:<9} {rd:7.3f} {su:8.3f} {lp:7.3f} {100 * lp / (rd + su + lp):6.1f} "
            f"{1e3 * lp / ep:10.2f} {ep / lp:9.1f}"
        )
    print(
        "read = RINEX obs (rover, base) + nav; setup = ephemeris tables, signal rows, SPP start, "
        "slip detectors; loop = run_dd"
    )
    for n in notes:
        print(f"note: {n}")

    if args.profile is not None:
        ds = DATASETS[args.profile]
        d = args.data / ds.folder
        if _missing(d, ds):
            print(f"\nnote: profile of {args.profile} skipped, its files are absent")
        else:
            prof = cProfile.Profile()
            r = solve_once(d, ds, base_position_ecef_m(d / ds.base_pos_file), profiler=prof)
            print(f"\nprofile of the epoch loop on {args.profile}")
            print_profile(prof, r.epochs, r.loop_s)
    return 0


if __name__ == "__main__":
    sys.exit(main())
