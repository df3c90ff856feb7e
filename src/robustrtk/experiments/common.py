"""Helpers shared by the experiments' runners."""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

from robustrtk.errors import InputError


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


def output_dir(path: str | os.PathLike[str]) -> Path:
    """The directory ``path``, created with its parents when missing.

    Raises
    ------
    InputError
        It cannot be created (the message names it).
    """
    out = Path(path)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create output directory: {exc.strerror}", path=str(out)) from exc
    return out


__all__ = ["jsonable", "output_dir"]
