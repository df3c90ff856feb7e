"""``robustrtk experiment ...``: reproductions of published experiments (simulated, phone-profiled data)."""

from __future__ import annotations

import functools
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, NamedTuple, NoReturn

import click

from robustrtk.cli.errors import one_line
from robustrtk.errors import InputError


@click.group("experiment", context_settings={"help_option_names": ["-h", "--help"]})
def experiment() -> None:
    """Reproduce a paper's experiments end to end (simulate, solve, report)."""


_Decorated = Callable[..., Any]


class _Seeds(NamedTuple):
    """The Monte Carlo options of an experiment, checked: seeds ``seed .. seed + runs − 1``
    run by ``workers`` processes (None: all cores) of ``engine`` (at ``scheduler``)."""

    runs: int
    seed: int
    workers: int | None
    engine: str
    scheduler: str | None


def _seed_options(runs_help: str) -> Callable[[_Decorated], _Decorated]:
    """The options ``--runs`` (described by ``runs_help``), ``--seed`` and ``--workers``, in
    this order; with those of :func:`_cluster_options` (applied below it) they reach the
    command as one checked :class:`_Seeds` argument ``seeds``, or a one-line error."""

    def apply(f: _Decorated) -> _Decorated:
        @functools.wraps(f)
        def command(
            *, runs: int, seed: int, workers: int | None, engine: str | None, scheduler: str | None, **kw: Any
        ) -> Any:
            try:
                _check_counts(runs, workers)
            except InputError as exc:
                _fail(exc)
            return f(seeds=_Seeds(runs, seed, workers, _engine(engine, scheduler), scheduler), **kw)

        g: _Decorated = click.option(
            "--workers", type=int, default=None, help="Worker processes [all cores]."
        )(command)
        g = click.option("--seed", type=int, default=0, show_default=True, help="First seed.")(g)
        return click.option("--runs", type=int, default=1, show_default=True, help=runs_help)(g)

    return apply


def _cluster_options(f: _Decorated) -> _Decorated:
    """The options ``--engine`` and ``--scheduler`` of where the seeds' tasks run."""
    f = click.option(
        "--scheduler", default=None, help="Address of a running Dask scheduler (a real cluster)."
    )(f)
    return click.option(
        "--engine",
        type=click.Choice(["local", "dask", "auto"]),
        default=None,
        help="Where the seeds' tasks run: a local process pool, or Dask (a local cluster, or the "
        "cluster at --scheduler) [local; dask with --scheduler].",
    )(f)


def _engine(engine: str | None, scheduler: str | None) -> str:
    """The experiments' default engine: the local pool, or Dask when a scheduler is given."""
    if engine is not None:
        return engine
    return "dask" if scheduler is not None else "local"


def _out_option(default: str, contents: str) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """The ``--out`` option (into ``out_dir``) with its default folder and what is written there."""
    return click.option(
        "--out",
        "out_dir",
        type=click.Path(),
        default=default,
        show_default=True,
        help=f"Output directory for {contents}.",
    )


def _check_counts(runs: int, workers: int | None) -> None:
    """Reject ``--runs`` or ``--workers`` below one (:class:`InputError` naming the flag)."""
    if runs < 1:
        raise InputError(f"--runs must be at least 1, got {runs}")
    if workers is not None and workers < 1:
        raise InputError(f"--workers must be at least 1, got {workers}")


def _fail(exc: InputError) -> NoReturn:
    """Print ``exc`` as a one-line error and exit with status 2."""
    click.echo(f"error: {one_line(str(exc))}", err=True)
    sys.exit(2)


def _echo_written(
    report_path: Path, results_path: Path, n_figures: int, elapsed_s: float, holds: Sequence[bool | None]
) -> None:
    """Print what an experiment wrote, its wall time (s) and how many of its claims hold
    (``holds``: True, False or None; only True counts)."""
    click.echo(
        f"wrote {report_path} and {results_path} ({n_figures} figures) "
        f"in {elapsed_s:.0f} s; {sum(1 for h in holds if h)}/{len(holds)} claims hold"
    )


