"""One cell of the reproduction's tables: a statistic over seeds as text."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any


def format_cell(agg: Mapping[str, Any], fmt: str, runs: int) -> str:
    """One table cell: the value (one run) or ``median [p5, p95]`` (several runs)."""

    def one(v: float) -> str:
        if v is None or not math.isfinite(v):
            return "–"
        txt = format(int(round(v)), "d") if fmt == "d" else format(v, fmt)
        # no "-0.000": a value that rounds to zero is shown without a sign
        return txt[1:] if txt.startswith("-") and float(txt) == 0 else txt

    if runs == 1:
        return one(agg["median"])
    return f"{one(agg['median'])} [{one(agg['p5'])}, {one(agg['p95'])}]"


__all__ = ["format_cell"]
