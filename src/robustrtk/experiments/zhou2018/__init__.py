"""Zhou et al. (2018), *Improved GNSS cooperation positioning algorithm for indoor
localization*, reproduced on simulated data (issue #12, item 7).

Two static nodes — node 1 on a roof (open sky), node 2 on a windowsill (fewer than four GPS
and four to five BeiDou satellites) 6.5 m away — are simulated from real broadcast GPS and
BeiDou orbits (:mod:`robustrtk.sim.coop`), 50 epochs per run, a clean and a degraded
session per seed (node 1 with +20 m on two satellites for 15 epochs). Node 2 is solved by LS,
EKF, augmented UKF and particle filter (:mod:`robustrtk.estimation.coop`), each alone
(``off``), ``traditional`` and ``improved`` (eq. 24 with the covariance reset of eqs. 29–30).
Statistics are the paper's Table 2 (RMS per ECEF axis), pooled over runs, with per-run
medians and 2.5/97.5 percentiles.

:mod:`.solve` (the two-node loop), :mod:`.runner` (seeds in parallel, ``runs.npz``,
``results.json``), :mod:`.metrics` (statistics, claims), :mod:`.report` (figures,
``report.md``).
"""

from robustrtk.experiments.zhou2018.metrics import PAPER_TABLE2, Claim, all_stats, axis_rms, build_claims
from robustrtk.experiments.zhou2018.runner import load_errors, run_task, run_zhou2018
from robustrtk.experiments.zhou2018.solve import PairSolution, SimNode, solve_pair

__all__ = [
    "PAPER_TABLE2",
    "Claim",
    "PairSolution",
    "SimNode",
    "all_stats",
    "axis_rms",
    "build_claims",
    "load_errors",
    "run_task",
    "run_zhou2018",
    "solve_pair",
]
