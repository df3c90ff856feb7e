"""Observation summary: brute-force counts on a random synthetic batch, real files."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from robustrtk.core import empty_batch
from robustrtk.io.info import format_summary, summarize
from robustrtk.io.rinex_obs import read_rinex_obs


def _random_batch(rng: np.random.Generator):  # type: ignore[no-untyped-def]
    t = 1000.0 + np.arange(40.0)
    t[25:] += 5.0  # one gap
    tx = ("G01", "G02", "R05", "E11", "E12")
    b = empty_batch(t, tx, tuple(x[0] for x in tx), ("1C", "2W", "5Q"))
    code = rng.random(b.code_m.shape) < 0.6
    phase = rng.random(b.code_m.shape) < 0.5
    code[:, 4] = False  # E12 never tracked
    phase[:, 4] = False
    code[:, :, 2] &= False  # no 5Q code anywhere
    phase[:, 0:2, 2] = False  # GPS has no 5Q at all
    b.code_m[code] = 2e7
    b.phase_cyc[phase] = 1e8
    return b, code, phase


def test_summary_matches_brute_force() -> None:
    b, code, phase = _random_batch(np.random.default_rng(7))
    s = summarize(b)
    assert s["epochs"] == 40
    assert s["t_start_s"] == 1000.0 and s["t_end_s"] == 1044.0 and s["duration_s"] == 44.0
    assert s["interval_s"] == 1.0 and s["n_gaps"] == 1
    per_epoch = []
    for i in range(40):
        per_epoch.append(sum(any(code[i, n, k] or phase[i, n, k] for k in range(3)) for n in range(5)))
    assert s["sats_per_epoch"] == {
        "min": min(per_epoch),
        "median": float(np.median(per_epoch)),
        "max": max(per_epoch),
    }
    assert s["systems"] == {"G": 2, "R": 1, "E": 1}  # E12 never seen
    assert s["signals"]["G"] == ["1C", "2W"]
    assert s["signals"]["E"] == ["1C", "2W", "5Q"]  # phase-only 5Q counts
    tracked = code | phase
    assert math.isclose(s["phase_fraction"], phase.sum() / tracked.sum())
    g = slice(0, 2)
    assert math.isclose(s["phase_fraction_by_system"]["G"], phase[:, g].sum() / tracked[:, g].sum())
    text = format_summary(s)
    assert "epochs      40" in text and "1 gap(s)" in text
    assert "GPS" in text and "GLONASS" in text and "Galileo" in text


def test_empty_batch_summary() -> None:
    b = empty_batch(np.zeros(0), ("G01",), ("G",), ("1C",))
    s = summarize(b)
    assert s["epochs"] == 0 and s["systems"] == {} and math.isnan(s["phase_fraction"])
    assert "epochs      0" in format_summary(s)


def test_summary_of_geonet_against_epoch_lines(shared_data: Path) -> None:
    path = shared_data / "geonet_0759_3040_static_3km/07590920.05o"
    s = summarize(read_rinex_obs(path))
    # satellite counts announced by the epoch lines (flag 0), read by slicing
    counts = [
        int(ln[29:32]) for ln in path.read_text().splitlines() if ln.startswith(" 05  4  2") and ln[28] == "0"
    ]
    assert len(counts) == s["epochs"] == 120
    assert (s["sats_per_epoch"]["min"], s["sats_per_epoch"]["max"]) == (min(counts), max(counts))
    assert s["interval_s"] == 30.0 and s["n_gaps"] == 0
    assert s["signals"] == {"G": ["1C", "2W"]}
    assert s["end"].startswith("2005-04-02 00:59:30.005")
    assert "TRIMBLE 5700" in format_summary(s)


def test_summary_of_mosaic(shared_data: Path) -> None:
    s = summarize(read_rinex_obs(shared_data / "mosaicx5_static_1m/rover.obs"))
    assert s["epochs"] == 301 and s["duration_s"] == 300.0
    assert set(s["systems"]) == {"G", "R", "E", "C", "J"}
    assert s["signals"]["C"] == ["2I", "6I", "7I"]
    assert 0.9 < s["phase_fraction"] <= 1.0
