"""``robustrtk batch JOBS``: many ``solve`` runs in parallel, on Dask or a process pool.

Each job of the list (:func:`robustrtk.campaign.jobs.read_jobs`, format in docs/batch.md)
is the ``robustrtk solve`` command with the job's files and flags, run as a child process of
a worker, so its output is byte for byte the output of the same command run alone. A failed job
(bad input, nothing solved, an exception) is reported in the summary and the others go on.
Exit status: 0 when every job succeeded, 1 when some failed, 2 for a bad job list or option.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from robustrtk.cli.errors import one_line, one_line_errors

if TYPE_CHECKING:  # the campaign machinery is imported when the command runs (start-up time)
    from robustrtk.campaign.jobs import Job
    from robustrtk.campaign.runner import JobResult

#: ``--engine`` choices (:data:`robustrtk.campaign.runner.ENGINES`; a test keeps them equal).
ENGINE_CHOICES = ("auto", "dask", "local")

#: ``.pos`` quality flag -> solution status (RTKLIB's Q; robustrtk writes partial fixes as 1).
_POS_Q = {"1": "fixed", "2": "float", "3": "sbas", "4": "dgnss", "5": "single", "6": "ppp"}


def output_counts(path: str) -> dict[str, int]:
    """Epochs per status of a written solution: ``.pos`` by its Q column, ``.csv`` by its
    ``status`` column; empty for other formats."""
    p = Path(path)
    counts: dict[str, int] = {}
    suffix = p.suffix.lower()
    if suffix == ".pos":
        for line in p.read_text(errors="replace").splitlines():
            words = line.split()
            if len(words) > 5 and not line.startswith("%"):
                st = _POS_Q.get(words[5], "none")
                counts[st] = counts.get(st, 0) + 1
    elif suffix == ".csv":
        lines = p.read_text(errors="replace").splitlines()
        if lines:
            cols = lines[0].split(",")
            if "status" in cols:
                k = cols.index("status")
                for line in lines[1:]:
                    words = line.split(",")
                    if len(words) > k:
                        counts[words[k]] = counts.get(words[k], 0) + 1
    return counts


def solve_command() -> list[str]:
    """The command that runs ``robustrtk`` with this interpreter (``python -m robustrtk``)."""
    return [sys.executable, "-m", "robustrtk"]


def solve_job(job: Job) -> JobResult:
    """Run ``robustrtk solve`` for ``job`` as a child process of this worker; never raises.

    A process of its own per job: the output is that of the same command run alone, a crash
    or a leak stays inside the job, and the worker returns the memory when it ends. A
    failure's reason is the last line of the solve's stderr (its one-line error).
    """
    import subprocess

    from robustrtk.campaign.runner import JobResult, worker_label

    t0 = time.perf_counter()
    try:
        Path(job.out).parent.mkdir(parents=True, exist_ok=True)
        proc = subprocess.run(
            [*solve_command(), *job.solve_args()],
            stdin=subprocess.DEVNULL,
            capture_output=True,
            text=True,
            errors="replace",
            check=False,
        )
        status = proc.returncode
        lines = [ln.strip() for ln in proc.stderr.splitlines() if ln.strip()]
        error = (
            "" if status == 0 else (lines[-1].removeprefix("error: ") if lines else f"exit status {status}")
        )
    except OSError as exc:  # the output folder cannot be made, the interpreter cannot start
        status, error = 1, f"{type(exc).__name__}: {one_line(str(exc))}"
    wall = time.perf_counter() - t0
    ok = status == 0 and Path(job.out).is_file()
    if status == 0 and not ok:
        status, error = 1, "no output written"
    counts = output_counts(job.out) if ok else {}
    return JobResult(
        name=job.name,
        out=job.out,
        ok=ok,
        status=status,
        error=error,
        epochs=sum(counts.values()),
        counts=counts,
        wall_s=wall,
        worker=worker_label(),
    )


def _progress(quiet: bool) -> tuple[Any, Any]:
    """``on_done`` callback and a closer: a bar on a terminal, one line per job otherwise."""
    if quiet:
        return None, lambda: None
    from robustrtk.cli.progress import ProgressBar, bar_wanted

    if bar_wanted(False):
        bar = ProgressBar("batch", "jobs")

        def on_bar(res: JobResult, done: int, total: int) -> None:
            bar(done, total)

        return on_bar, bar.close

    def on_done(res: JobResult, done: int, total: int) -> None:
        word = "ok" if res.ok else f"FAILED: {res.error}"
        click.echo(f"[{done}/{total}] {res.name}: {word} ({res.wall_s:.1f} s)", err=True)

    return on_done, lambda: None


@click.command("batch")
@click.argument("jobs", type=click.Path())
@click.option(
    "--engine",
    type=click.Choice(ENGINE_CHOICES),
    default="auto",
    show_default=True,
    help="dask (a local cluster, or --scheduler), local (a process pool), auto (dask if installed).",
)
@click.option(
    "--workers", type=int, default=2, show_default=True, help="Worker processes of the local cluster or pool."
)
@click.option("--scheduler", default=None, help="Address of a running Dask scheduler (tcp://host:8786).")
@click.option(
    "--summary",
    "summary_csv",
    type=click.Path(dir_okay=False),
    default=None,
    help="Also write the summary as CSV.",
)
@click.option("--quiet", is_flag=True, help="No progress; the summary table only.")
@one_line_errors
def batch(
    jobs: str, engine: str, workers: int, scheduler: str | None, summary_csv: str | None, quiet: bool
) -> None:
    """Solve every job of JOBS (a .toml or .csv job list, or a folder of them) in parallel.

    Each job is one `robustrtk solve` run (rover, base, nav, base_pos, mode, out, config,
    args): same output as that run alone. Failed jobs are listed and do not stop the
    others; exit status 1 when any failed. Job format: docs/batch.md.
    """
    from robustrtk.campaign.jobs import read_jobs
    from robustrtk.campaign.runner import run_jobs, summary_table

    job_list = read_jobs(jobs)
    on_done, close = _progress(quiet)
    t0 = time.perf_counter()
    try:
        results = run_jobs(
            job_list, solve_job, engine=engine, workers=workers, scheduler=scheduler, on_done=on_done
        )
    finally:
        close()
    dt = time.perf_counter() - t0
    click.echo(summary_table(results))
    click.echo(f"{len(results)} jobs in {dt:.1f} s")
    if summary_csv:
        _write_summary_csv(results, summary_csv)
    if not all(r.ok for r in results):
        sys.exit(1)


def _write_summary_csv(results: list[JobResult], path: str) -> None:
    import csv

    from robustrtk.io.atomic import atomic_paths

    with atomic_paths([path]) as (tmp,), open(tmp, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(["job", "ok", "status", "epochs", "fixed", "wall_s", "worker", "out", "error"])
        for r in results:
            fixed = r.counts.get("fixed", 0) + r.counts.get("partial", 0)
            w.writerow(
                [r.name, int(r.ok), r.status, r.epochs, fixed, f"{r.wall_s:.3f}", r.worker, r.out, r.error]
            )


__all__ = ["batch", "output_counts", "solve_command", "solve_job"]
