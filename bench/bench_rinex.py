"""Speed of :func:`robustrtk.io.rinex_obs.read_rinex_obs` on the shared observation files.

Prints one row per file: size, epochs, median wall time of ``--runs`` reads, MB/s and
epochs/s, and (when ``georinex`` is importable and ``--no-georinex`` is not given) the wall
time of ``georinex.load`` on the same file, read once when it is slow.

Usage::

    python bench/bench_rinex.py [--runs 7] [--no-georinex] [--data DIR]
"""

from __future__ import annotations

import argparse
import importlib
import os
import statistics
import sys
import time
import warnings
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import Any

from robustrtk.io.rinex_obs import read_rinex_obs

FILES = (
    "geonet_0759_3040_static_3km/07590920.05o",
    "geonet_0759_3040_static_3km/30400920.05o",
    "mosaicx5_static_1m/rover.obs",
    "mosaicx5_static_1m/base.obs",
    "kamakura_kinematic_5km/SEPT265G.21O",
    "kamakura_kinematic_5km/3034265G.21O",
    "gsdc2021_mtv1_pixel5_phone/Pixel5/supplemental/Pixel5_GnssLog.21o",
)


def _default_data() -> Path:
    env = os.environ.get("ROBUSTRTK_SHARED_DATA")
    if env:
        return Path(env)
    return Path(__file__).resolve().parents[1].parent / "shared" / "data"


def _median_time(fn: Callable[[], object], runs: int, budget_s: float = 5.0) -> float:
    """Median wall time (s) of ``runs`` calls, fewer when one call exceeds ``budget_s``."""
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
        if times[-1] > budget_s:
            break
    return statistics.median(times)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=7)
    ap.add_argument("--no-georinex", action="store_true")
    ap.add_argument("--data", type=Path, default=_default_data())
    args = ap.parse_args(argv)
    if not args.data.is_dir():
        print(f"shared data not found at {args.data}; nothing to measure")
        return 0
    gr: Any = None
    if not args.no_georinex:
        try:
            gr = importlib.import_module("georinex")  # optional, not a project dependency
        except ImportError:
            gr = None
    head = f"{'file':<28} {'MB':>6} {'epochs':>6} {'ms':>8} {'MB/s':>7} {'epochs/s':>9}"
    if gr is not None:
        head += f" {'georinex ms':>12} {'speed-up':>9}"
    print(head)
    print("-" * len(head))
    for rel in FILES:
        path = args.data / rel
        if not path.is_file():
            continue
        mb = path.stat().st_size / 1e6
        read_rinex_obs(path)  # warm the page cache and imports
        n_ep = len(read_rinex_obs(path))
        t = _median_time(partial(read_rinex_obs, path), args.runs)
        row = f"{Path(rel).name:<28} {mb:6.2f} {n_ep:6d} {1e3 * t:8.1f} {mb / t:7.1f} "
        row += f"{n_ep / t:9.0f}"
        if gr is not None:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                tg = _median_time(partial(gr.load, path), args.runs, budget_s=1.0)
            row += f" {1e3 * tg:12.1f} {tg / t:9.1f}"
        print(row, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
