"""Processing campaigns: many rover/base jobs in parallel (Dask or a local process pool).

:mod:`~robustrtk.campaign.jobs` reads job lists (TOML, CSV, folders of them);
:mod:`~robustrtk.campaign.runner` runs a task per job on Dask or a process pool and
collects one :class:`~robustrtk.campaign.runner.JobResult` per job. ``robustrtk batch``
(:mod:`robustrtk.cli.batch`) puts the two together with the ``solve`` command.
"""

from robustrtk.campaign.jobs import JOB_KEYS, JOB_MODES, Job, read_jobs
from robustrtk.campaign.runner import (
    ENGINES,
    JobResult,
    dask_available,
    resolve_engine,
    run_jobs,
    summary_table,
)

__all__ = [
    "ENGINES",
    "JOB_KEYS",
    "JOB_MODES",
    "Job",
    "JobResult",
    "dask_available",
    "read_jobs",
    "resolve_engine",
    "run_jobs",
    "summary_table",
]
