"""Plain-text tables for the command line."""

from __future__ import annotations

import math
from collections.abc import Sequence
from numbers import Integral, Real


def _cell(v: object, floatfmt: str) -> str:
    if isinstance(v, bool) or v is None:
        return "-" if v is None else str(v)
    if isinstance(v, Integral):
        return str(int(v))
    if isinstance(v, Real):
        f = float(v)
        return "-" if math.isnan(f) else format(f, floatfmt)
    return str(v)


def _numeric(v: object) -> bool:
    return isinstance(v, Real) and not isinstance(v, bool)


def format_table(rows: Sequence[Sequence[object]], headers: Sequence[str], *, floatfmt: str = ".3f") -> str:
    """Aligned plain-text table.

    Numbers are right-aligned and formatted with ``floatfmt`` (integers as integers, NaN
    and None as ``-``); other cells are left-aligned. Columns are separated by two spaces
    and the header is underlined with dashes.

    Parameters
    ----------
    rows : sequence of sequences, each of ``len(headers)`` cells
    headers : sequence of str
    floatfmt : str
        Format spec for floats.

    Returns
    -------
    str
        Lines joined by ``\\n`` (no trailing newline).
    """
    ncol = len(headers)
    for i, r in enumerate(rows):
        if len(r) != ncol:
            raise ValueError(f"row {i} has {len(r)} cells, expected {ncol}")
    text = [[_cell(v, floatfmt) for v in r] for r in rows]
    right = [all(_numeric(r[j]) or r[j] is None for r in rows) and len(rows) > 0 for j in range(ncol)]
    width = [max([len(h)] + [len(t[j]) for t in text]) for j, h in enumerate(headers)]

    def line(cells: Sequence[str]) -> str:
        parts = [c.rjust(w) if rj else c.ljust(w) for c, w, rj in zip(cells, width, right, strict=True)]
        return "  ".join(parts).rstrip()

    out = [line(list(headers)), "  ".join("-" * w for w in width)]
    out += [line(t) for t in text]
    return "\n".join(out)
