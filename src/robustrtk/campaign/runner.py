"""Run a campaign's jobs in parallel: on Dask (local cluster or a scheduler) or a process pool.

:func:`run_jobs` submits one task per job and collects the results as they finish; a job
that fails (bad input, an exception in the solver, a worker lost) becomes a failed
:class:`JobResult` and never stops the others. The task itself (``fn``) comes from the
caller — ``robustrtk batch`` passes the ``solve`` command — so this module knows nothing of
the solvers.

Engines:

* ``dask``: :class:`distributed.Client` on a :class:`distributed.LocalCluster` of
  ``workers`` single-threaded worker processes, or on the scheduler at ``scheduler``
  (``tcp://host:8786``; the workers must see the same file paths). Needs the optional
  extra ``pip install 'robustrtk[dask]'``.
* ``local``: :class:`concurrent.futures.ProcessPoolExecutor` with ``workers`` processes.
* ``auto``: ``dask`` when it is installed, else ``local``.
"""

from __future__ import annotations

import concurrent.futures as cf
import importlib.util
import os
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from robustrtk.campaign.jobs import Job
from robustrtk.errors import InputError
from robustrtk.io.tables import format_table

if TYPE_CHECKING:
    from concurrent.futures import Future

ENGINES = ("auto", "dask", "local")

#: Dask settings of the local cluster this module starts (a scheduler given by address keeps
#: its own): the background work a cluster does for its dashboard and diagnostics, which
#: nobody reads here, shares the cores with the jobs. Each worker's sampling profiler takes
#: the GIL from the running job every 10 ms; the event-loop tick (20 ms), the system monitor
#: (0.5 s) and the memory monitor (0.1 s) wake every process. Measured on two cores, eight RTK
#: jobs: the jobs' own time −7 % on one worker and −11 % on two (``bench/bench_batch.py``).
LOCAL_CLUSTER_CONFIG: dict[str, object] = {
    "distributed.worker.profile.enabled": False,
    "distributed.admin.tick.interval": "1s",
    "distributed.admin.system-monitor.interval": "5s",
    "distributed.worker.memory.monitor-interval": "1s",
}

DASK_MISSING = (
    "the dask engine needs dask and distributed: pip install 'robustrtk[dask]' (or run with --engine local)"
)


@dataclass
class JobResult:
    """Outcome of one job.

    Attributes
    ----------
    name, out : str
        The job's name and output file.
    ok : bool
        The job wrote its output.
    status : int
        Exit status of the solve (0 ok, 2 bad input, 3 nothing solved, 1 other failure).
    error : str
        One-line reason of a failure (empty when ``ok``).
    epochs : int
        Solution epochs written.
    counts : dict of str to int
        Epochs per solution status (``fixed``, ``float``, ...).
    wall_s : float
        Wall time of the job on its worker (s).
    worker : str
        ``host:pid`` of the process that ran it.
    """

    name: str
    out: str
    ok: bool
    status: int = 0
    error: str = ""
    epochs: int = 0
    counts: dict[str, int] = field(default_factory=dict)
    wall_s: float = float("nan")
    worker: str = ""


def worker_label() -> str:
    """``host:pid`` of the calling process."""
    import socket

    return f"{socket.gethostname()}:{os.getpid()}"


def dask_available() -> bool:
    """Both ``dask`` and ``distributed`` can be imported."""
    return all(importlib.util.find_spec(m) is not None for m in ("dask", "distributed"))


def resolve_engine(engine: str, scheduler: str | None) -> str:
    """``dask`` or ``local`` for ``engine`` (``auto`` picks dask when installed).

    Raises
    ------
    InputError
        Unknown engine; dask asked for (``--engine dask`` or ``--scheduler``) but not installed;
        ``--scheduler`` with the local engine.
    """
    if engine not in ENGINES:
        raise InputError(f"--engine: expected one of {', '.join(ENGINES)}, got {engine!r}")
    if scheduler is not None:
        if engine == "local":
            raise InputError("--scheduler: needs the dask engine, not --engine local")
        if not dask_available():
            raise InputError(f"--scheduler: {DASK_MISSING}")
        return "dask"
    if engine == "dask" and not dask_available():
        raise InputError(f"--engine dask: {DASK_MISSING}")
    if engine == "auto":
        return "dask" if dask_available() else "local"
    return engine


def _failed(job: Job, exc: BaseException) -> JobResult:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return JobResult(job.name, job.out, False, 1, f"{type(exc).__name__}: {text}")


def run_jobs(
    jobs: Sequence[Job],
    fn: Callable[[Job], JobResult],
    engine: str = "auto",
    workers: int = 2,
    scheduler: str | None = None,
    on_done: Callable[[JobResult, int, int], None] | None = None,
) -> list[JobResult]:
    """Run ``fn(job)`` for every job in parallel; results in job order.

    Parameters
    ----------
    jobs : sequence of Job
    fn : callable
        Module-level function (picklable) run once per job on a worker; it should return a
        failed :class:`JobResult` rather than raise, but an exception is caught too.
    engine : {"auto", "dask", "local"}
    workers : int
        Worker processes of the local cluster or pool (ignored with ``scheduler``).
    scheduler : str, optional
        Address of a running Dask scheduler.
    on_done : callable, optional
        ``on_done(result, n_done, n_total)`` in the calling process as each job finishes.

    Returns
    -------
    list of JobResult
        One per job, in the order of ``jobs``.
    """
    if workers < 1:
        raise InputError(f"--workers: expected at least 1, got {workers}")
    kind = resolve_engine(engine, scheduler)
    if not jobs:
        return []
    if kind == "dask":
        return _run_dask(jobs, fn, workers, scheduler, on_done)
    return _run_local(jobs, fn, workers, on_done)


