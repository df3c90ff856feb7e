"""Runner of the Li et al. (2019) reproduction: simulate and solve every experiment per
seed (:func:`run_task`, a process-pool worker), then compute the statistics, claims,
figures, ``report.md`` and ``results.json`` (:func:`run_li2019`)."""

from __future__ import annotations

import concurrent.futures as cf
import dataclasses
import json
import math
import os
import sys
import time
from collections.abc import Callable

import click
import numpy as np

from robustrtk.campaign.runner import resolve_engine, task_executor
from robustrtk.core import InputError
from robustrtk.estimation.robust import RobustPolicy
from robustrtk.experiments.common import jsonable, output_dir
from robustrtk.experiments.li2019.cells import format_cell
from robustrtk.experiments.li2019.claims import build_claims
from robustrtk.experiments.li2019.figures import make_figures
from robustrtk.experiments.li2019.metrics import aggregate, seed_stats, stat_value
from robustrtk.experiments.li2019.report import Report, write_report
from robustrtk.experiments.li2019.schemes import (
    DEFAULT_SLIP,
    INIT_OFFSETS_M,
    PRIOR_SIGMA_M,
    PRIOR_SIGMAS_SENS_M,
    Q_SIGMAS_M,
    Q_SIGMAS_QUICK_M,
    Raw,
    dpl_config,
    experiment_epochs,
    literal_rukf,
    q_config,
    rtk_config,
)
from robustrtk.geometry.surveyed import SurveyedSource
from robustrtk.io.site import Site
from robustrtk.pipeline.config import Config
from robustrtk.pipeline.engine import DDEngine
from robustrtk.pipeline.loop import run_dd
from robustrtk.sim.pseudolite import SimResult, simulate
from robustrtk.sim.scenario import load_scenario

#: Task groups of the carrier-phase experiments (each task one seed's share, so that the
#: pool balances them); their labels carry no group prefix.
RTK_GROUPS = ("rtk_015", "rtk_static", "rail")
#: Task group of the process-noise sensitivity (one task per seed and σ; no label prefix).
Q_GROUP = "rtk_q"


def _simulate(name: str, seed: int, n: int | None, *, clean: bool = False) -> SimResult:
    sc = load_scenario(name)
    if clean:
        sc = dataclasses.replace(sc, gross=())
    return simulate(sc, np.random.default_rng(seed), n_epochs=n)


def _solve(sim: SimResult, cfg: Config, site: Site | None = None, robust: RobustPolicy | None = None) -> Raw:
    """Solve one simulation; ``robust`` replaces the policy the configuration names."""
    st = site if site is not None else sim.site
    src = SurveyedSource(st.transmitters)
    pos0 = np.asarray(st.rover_initial_pos_m)
    engine = (
        DDEngine(cfg, src, st.base_pos_m, pos0, reference=st.reference, robust=robust)
        if robust is not None
        else None
    )
    res = run_dd(
        sim.batches["rover"], sim.batches["base"], cfg, src, st.base_pos_m, pos0, reference=st.reference,
        engine=engine,
    )  # fmt: skip
    sols = res.solutions
    d = res.diagnostics
    return {
        "t_s": np.array([s.t_s for s in sols]),
        "pos_m": np.array([s.pos_m for s in sols]).reshape(-1, 3),
        "status": np.array([s.status for s in sols]),
        "n_fixed": np.array([s.n_fixed for s in sols], dtype=np.int64),
        "ratio": np.array([s.ratio for s in sols], dtype=float),
        "sigma_3d_m": np.array([math.sqrt(max(float(np.trace(s.cov_m2)), 0.0)) for s in sols]),
        "truth_t_s": sim.t_s,
        "truth_m": sim.truth_pos_m,
        "diag": {
            "t_s": np.array([r.t_s for r in d]),
            "dd": np.array([r.dd for r in d], dtype=str),
            "innovation": np.array([r.innovation for r in d]),
            "residual": np.array([r.residual for r in d]),
            "std_residual": np.array([r.std_residual for r in d]),
            "dv": np.array([r.dv for r in d]),
            "factor": np.array([r.factor for r in d]),
            "situation": np.array([r.situation for r in d], dtype=np.int64),
        },
        "faults": {
            "epoch": sim.faults.epoch.copy(),
            "transmitter": np.array(sim.faults.transmitter),
            "kind": np.array(sim.faults.kind),
            "size": sim.faults.size.copy(),
        },
    }


