"""Figures carry labels and legends; tables align."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from robustrtk.core import InputError
from robustrtk.eval.plots import (
    plot_dd_diagnostics,
    plot_error_series,
    plot_situation_bars,
    plot_trajectory,
    save_figure,
)
from robustrtk.eval.report import format_table
from robustrtk.io.solution import DiagTable


def _check_axes(fig: object, n_axes: int) -> None:
    axes = fig.get_axes()  # type: ignore[attr-defined]
    assert len(axes) == n_axes
    for ax in axes:
        assert ax.get_ylabel()
        if ax.get_subplotspec().is_last_row():  # stacked panels share the bottom x label
            assert ax.get_xlabel()
        assert ax.get_legend() is not None
        assert len(ax.get_legend().get_texts()) >= 1
        assert ax.has_data()


def _diag(n_dd: int, T: int = 50) -> DiagTable:
    rng = np.random.default_rng(0)
    t = np.repeat(np.arange(T, dtype=float), n_dd)
    dd = np.tile(np.array([f"PL{i}-PL6" for i in range(n_dd)]), T)
    dv = rng.normal(0, 2, t.size)
    return DiagTable(t_s=t, dd=dd, innovation=dv, residual=dv * 0.1, std_residual=dv,
                     dv=dv, factor=np.ones_like(t), situation=np.ones(t.size, np.int64))  # fmt: skip


def test_error_series_figure(tmp_path: Path) -> None:
    t = np.arange(100.0)
    e = np.random.default_rng(1).normal(size=(100, 3))
    fig = plot_error_series({"SUKF": (t, e), "RUKF": (t, e / 2)})
    _check_axes(fig, 3)
    assert [tx.get_text() for tx in fig.get_axes()[0].get_legend().get_texts()] == ["SUKF", "RUKF"]
    assert "(m)" in fig.get_axes()[0].get_ylabel()
    assert fig._suptitle is not None and fig._suptitle.get_text()
    out = save_figure(fig, tmp_path / "e.png")
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["e.png"]
    with pytest.raises(InputError):
        save_figure(fig, tmp_path / "missing" / "e.png")


def test_dd_diagnostics_figure_has_k_lines() -> None:
    fig = plot_dd_diagnostics(_diag(4), k0=2.0, k1=8.0)
    _check_axes(fig, 8)
    dv_ax = fig.get_axes()[1]
    levels = sorted({round(float(line.get_ydata()[0]), 6) for line in dv_ax.get_lines()[1:]})
    assert levels == [-8.0, -2.0, 2.0, 8.0]
    fig_many = plot_dd_diagnostics(_diag(9))
    _check_axes(fig_many, 2)


def test_situation_bars_and_trajectory() -> None:
    mean_abs = {"SUKF": {2: np.array([0.3, 0.2, 0.5]), 3: np.array([1.0, 2.0, 3.0])},
                "RUKF": {2: np.array([0.1, 0.1, 0.2]), 3: np.array([0.2, 0.3, 0.4])}}  # fmt: skip
    fig = plot_situation_bars(mean_abs)
    _check_axes(fig, 2)
    heights = [p.get_height() for p in fig.get_axes()[1].patches]
    np.testing.assert_allclose(heights, [1.0, 2.0, 3.0, 0.2, 0.3, 0.4])
    assert fig.get_axes()[1].get_title() == "Situation #3"
    fig2 = plot_trajectory({"truth": np.c_[np.arange(5.0), np.zeros(5)],
                            "RUKF": np.c_[np.arange(5.0), np.ones(5) * 0.1, np.zeros(5)]})  # fmt: skip
    _check_axes(fig2, 1)


def test_format_table() -> None:
    s = format_table(
        [["PL1-PL6", 9887, 949, 0.12345], ["All DD PLs", 3693, 6794, float("nan")]],
        ["DD", "#1", "#2", "err (m)"],
    )
    lines = s.split("\n")
    assert lines[0] == "DD            #1    #2  err (m)"
    assert lines[1] == "----------  ----  ----  -------"
    assert lines[2] == "PL1-PL6     9887   949    0.123"
    assert lines[3] == "All DD PLs  3693  6794        -"
    with pytest.raises(ValueError):
        format_table([[1, 2]], ["a"])
