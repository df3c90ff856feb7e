"""Integer ambiguity resolution: LAMBDA, validation, partial fixing, conditional update."""

from robustrtk.ambiguity.lambda_ import (
    bootstrap_success_rate,
    decorrelate,
    lambda_search,
    ltdl,
    search,
)
from robustrtk.ambiguity.par import (
    FixResult,
    conditional_update,
    fix_state,
    resolve_full,
    resolve_par_ranked,
    resolve_par_success_rate,
)
from robustrtk.ambiguity.validation import RatioTest, ffrt_threshold, ratio_of, ratio_test

__all__ = [
    "FixResult",
    "RatioTest",
    "bootstrap_success_rate",
    "conditional_update",
    "decorrelate",
    "ffrt_threshold",
    "fix_state",
    "lambda_search",
    "ltdl",
    "ratio_of",
    "ratio_test",
    "resolve_full",
    "resolve_par_ranked",
    "resolve_par_success_rate",
    "search",
]