def _run_local(
    jobs: Sequence[Job],
    fn: Callable[[Job], JobResult],
    workers: int,
    on_done: Callable[[JobResult, int, int], None] | None,
) -> list[JobResult]:
    from concurrent.futures import ProcessPoolExecutor, as_completed

    with ProcessPoolExecutor(max_workers=min(workers, len(jobs))) as pool:
        futs: dict[Future[JobResult], int] = {pool.submit(fn, job): i for i, job in enumerate(jobs)}
        return _collect(jobs, futs, as_completed(futs), on_done)


def _collect(
    jobs: Sequence[Job],
    futs: Mapping[Any, int],
    done: Iterable[Any],
    on_done: Callable[[JobResult, int, int], None] | None,
) -> list[JobResult]:
    """The results of the futures ``futs`` (future -> index in ``jobs``) in job order, taken
    as ``done`` yields the futures; a future that raised (in the task, or a worker that died
    or was lost, or a result that could not be sent back) gives the job a failed result."""
    results: list[JobResult | None] = [None] * len(jobs)
    for n, fut in enumerate(done, start=1):
        i = futs[fut]
        try:
            res = fut.result()
        except Exception as exc:  # the job failed, the run goes on
            res = _failed(jobs[i], exc)
        results[i] = res
        if on_done is not None:
            on_done(res, n, len(jobs))
    return [r for r in results if r is not None]


@contextmanager
def _dask_client(workers: int, scheduler: str | None) -> Iterator[Any]:
    """A ``distributed.Client``: of a local cluster of ``workers`` single-threaded worker
    processes (closed on exit), or of the running scheduler at ``scheduler``."""
    import logging

    import dask
    import distributed

    cluster: Any = None
    try:
        if scheduler is None:
            # the nannies pass the settings in force when they are made on to their workers
            with dask.config.set(LOCAL_CLUSTER_CONFIG):
                cluster = distributed.LocalCluster(
                    n_workers=max(1, workers),
                    threads_per_worker=1,
                    processes=True,
                    dashboard_address=None,
                    silence_logs=logging.ERROR,
                )
                client = distributed.Client(cluster)
        else:
            try:
                client = distributed.Client(scheduler, timeout="10s")
            except OSError as exc:
                raise InputError(
                    f"--scheduler: cannot reach the Dask scheduler at {scheduler}: {exc}"
                ) from None
        with client:
            yield client
    finally:
        if cluster is not None:
            cluster.close()


def _run_dask(
    jobs: Sequence[Job],
    fn: Callable[[Job], JobResult],
    workers: int,
    scheduler: str | None,
    on_done: Callable[[JobResult, int, int], None] | None,
) -> list[JobResult]:
    import distributed

    with _dask_client(workers, scheduler) as client:
        futs = {
            client.submit(fn, job, key=f"robustrtk-job-{i}-{job.name}", pure=False, retries=0): i
            for i, job in enumerate(jobs)
        }
        return _collect(jobs, futs, distributed.as_completed(list(futs)), on_done)


@contextmanager
def task_executor(engine: str, workers: int, scheduler: str | None = None) -> Iterator[cf.Executor]:
    """A ``concurrent.futures`` executor for independent tasks (an experiment's seeds).

    Parameters
    ----------
    engine : {"auto", "dask", "local"}
        As ``robustrtk batch --engine`` (:func:`resolve_engine`).
    workers : int
        Worker processes of the local pool or of the Dask local cluster.
    scheduler : str, optional
        Address of a running Dask scheduler (a real cluster); ``workers`` is then unused.

    Yields
    ------
    concurrent.futures.Executor
        ``ProcessPoolExecutor`` (local), or distributed's executor over a local cluster or
        the scheduler; its ``submit`` returns standard futures, so callers use
        ``concurrent.futures.as_completed`` either way. The cluster closes on exit.

    Raises
    ------
    InputError
        As :func:`resolve_engine`, or the scheduler cannot be reached.
    """
    kind = resolve_engine(engine, scheduler)
    if kind == "local":
        with cf.ProcessPoolExecutor(max_workers=max(1, workers)) as pool:
            yield pool
        return
    with _dask_client(workers, scheduler) as client:
        executor = client.get_executor(pure=False)
        try:
            yield executor
        finally:
            executor.shutdown(wait=True)


def summary_table(results: Sequence[JobResult]) -> str:
    """A text table: one row per job (status, epochs, fixed %, wall s, output or error), then totals."""
    rows = []
    for r in results:
        fixed = r.counts.get("fixed", 0) + r.counts.get("partial", 0)
        rows.append([
            r.name, "ok" if r.ok else "FAILED", str(r.epochs) if r.ok else "-",
            f"{100.0 * fixed / r.epochs:.1f}" if r.ok and r.epochs else "-",
            f"{r.wall_s:.2f}" if r.wall_s == r.wall_s else "-", r.out if r.ok else r.error,
        ])  # fmt: skip
    n_ok = sum(r.ok for r in results)
    total = f"{n_ok} of {len(results)} jobs ok" + (
        f", {len(results) - n_ok} failed" if n_ok < len(results) else ""
    )
    head = ["job", "result", "epochs", "fixed %", "wall s", "output / error"]
    return format_table(rows, head, align="llrrrl") + "\n" + total


__all__ = [
    "DASK_MISSING",
    "ENGINES",
    "JobResult",
    "LOCAL_CLUSTER_CONFIG",
    "dask_available",
    "resolve_engine",
    "run_jobs",
    "summary_table",
    "task_executor",
    "worker_label",
]