@experiment.command("li2019")
@_out_option("li2019_report", "report.md, results.json, figures")
@_seed_options("Number of seeds; statistics become median and 5–95 % range over runs.")
@click.option("--quick", is_flag=True, help="Shortened experiments (smoke test).")
@click.option("--no-progress", is_flag=True, help="Hide the progress bar.")
@click.option("--quiet", is_flag=True, help="No progress bar (the same as --no-progress).")
@_cluster_options
def li2019(out_dir: str, seeds: _Seeds, quick: bool, no_progress: bool, quiet: bool) -> None:
    """Li et al. (2019): RUKF + PAR for indoor pseudolite DPL and RTK."""
    from robustrtk.cli.progress import ProgressBar, bar_wanted
    from robustrtk.experiments.li2019 import run_li2019

    s = seeds
    try:
        with ProgressBar("li2019", "tasks", enabled=bar_wanted(quiet or no_progress)) as bar:
            rep = run_li2019(
                out_dir, runs=s.runs, seed=s.seed, workers=s.workers, progress=bar, quick=quick,
                engine=s.engine, scheduler=s.scheduler,
            )  # fmt: skip
    except InputError as exc:
        _fail(exc)
    _echo_written(
        rep.report_path, rep.results_path, len(rep.figures), rep.elapsed_s, [c.holds for c in rep.claims]
    )


@experiment.command("smartphone")
@_out_option("smartphone_report", "report.md and results.json")
@click.option(
    "--data",
    "data_root",
    type=click.Path(),
    default="../shared/data",
    show_default=True,
    help="Shared data folder (mosaicx5_static_1m, kamakura_kinematic_5km).",
)
@click.option("--seeds", default="0,1,2", show_default=True, help="Phone-profile seeds, comma separated.")
@click.option("--datasets", default="mosaicx5,kamakura", show_default=True, help="Datasets, comma separated.")
def smartphone(out_dir: str, data_root: str, seeds: str, datasets: str) -> None:
    """KF vs robust vs robust-adaptive KF on phone-profiled real data (DGNSS and RTK)."""
    from robustrtk.experiments.smartphone import run_smartphone

    try:
        try:
            seed_t = tuple(int(s) for s in seeds.split(",") if s.strip())
        except ValueError:
            raise InputError(f"--seeds: expected integers separated by commas, got {seeds!r}") from None
        if not seed_t:
            raise InputError("--seeds: give at least one seed")
        names = tuple(d.strip() for d in datasets.split(",") if d.strip())
        rep = run_smartphone(out_dir, data_root, seeds=seed_t, datasets=names)
    except InputError as exc:
        _fail(exc)
    n_hold = sum(1 for c in rep.claims if c[1])
    click.echo(
        f"wrote {rep.report_path} and {rep.results_path} in {rep.elapsed_s:.0f} s; "
        f"{n_hold}/{len(rep.claims)} claims hold"
    )


@experiment.command("zhou2018")
@_out_option("zhou2018_report", "report.md, results.json, runs.npz, figures")
@_seed_options("Number of seeds (Monte Carlo runs).")
@click.option(
    "--nav", type=click.Path(), default=None, help="RINEX navigation file with GPS and BeiDou orbits."
)
@click.option("--quick", is_flag=True, help="Shortened experiment (smoke test).")
@click.option("--no-progress", is_flag=True, help="Hide the progress bar.")
@_cluster_options
def zhou2018(out_dir: str, seeds: _Seeds, nav: str | None, quick: bool, no_progress: bool) -> None:
    """Zhou et al. (2018): cooperative EKF / UKF / PF of two static nodes."""
    from robustrtk.experiments.zhou2018 import run_zhou2018

    s = seeds
    try:
        rep = run_zhou2018(
            out_dir, runs=s.runs, seed=s.seed, workers=s.workers, progress=not no_progress, quick=quick,
            nav=nav, engine=s.engine, scheduler=s.scheduler,
        )  # fmt: skip
    except InputError as exc:
        _fail(exc)
    _echo_written(
        rep.report_path, rep.results_path, len(rep.figures), rep.elapsed_s, [c.holds for c in rep.claims]
    )


__all__ = ["experiment"]
