"""Figures of the HTML report and the README figure."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from robustrtk.eval.plots import dd_satellite, figure_png, plot_satellite_counts, plot_sky, plot_status_tracks

ROOT = Path(__file__).resolve().parents[2]


def _is_png(data: bytes) -> bool:
    return data[:8] == b"\x89PNG\r\n\x1a\n" and data[-8:-4] == b"IEND"


def test_sky_and_counts_render() -> None:
    t = np.arange(50.0)
    az = {"G05": np.linspace(0, 1, 50), "E26": np.full(50, np.nan), "J02": np.linspace(3, 4, 50)}
    el = {k: np.full(50, 0.6) for k in az}
    assert _is_png(figure_png(plot_sky(az, el, elev_mask_deg=15.0)))
    assert _is_png(figure_png(plot_satellite_counts(t, {"G": np.full(50, 8), "E": np.full(50, 5)})))


def test_status_tracks_side_by_side() -> None:
    p = np.c_[np.cos(np.arange(30) / 5), np.sin(np.arange(30) / 5)]
    q = np.r_[np.full(10, 2), np.full(20, 1)]
    fig = plot_status_tracks({"a": (p, q), "b": (p + 0.1, q)})
    assert len(fig.axes) == 2 and _is_png(figure_png(fig))


def test_dd_satellite() -> None:
    assert dd_satellite("G05:L1-G15:L1") == "G05"
    assert dd_satellite("PL4-PL6") == "PL4"
    assert dd_satellite("G05-G12/1C") == "G05"


def test_readme_figure_is_committed_and_small() -> None:
    img = ROOT / "docs" / "img" / "kamakura_rtk.png"
    assert "docs/img/kamakura_rtk.png" in (ROOT / "README.md").read_text(encoding="utf-8")
    data = img.read_bytes()
    assert _is_png(data) and 20_000 < len(data) < 150_000
