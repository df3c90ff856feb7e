r"""Li et al. (2019), *Reliable indoor pseudolite positioning based on a robust estimation
and partial ambiguity resolution method*, reproduced on simulated data.

Every experiment of the paper's section 3 is simulated with the presets ``li2019_*`` and
solved with the schemes of the paper:

* **DPL static** (``li2019_dpl_static``, 11,000 epochs): SUKF (no robust weighting) versus
  RUKF (Δv̄ + IGG-III, :math:`k_0 = 2`, :math:`k_1 = 8`); Table 1 (epochs per situation
  from RUKF's Δv̄), Fig. 4 (residuals and Δv̄), Fig. 5 (error series), Fig. 6 (mean
  :math:`|e|` per axis in situations #2 and #3, situations from RUKF).
* **RTK static, 5 cm** (``li2019_rtk_static``): RUKF Δv̄ of PL4-PL1 with and without the
  gross errors (same seed, scheduled errors removed), Fig. 7; SUKF vs RUKF errors, Fig. 8.
* **RTK static, 0.15 m at epoch 100** (``li2019_rtk_static_015``): SUKF / RUKF (full-set
  LAMBDA) / RUKF+PAR. The error is added on epoch 100 only: the paper adds it "on the 100th
  epoch" and describes a jump there followed by re-fixing, which a persisting 0.15 m
  (0.79 cycle, non-integer) step would rule out. *Jump* :math:`= d_{100} - d_{99}` with
  :math:`d_k` the 3D error at epoch :math:`k`; *epochs to re-fix* :math:`= k^\star - 100`
  with :math:`k^\star` the first epoch :math:`\ge 100` whose status is fixed or partial (0
  when epoch 100 itself is fixed, NaN when never). Primary (the claims): the paper's own
  scheme of Sec. 2.1 (``ar_scheme = "prior"``, ``docs/algorithms.md`` §20) — known-point
  start, each epoch's float solution from the previous coordinate with σ =
  :data:`~.schemes.PRIOR_SIGMA_M`, carried float ambiguities, AR every epoch, a fixed
  solution accepted only within :data:`~.schemes.FIX_RESIDUAL_K` σ; a sensitivity table
  over the prior σ; variants: the paper's RUKF recipe taken literally
  (:func:`~.schemes.literal_rukf`, Δv̄ from the posterior residuals), the solver's default
  slip detectors, fix-and-hold and continuous AR in the filter scheme.
* Every RTK scheme detects slips from loss-of-lock flags only (:data:`~.schemes.RTK_SLIP`):
  the paper's gross errors are for the estimator, and a polynomial slip detector would
  turn them into ambiguity resets that a non-robust filter never sees.
* **RTK kinematic rail**: 0.1 m errors (``li2019_rtk_rail``), fix-and-hold as in the
  paper, X error SUKF vs RUKF (Fig. 10); 0.15 m at epoch 50 only (``li2019_rtk_rail_015``),
  SUKF vs RUKF+PAR horizontal track against the straight rail (Fig. 11). Cross-track
  deviation :math:`|(p - a) \times u|` in the horizontal plane, :math:`a` the rail start
  and :math:`u` its unit direction. Primary: the paper's scheme as for Fig. 9 (each epoch
  starts from the previous epoch's coordinates, AR every epoch); variants: the same scheme
  with new ambiguities at every epoch (Sec. 3.3.2's "single-epoch PL-AR" read literally),
  single-epoch AR in the filter scheme and fix-and-hold.
* **EKF vs UKF** with the known initial point displaced by 0.1, 0.5 and 1 m along
  :math:`(1, 1, 1)/\sqrt 3` (first 1000 DPL static epochs and fault-free RTK static, no
  robust weighting):
  3D RMS and convergence epoch (first epoch after which the 3D error stays below 0.5 m for
  DPL, 0.05 m for RTK).
* **Filter memory (sensitivity, not a paper setting)**: the DPL static data solved again
  with the solver's random-walk position model (default noise) instead of the static one,
  to show how much the situation-#2 gain depends on how many epochs the filter averages
  (first seed only).

With ``runs = N`` every experiment is repeated for seeds ``seed .. seed + N - 1`` in
parallel processes; each statistic is reported as the median and the 5/95 percentiles
over runs. Figures show the first seed. The scenario is checked
against the paper's stated setting in the report's calibration table.

The reproduction is split by responsibility: :mod:`.schemes` (configurations and
experiment sizes), :mod:`.runner` (simulate, solve, :func:`run_li2019`), :mod:`.metrics`
(per-run statistics and aggregation), :mod:`.claims` (the claims table), :mod:`.figures`
and :mod:`.report`.
"""

from robustrtk.experiments.li2019.cells import format_cell
from robustrtk.experiments.li2019.claims import PAPER_DPL_EPOCHS, PAPER_TABLE1, Claim, build_claims
from robustrtk.experiments.li2019.figures import make_figures
from robustrtk.experiments.li2019.metrics import (
    CONV_DPL_M,
    CONV_RTK_M,
    FIXED,
    aggregate,
    convergence_epoch,
    dd_series,
    diag_table,
    epochs_to_refix,
    error_3d_m,
    fault_epochs,
    gauss_dv_exceed_prob,
    impulse_share_bound,
    jump_m,
    pos_error_m,
    rail_deviation_m,
    seed_stats,
)
from robustrtk.experiments.li2019.report import MODE_LABEL, Report, write_report
from robustrtk.experiments.li2019.runner import run_li2019, run_task
from robustrtk.experiments.li2019.schemes import (
    INIT_OFFSETS_M,
    K0,
    K1,
    Q_SIGMAS_M,
    Q_SIGMAS_QUICK_M,
    RAIL_FAULT_EPOCH,
    STATIC_FAULT_EPOCH,
    Raw,
    dpl_config,
    experiment_epochs,
    q_config,
    rtk_config,
)

__all__ = [
    "CONV_DPL_M",
    "CONV_RTK_M",
    "FIXED",
    "INIT_OFFSETS_M",
    "K0",
    "K1",
    "MODE_LABEL",
    "PAPER_DPL_EPOCHS",
    "PAPER_TABLE1",
    "Q_SIGMAS_M",
    "Q_SIGMAS_QUICK_M",
    "RAIL_FAULT_EPOCH",
    "STATIC_FAULT_EPOCH",
    "Claim",
    "Raw",
    "Report",
    "aggregate",
    "build_claims",
    "convergence_epoch",
    "dd_series",
    "diag_table",
    "dpl_config",
    "epochs_to_refix",
    "error_3d_m",
    "experiment_epochs",
    "fault_epochs",
    "format_cell",
    "gauss_dv_exceed_prob",
    "impulse_share_bound",
    "jump_m",
    "make_figures",
    "pos_error_m",
    "q_config",
    "rail_deviation_m",
    "rtk_config",
    "run_li2019",
    "run_task",
    "seed_stats",
    "write_report",
]
