"""Runner of the Zhou et al. (2018) reproduction: per seed simulate a clean and a degraded
session (:func:`robustrtk.sim.coop.simulate_coop`) and solve them with every filter and
cooperation mode (:func:`run_task`, a process-pool worker); then save ``runs.npz``, compute
the statistics and claims from it, draw the figures and write ``report.md`` and
``results.json`` (:func:`run_zhou2018`)."""

from __future__ import annotations

import concurrent.futures as cf
import dataclasses
import json
import os
import sys
import time
from pathlib import Path
from typing import Any

import click
import numpy as np

from robustrtk.campaign.runner import resolve_engine, task_executor
from robustrtk.core import InputError
from robustrtk.experiments.common import jsonable, output_dir
from robustrtk.experiments.zhou2018.metrics import (
    FILTERS,
    MODES,
    MUTUAL_FILTERS,
    SCENARIOS,
    all_stats,
    build_claims,
    node1_and_mutual_stats,
)
from robustrtk.experiments.zhou2018.report import make_figures, write_report
from robustrtk.experiments.zhou2018.solve import solve_pair
from robustrtk.io.rinex_nav import read_rinex_nav
from robustrtk.pipeline.config import ZHOU2018_PRESET
from robustrtk.sim.coop import CoopSimSpec, simulate_coop

#: Broadcast orbits used by default (GPS and BeiDou, 2024-06-24), relative to the repository.
DEFAULT_NAV = (
    Path(__file__).resolve().parents[4] / ".." / "shared" / "data" / "mosaicx5_static_1m" / "base.nav"
)
#: First epoch: 2024-06-24 08:20:00 GPST (inside the file's ephemeris validity).
DEFAULT_T0_S = 1403252400.0


def run_task(task: tuple[str, int, bool]) -> tuple[int, dict[str, Any]]:
    """Simulate and solve one seed; returns ``(seed, arrays)``."""
    nav_path, seed, quick = task
    nav = read_rinex_nav(nav_path)
    spec = (
        CoopSimSpec(t0_s=DEFAULT_T0_S, n_epochs=20, bias_epochs=(8, 14))
        if quick
        else CoopSimSpec(t0_s=DEFAULT_T0_S)
    )
    cfg = ZHOU2018_PRESET.updated(n_particles=300 if quick else 1000)
    out: dict[str, Any] = {}
    for sc in SCENARIOS:
        sim = simulate_coop(nav, spec, np.random.default_rng(seed), degraded=sc == "degraded")
        out[f"{sc}/truth2"] = sim.nodes[1].truth_ecef_m
        out[f"{sc}/truth1"] = sim.nodes[0].truth_ecef_m
        out[f"{sc}/n_gps2"] = sim.nodes[1].n_seen("G")
        out[f"{sc}/n_bds2"] = sim.nodes[1].n_seen("C")
        out[f"{sc}/n_sats1"] = sim.nodes[0].n_seen("G") + sim.nodes[0].n_seen("C")
        out[f"{sc}/fault1"] = sim.nodes[0].fault_m.any(axis=1)
        for f in FILTERS:
            node1 = None
            for m in MODES:
                sol = solve_pair(sim, f, m, cfg, seed=1000 * seed, node1=node1)
                node1 = sol
                out[f"{sc}/{f}/{m}/pos2"] = sol.pos_m[1]
                out[f"{sc}/{f}/{m}/pos1"] = sol.pos_m[0]
                out[f"{sc}/{f}/{m}/range_sigma2"] = sol.range_sigma_m[1]
                out[f"{sc}/{f}/{m}/trace_p1"] = sol.trace_p_m2[0]
        if sc == "clean":
            # both nodes cooperating: node 1 also uses the range to node 2's broadcast
            for f in MUTUAL_FILTERS:
                for m in ("traditional", "improved"):
                    sol = solve_pair(sim, f, m, cfg, seed=1000 * seed, mutual=True)
                    out[f"mutual/{f}/{m}/pos2"] = sol.pos_m[1]
                    out[f"mutual/{f}/{m}/pos1"] = sol.pos_m[0]
    return seed, out


def load_errors(npz: Any) -> dict[str, dict[str, np.ndarray]]:
    """Node 2's error arrays ``err[scenario]["filter/mode"]`` (R, T, 3) from ``runs.npz``."""
    return {
        sc: {
            f"{f}/{m}": npz[f"{sc}/{f}/{m}/pos2"] - npz[f"{sc}/truth2"][:, None, :]
            for f in FILTERS
            for m in MODES
        }
        for sc in SCENARIOS
    }


@dataclasses.dataclass(frozen=True)
class Report:
    out_dir: Path
    report_path: Path
    results_path: Path
    runs_path: Path
    claims: list[Any]
    figures: list[Path]
    elapsed_s: float