def _offset_site(site: Site, offset_m: float) -> Site:
    shift = offset_m * np.ones(3) / math.sqrt(3.0)
    if site.rover_initial_pos_m is None:
        raise InputError("the site has no rover initial position to offset")
    return dataclasses.replace(site, rover_initial_pos_m=site.rover_initial_pos_m + shift)


# a top-level function, so that the process pool can pickle it
def run_task(task: tuple[str, str, int, bool]) -> tuple[tuple[str, str, int], dict[str, Raw]]:
    """Simulate and solve one piece of the experiment (process-pool worker).

    Parameters
    ----------
    task : (group, scheme, seed, quick)

    Returns
    -------
    key : (group, scheme, seed)
    raws : dict of label -> raw solution arrays
    """
    group, scheme, seed, quick = task
    n = experiment_epochs(quick)
    out: dict[str, Raw] = {}
    if group in ("dpl", "dpl_rw"):
        sim = _simulate("li2019_dpl_static", seed, n["dpl"])
        dyn = "static" if group == "dpl" else "kinematic"
        out[scheme] = _solve(sim, dpl_config("none" if scheme == "SUKF" else "igg3", dynamics=dyn))
    elif group == "dpl_init":
        filt, off = scheme.split("@")
        sim = _simulate("li2019_dpl_static", seed, n["dpl_init"])
        st = _offset_site(sim.site, float(off))
        out[scheme] = _solve(sim, dpl_config("none", filt.lower()), st)
    elif group == "rtk_static":
        sim = _simulate("li2019_rtk_static", seed, n["rtk_static"])
        clean = _simulate("li2019_rtk_static", seed, n["rtk_static"], clean=True)
        for lab, rob in (("SUKF", "none"), ("RUKF", "igg3")):
            out[f"static/{lab}"] = _solve(sim, rtk_config(rob, "lambda"))
            out[f"static_orig/{lab}"] = _solve(clean, rtk_config(rob, "lambda"))
            # the same data in the paper's per-epoch scheme (variant of Fig. 8)
            out[f"static_prior/{lab}"] = _solve(sim, rtk_config(rob, "lambda", scheme="prior"))
            out[f"static_prior_orig/{lab}"] = _solve(clean, rtk_config(rob, "lambda", scheme="prior"))
        for filt in ("EKF", "UKF"):
            for off_m in INIT_OFFSETS_M:
                out[f"rtk_init/{filt}@{off_m:g}"] = _solve(
                    clean,
                    rtk_config("none", "lambda", filt=filt.lower(), init_sigma_m=max(0.1, off_m)),
                    _offset_site(clean.site, off_m),
                )
    elif group == "rtk_015":
        s15 = _simulate("li2019_rtk_static_015", seed, n["rtk_015"])
        labs = (("SUKF", "none", "lambda"), ("RUKF", "igg3", "lambda"), ("RUKF+PAR", "igg3", "par"))
        for hold in (True, False):
            h = "hold" if hold else "cont"
            for lab, rob, ar in labs:
                out[f"s015_{h}/{lab}"] = _solve(s15, rtk_config(rob, ar, hold=hold))
        # the paper's own scheme (Sec. 2.1): previous coordinate as each epoch's prior; and
        # the same with the solver's default slip detectors (variant)
        for lab, rob, ar in labs:
            out[f"s015_prior/{lab}"] = _solve(s15, rtk_config(rob, ar, scheme="prior"))
            poly = rtk_config(rob, ar, scheme="prior", slip=DEFAULT_SLIP)
            out[f"s015_prior_poly/{lab}"] = _solve(s15, poly)
            kept = rtk_config(rob, ar, scheme="prior", prior_covariance="add")
            out[f"s015_prior_kept/{lab}"] = _solve(s15, kept)
        # the paper's literal RUKF recipe (Δv̄ from the posterior residuals of the nominal
        # update, one re-update) in the paper's scheme; SUKF has no robust policy to change
        out["s015_prior_lit/SUKF"] = out["s015_prior/SUKF"]
        for lab, rob, ar in labs[1:]:
            out[f"s015_prior_lit/{lab}"] = _solve(
                s15, rtk_config(rob, ar, scheme="prior"), robust=literal_rukf()
            )
        # sensitivity to the prior σ (not a paper setting, not in the claims)
        for sig in PRIOR_SIGMAS_SENS_M:
            if sig == PRIOR_SIGMA_M:
                continue
            for lab, rob, ar in labs:
                out[f"s015_prior@{sig:g}/{lab}"] = _solve(
                    s15, rtk_config(rob, ar, scheme="prior", prior_sigma_m=sig)
                )
    elif group == "rail":
        rail = _simulate("li2019_rtk_rail", seed, n["rail"])
        out["rail/SUKF"] = _solve(rail, rtk_config("none", "lambda", dynamics="kinematic"))
        out["rail/RUKF"] = _solve(rail, rtk_config("igg3", "lambda", dynamics="kinematic"))
        r15 = _simulate("li2019_rtk_rail_015", seed, n["rail_015"])
        for inst in (False, True):
            v = "inst" if inst else "hold"
            out[f"rail015_{v}/SUKF"] = _solve(
                r15, rtk_config("none", "lambda", dynamics="kinematic", hold=not inst, inst=inst)
            )
            out[f"rail015_{v}/RUKF+PAR"] = _solve(
                r15, rtk_config("igg3", "par", dynamics="kinematic", hold=not inst, inst=inst)
            )
        out["rail015_prior/SUKF"] = _solve(r15, rtk_config("none", "lambda", scheme="prior"))
        out["rail015_prior/RUKF+PAR"] = _solve(r15, rtk_config("igg3", "par", scheme="prior"))
        # Sec. 3.3.2's "single-epoch PL-AR" read literally: the same scheme, new ambiguities
        # at every epoch
        out["rail015_prior_re/SUKF"] = _solve(
            r15, rtk_config("none", "lambda", scheme="prior", prior_ambiguities="reestimate")
        )
        out["rail015_prior_re/RUKF+PAR"] = _solve(
            r15, rtk_config("igg3", "par", scheme="prior", prior_ambiguities="reestimate")
        )
    elif group == Q_GROUP:
        # fix-and-hold with a coordinate random walk of σ per epoch (the paper's f = I with
        # a Q it does not state): Fig. 8's data with and without its errors, and Fig. 9's
        q = float(scheme)
        sim = _simulate("li2019_rtk_static", seed, n["rtk_static"])
        clean = _simulate("li2019_rtk_static", seed, n["rtk_static"], clean=True)
        s15 = _simulate("li2019_rtk_static_015", seed, n["rtk_015"])
        labs = (("SUKF", "none", "lambda"), ("RUKF", "igg3", "lambda"), ("RUKF+PAR", "igg3", "par"))
        for lab, rob, ar in labs:
            cfg = q_config(rob, ar, q)
            if ar == "lambda":
                out[f"static_q@{q:g}/{lab}"] = _solve(sim, cfg)
                out[f"static_q@{q:g}_orig/{lab}"] = _solve(clean, cfg)
            out[f"s015_q@{q:g}/{lab}"] = _solve(s15, cfg)
    else:  # pragma: no cover - internal
        raise ValueError(f"unknown task group {group!r}")
    return (group, scheme, seed), out


