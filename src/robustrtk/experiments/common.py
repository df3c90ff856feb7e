"""Helpers shared by the experiments' runners."""

from __future__ import annotations

import math
from typing import Any


def jsonable(x: Any) -> Any:
    """``x`` with every non-finite float (at any depth of dicts, lists and tuples) as None,
    so that ``json.dumps(..., allow_nan=False)`` accepts it; tuples become lists."""
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, dict):
        return {k: jsonable(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [jsonable(v) for v in x]
    return x


__all__ = ["jsonable"]
