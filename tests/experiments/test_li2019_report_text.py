"""The li2019 report's sentence on slow re-fixes is computed from the prior-σ sensitivity:
it names exactly the σ whose SUKF median re-fix exceeds one epoch, with the fix rate there."""

from __future__ import annotations

from typing import Any

from robustrtk.experiments.li2019.differences import slow_refix_sentence
from robustrtk.experiments.li2019.schemes import PRIOR_SIGMAS_SENS_M, prior_label


def _agg(v: float | None) -> dict[str, Any]:
    return {"median": v, "p5": v, "p95": v, "values": [v]}


def _stats(refix: dict[float, float | None], before: float = 0.5) -> dict[str, dict[str, Any]]:
    out = {}
    for sig, r in refix.items():
        p = f"rtk015.{prior_label(sig)}.SUKF"
        out[f"{p}.refix_epochs"] = _agg(r)
        out[f"{p}.fix_rate_before"] = _agg(before)
    return out


def test_names_only_the_slow_sigmas_with_their_fix_rate() -> None:
    slow = max(PRIOR_SIGMAS_SENS_M)
    refix = {sig: (21.0 if sig == slow else 1.0) for sig in PRIOR_SIGMAS_SENS_M}
    text = slow_refix_sentence(_stats(refix, before=0.59), runs=1)
    assert f"only at σ = {slow:g} m" in text and "0.59" in text
    for sig in PRIOR_SIGMAS_SENS_M:
        if sig != slow:
            assert f"σ = {sig:g} m" not in text


def test_no_slow_sigma_says_so_and_missing_or_nan_cells_count_as_not_slow() -> None:
    refix: dict[float, float | None] = {sig: 1.0 for sig in PRIOR_SIGMAS_SENS_M}
    refix[min(PRIOR_SIGMAS_SENS_M)] = float("nan")
    refix[max(PRIOR_SIGMAS_SENS_M)] = None
    text = slow_refix_sentence(_stats(refix), runs=1)
    assert text.startswith("no prior σ of the sensitivity table")
    # a quick run without the sensitivity has no such statistics at all
    assert slow_refix_sentence({}, runs=1).startswith("no prior σ")