def _tasks(seed: int, quick: bool, first: bool = True) -> list[tuple[str, str, int, bool]]:
    """The tasks of one seed; the filter-memory sensitivity (``dpl_rw``, not a paper
    setting) only for the first seed."""
    groups = ("dpl", "dpl_rw") if first else ("dpl",)
    t: list[tuple[str, str, int, bool]] = [(g, sch, seed, quick) for g in groups for sch in ("SUKF", "RUKF")]
    t += [(g, "all", seed, quick) for g in RTK_GROUPS]
    t += [(Q_GROUP, f"{q:g}", seed, quick) for q in (Q_SIGMAS_QUICK_M if quick else Q_SIGMAS_M)]
    t += [("dpl_init", f"{f}@{o:g}", seed, quick) for f in ("EKF", "UKF") for o in INIT_OFFSETS_M]
    return t


def run_li2019(
    out_dir: str | os.PathLike[str],
    runs: int = 1,
    seed: int = 0,
    workers: int | None = None,
    progress: bool | Callable[[int, int], None] = True,
    quick: bool = False,
    engine: str = "local",
    scheduler: str | None = None,
) -> Report:
    """Simulate and solve every experiment of Li et al. (2019); write ``report.md``,
    ``results.json`` and the PNG figures to ``out_dir``.

    Parameters
    ----------
    out_dir : path
        Output directory (created).
    runs : int
        Number of seeds (``seed, seed + 1, ...``); statistics are medians and 5/95
        percentiles over runs.
    seed : int
        First seed.
    workers : int, optional
        Worker processes (default: all cores; 1 runs in this process).
    engine : {"local", "dask", "auto"}
        Where the tasks run: a local process pool (default), or Dask (a local cluster of
        ``workers`` processes, or the cluster at ``scheduler``); as ``robustrtk batch``.
    scheduler : str, optional
        Address of a running Dask scheduler.
    progress : bool or callable (done, total)
        Show click's progress bar on stderr (True), or call this after each finished
        simulation-and-solve task (the command line's bar).
    quick : bool
        Shorten every experiment (tests).

    Returns
    -------
    Report
    """
    if runs < 1:
        raise InputError(f"runs must be at least 1, got {runs}")
    resolve_engine(engine, scheduler)  # a bad engine choice fails before any work
    t0 = time.perf_counter()
    out = output_dir(out_dir)
    seeds = [seed + i for i in range(runs)]
    tasks = [t for s in seeds for t in _tasks(s, quick, first=s == seeds[0])]
    # longest tasks first so that the pool stays busy
    order = {"dpl": 0, "dpl_rw": 1, **{g: 2 for g in (*RTK_GROUPS, Q_GROUP)}}
    tasks.sort(key=lambda t: order.get(t[0], 3))
    n_workers = workers if workers is not None else (os.cpu_count() or 1)
    results: dict[int, dict[str, Raw]] = {s: {} for s in seeds}

    def collect(key: tuple[str, str, int], raws: dict[str, Raw]) -> None:
        group, _, s = key
        prefix = "" if group in (*RTK_GROUPS, Q_GROUP) else f"{group}/"
        for lab, raw in raws.items():
            results[s][prefix + lab] = raw

    if callable(progress):
        tick: Callable[[int, int], None] | None = progress
        bar = None
    else:
        tick = None
        bar = click.progressbar(length=len(tasks), label="li2019", file=sys.stderr) if progress else None
    done = 0

    def advance() -> None:
        nonlocal done
        done += 1
        if bar is not None:
            bar.update(1)
        if tick is not None:
            tick(done, len(tasks))

    try:
        if bar is not None:
            bar.__enter__()
        if n_workers <= 1 and engine == "local" and scheduler is None:
            for t in tasks:
                collect(*run_task(t))
                advance()
        else:
            with task_executor(engine, min(n_workers, len(tasks)), scheduler) as pool:
                futs = [pool.submit(run_task, t) for t in tasks]
                for fut in cf.as_completed(futs):
                    collect(*fut.result())
                    advance()
    finally:
        if bar is not None:
            bar.__exit__(None, None, None)

    per_run = [seed_stats(results[s]) for s in seeds]
    stats = aggregate(per_run)
    n_dpl = int(results[seeds[0]]["dpl/RUKF"]["t_s"].size)

    def s(key: str) -> float:
        return stat_value(stats, key)

    def f(key: str, fmt: str) -> str:
        return format_cell(stats[key], fmt, 1)

    claims = build_claims(s, n_dpl, f)
    figs = make_figures(results[seeds[0]], out)
    elapsed = time.perf_counter() - t0
    report_path = write_report(out, stats, claims, figs, runs, seeds, n_dpl, elapsed, quick)
    results_path = out / "results.json"
    results_path.write_text(
        json.dumps(
            jsonable(
                {
                    "paper": "Li et al. (2019), Sensors 19(17), 3755",
                    "runs": runs,
                    "seeds": seeds,
                    "quick": quick,
                    "dpl_epochs": n_dpl,
                    "elapsed_s": elapsed,
                    "stats": stats,
                    "per_run": per_run,
                    "claims": [dataclasses.asdict(c) for c in claims],
                    "figures": sorted(figs),
                }
            ),
            indent=1,
        ),
        encoding="utf-8",
    )
    return Report(
        out_dir=out,
        report_path=report_path,
        results_path=results_path,
        stats=stats,
        per_run=per_run,
        claims=claims,
        figures=[out / p for p in figs.values()],
        elapsed_s=elapsed,
        seeds=seeds,
    )


__all__ = ["run_li2019", "run_task"]
