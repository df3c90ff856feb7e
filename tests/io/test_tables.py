"""The one table formatter: plain text, Markdown and HTML from the same cells."""

from __future__ import annotations

import math

import numpy as np
import pytest

from robustrtk.io.tables import cell_text, format_table, html_table, markdown_table


def test_cells_numbers_missing_and_text() -> None:
    assert cell_text(np.int64(7)) == "7" and cell_text(3) == "3"
    assert cell_text(np.float32(0.5), ".2f") == "0.50"
    assert cell_text(None) == "-" and cell_text(math.nan) == "-"
    assert cell_text(True) == "True" and cell_text("a|b") == "a|b"


def test_text_alignment_explicit_and_checked() -> None:
    rows = [["a", "12", "-"], ["long name", "3", "4.5"]]
    s = format_table(rows, ["solution", "n", "x"], align="lrr").split("\n")
    assert s == [
        "solution    n    x",
        "---------  --  ---",
        "a          12    -",
        "long name   3  4.5",
    ]
    # string cells are left-aligned unless told otherwise
    assert format_table(rows, ["solution", "n", "x"]).split("\n")[3] == "long name  3   4.5"
    with pytest.raises(ValueError, match="align"):
        format_table(rows, ["solution", "n", "x"], align="lr")
    with pytest.raises(ValueError, match="align"):
        format_table(rows, ["solution", "n", "x"], align="lrc")


def test_markdown_escapes_pipes_and_formats_numbers() -> None:
    s = markdown_table([["|X| (m)", 0.12345, None]], ["a", "b|c", "d"], floatfmt=".2f")
    assert s.split("\n") == ["| a | b\\|c | d |", "|---|---|---|", "| \\|X\\| (m) | 0.12 | - |"]
    with pytest.raises(ValueError):
        markdown_table([[1]], ["a", "b"])


def test_html_numbers_right_text_escaped() -> None:
    s = html_table([[np.int32(3), 1.23456, "<b>", None, math.inf]], ["n", "x", "t", "m", "i"], digits=2)
    assert s.startswith("<table><thead><tr><th>n</th><th>x</th>")
    assert '<td class="n">3</td><td class="n">1.23</td><td>&lt;b&gt;</td><td>-</td>' in s
    assert s.endswith('<td class="n">inf</td></tr></tbody></table>')
