"""Evaluation: metrics (errors, fix rate, time to first fix, extra error), the paper's
situation statistics (Table 1, Fig. 6), figures and plain-text reports."""

from robustrtk.eval.metrics import (
    enu_errors,
    error_stats,
    extra_error,
    fix_rate,
    hv_error_stats,
    mean_extra_error,
    position_errors,
    removed_fraction,
    time_to_first_fix,
)
from robustrtk.eval.report import format_table
from robustrtk.eval.situations import (
    classify_dv,
    epoch_situations,
    situation_counts,
    situation_mean_abs_errors,
)

__all__ = [
    "classify_dv",
    "enu_errors",
    "epoch_situations",
    "error_stats",
    "hv_error_stats",
    "extra_error",
    "fix_rate",
    "format_table",
    "mean_extra_error",
    "position_errors",
    "removed_fraction",
    "situation_counts",
    "situation_mean_abs_errors",
    "time_to_first_fix",
]