def run_zhou2018(
    out_dir: str | os.PathLike[str],
    runs: int = 1,
    seed: int = 0,
    workers: int | None = None,
    progress: bool = True,
    quick: bool = False,
    nav: str | os.PathLike[str] | None = None,
    engine: str = "local",
    scheduler: str | None = None,
) -> Report:
    """Run the study for seeds ``seed .. seed + runs − 1`` and write ``runs.npz``,
    ``results.json``, ``report.md`` and the figures to ``out_dir``.

    ``workers`` processes of a local pool run the seeds (``engine="local"``, the default;
    one worker runs them in this process), or Dask does (``engine="dask"``: a local
    cluster of ``workers`` processes, or the cluster at ``scheduler``; as ``robustrtk batch``).

    Raises
    ------
    InputError
        Bad arguments, a missing navigation file, an unwritable directory, or Dask asked
        for and not installed or not reachable.
    """
    if runs < 1:
        raise InputError(f"runs must be at least 1, got {runs}")
    resolve_engine(engine, scheduler)  # a bad engine choice fails before any work
    env = os.environ.get("ROBUSTRTK_SHARED_DATA")
    default = Path(env) / "mosaicx5_static_1m" / "base.nav" if env else DEFAULT_NAV
    nav_path = Path(nav) if nav is not None else default
    if not nav_path.is_file():
        raise InputError("navigation file not found (pass --nav)", path=str(nav_path))
    t0 = time.perf_counter()
    out = output_dir(out_dir)
    seeds = [seed + i for i in range(runs)]
    tasks = [(str(nav_path), s, quick) for s in seeds]
    n_workers = workers if workers is not None else (os.cpu_count() or 1)
    results: dict[int, dict[str, Any]] = {}
    bar = click.progressbar(length=len(tasks), label="zhou2018", file=sys.stderr) if progress else None
    try:
        if bar is not None:
            bar.__enter__()
        if (n_workers <= 1 or len(tasks) == 1) and engine == "local" and scheduler is None:
            for t in tasks:
                s, r = run_task(t)
                results[s] = r
                if bar is not None:
                    bar.update(1)
        else:
            with task_executor(engine, min(n_workers, len(tasks)), scheduler) as pool:
                for fut in cf.as_completed([pool.submit(run_task, t) for t in tasks]):
                    s, r = fut.result()
                    results[s] = r
                    if bar is not None:
                        bar.update(1)
    finally:
        if bar is not None:
            bar.__exit__(None, None, None)
    keys = list(results[seeds[0]])
    arrays = {k: np.stack([np.asarray(results[s][k]) for s in seeds]) for k in keys}
    arrays["seeds"] = np.array(seeds)
    runs_path = out / "runs.npz"
    np.savez_compressed(runs_path, **arrays)  # type: ignore[arg-type]  # numpy stub: kwargs typed as bool
    with np.load(runs_path) as npz:
        err = load_errors(npz)
        stats = all_stats(err)
        extra = node1_and_mutual_stats(npz)
        claims = build_claims(stats, extra)
        figs = make_figures(npz, out)
        vis = {
            "node2_gps_max": int(npz["clean/n_gps2"].max()),
            "node2_gps_mean": float(npz["clean/n_gps2"].mean()),
            "node2_bds_min": int(npz["clean/n_bds2"].min()),
            "node2_bds_max": int(npz["clean/n_bds2"].max()),
            "node2_bds_mean": float(npz["clean/n_bds2"].mean()),
            "node1_sats_mean": float(npz["clean/n_sats1"].mean()),
            "n_epochs": int(npz["clean/n_gps2"].shape[1]),
        }
    elapsed = time.perf_counter() - t0
    report_path = write_report(out, stats, extra, claims, figs, seeds, vis, elapsed, quick, nav_path)
    results_path = out / "results.json"
    results_path.write_text(
        json.dumps(
            jsonable(
                {
                    "paper": "Zhou et al. (2018), Computers, Materials & Continua 56(2), 225-245",
                    "runs": runs,
                    "seeds": seeds,
                    "quick": quick,
                    "nav": str(nav_path),
                    "elapsed_s": elapsed,
                    "visibility": vis,
                    "stats": stats,
                    "node1_and_mutual": extra,
                    "claims": [dataclasses.asdict(c) for c in claims],
                    "figures": sorted(figs.values()),
                }
            ),
            indent=1,
        ),
        encoding="utf-8",
    )
    return Report(
        out, report_path, results_path, runs_path, claims, [out / p for p in figs.values()], elapsed
    )


__all__ = ["DEFAULT_NAV", "DEFAULT_T0_S", "Report", "load_errors", "run_task", "run_zhou2018"]
