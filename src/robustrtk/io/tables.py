"""Tables as text: aligned plain text for the terminal, Markdown for reports, HTML for pages.

One cell rule for all three (:func:`cell_text`): integers as integers, floats with a format
spec, ``None`` and NaN as ``-``, anything else as ``str``. Imports nothing beyond the standard
library, so every layer may use it.
"""

from __future__ import annotations

import html
import math
from collections.abc import Sequence
from numbers import Integral, Real

__all__ = ["cell_text", "format_table", "html_table", "markdown_table"]


def cell_text(v: object, floatfmt: str = ".3f") -> str:
    """Text of one cell.

    Parameters
    ----------
    v : object
        ``None``, a bool, an integer or float (Python or numpy), or anything with ``str``.
    floatfmt : str
        Format spec for floats (``".3f"``).

    Returns
    -------
    str
        ``-`` for ``None`` and NaN, ``str(v)`` for bools and non-numbers.
    """
    if v is None:
        return "-"
    if isinstance(v, bool):
        return str(v)
    if isinstance(v, Integral):
        return str(int(v))
    if isinstance(v, Real):
        f = float(v)
        return "-" if math.isnan(f) else format(f, floatfmt)
    return str(v)


def _numeric(v: object) -> bool:
    return isinstance(v, Real) and not isinstance(v, bool)


def _check(rows: Sequence[Sequence[object]], ncol: int) -> None:
    for i, r in enumerate(rows):
        if len(r) != ncol:
            raise ValueError(f"row {i} has {len(r)} cells, expected {ncol}")


def format_table(
    rows: Sequence[Sequence[object]],
    headers: Sequence[str],
    *,
    floatfmt: str = ".3f",
    align: str | None = None,
) -> str:
    """Aligned plain-text table.

    Columns are separated by two spaces, the header is underlined with dashes (one run per
    column) and trailing blanks are stripped from every line.

    Parameters
    ----------
    rows : sequence of sequences, each of ``len(headers)`` cells
    headers : sequence of str
    floatfmt : str
        Format spec for floats (:func:`cell_text`).
    align : str, optional
        One letter per column, ``l`` (left) or ``r`` (right). By default a column is
        right-aligned when every cell in it is a number or ``None`` (and there is a row),
        left-aligned otherwise.

    Returns
    -------
    str
        Lines joined by ``\\n`` (no trailing newline).

    Raises
    ------
    ValueError
        A row's length differs from the header's, or ``align`` has the wrong length or letters.
    """
    ncol = len(headers)
    _check(rows, ncol)
    if align is None:
        right = [len(rows) > 0 and all(_numeric(r[j]) or r[j] is None for r in rows) for j in range(ncol)]
    else:
        if len(align) != ncol or set(align) - {"l", "r"}:
            raise ValueError(f"align {align!r}: expected {ncol} letters l or r")
        right = [a == "r" for a in align]
    text = [[cell_text(v, floatfmt) for v in r] for r in rows]
    width = [max([len(h)] + [len(t[j]) for t in text]) for j, h in enumerate(headers)]

    def line(cells: Sequence[str]) -> str:
        parts = [c.rjust(w) if rj else c.ljust(w) for c, w, rj in zip(cells, width, right, strict=True)]
        return "  ".join(parts).rstrip()

    out = [line(list(headers)), "  ".join("-" * w for w in width)]
    out += [line(t) for t in text]
    return "\n".join(out)


def markdown_table(rows: Sequence[Sequence[object]], headers: Sequence[str], *, floatfmt: str = ".3f") -> str:
    """GitHub-flavoured Markdown table (``|`` in a cell escaped as ``\\|``).

    Parameters
    ----------
    rows : sequence of sequences, each of ``len(headers)`` cells (:func:`cell_text`)
    headers : sequence of str
    floatfmt : str
        Format spec for floats.

    Returns
    -------
    str
        Header, ``|---|`` rule and one line per row, joined by ``\\n`` (no trailing newline).
    """
    _check(rows, len(headers))

    def line(cells: Sequence[str]) -> str:
        return "| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |"

    out = [line(list(headers)), "|" + "|".join("---" for _ in headers) + "|"]
    out += [line([cell_text(v, floatfmt) for v in r]) for r in rows]
    return "\n".join(out)


def html_table(rows: Sequence[Sequence[object]], headers: Sequence[str], *, digits: int = 3) -> str:
    """HTML ``<table>`` in one line: numbers in ``<td class="n">`` (right-aligned by the page's
    style) with ``digits`` decimals, other cells escaped.

    Parameters
    ----------
    rows : sequence of sequences of cells (:func:`cell_text`)
    headers : sequence of str
    digits : int
        Decimals of float cells.

    Returns
    -------
    str
        ``<table><thead>…</thead><tbody>…</tbody></table>``.
    """
    head = "".join(f"<th>{html.escape(h)}</th>" for h in headers)
    body = "".join(
        "<tr>"
        + "".join(
            f'<td class="n">{cell_text(c, f".{digits}f")}</td>'
            if _numeric(c)
            else f"<td>{html.escape(cell_text(c))}</td>"
            for c in r
        )
        + "</tr>"
        for r in rows
    )
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"
