"""One set of horizontal/vertical error statistics; GPST text formatting."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from robustrtk.eval.compare import error_group_stats
from robustrtk.eval.metrics import error_stats, hv_error_stats
from robustrtk.geometry.frames import geodetic2ecef
from robustrtk.timeutil import gpst_from_calendar, gpst_text


def test_hv_stats_hand_values() -> None:
    s = hv_error_stats([[3.0, 4.0, -1.0], [0.0, 0.0, 2.0], [np.nan, 0.0, 0.0]])
    assert s["H_rms_m"] == pytest.approx(math.sqrt(12.5))
    assert s["V_rms_m"] == pytest.approx(math.sqrt(2.5))
    assert s["H_max_m"] == 5.0 and s["V_max_m"] == 2.0
    assert s["H_95_m"] == pytest.approx(0.0 + 0.95 * 5.0)
    assert all(math.isnan(v) for v in hv_error_stats(np.zeros((0, 3))).values())


@given(st.integers(min_value=1, max_value=40), st.integers(min_value=0, max_value=2**31))
def test_metrics_and_compare_agree(n: int, seed: int) -> None:
    enu = np.random.default_rng(seed).normal(size=(n, 3))
    g = error_group_stats(enu)
    h = hv_error_stats(enu)
    assert g is not None
    for k in ("H_rms_m", "H_95_m", "V_rms_m", "V_95_m", "H_max_m", "V_max_m"):
        assert g[k] == h[k]
    ref = geodetic2ecef(0.0, 0.0, 0.0)  # ENU at (0, 0): e = y, n = z, u = x
    s = error_stats(enu[:, [2, 0, 1]], ref)
    for k in ("H_rms_m", "H_95_m", "V_rms_m", "V_95_m"):
        assert s[k] == pytest.approx(h[k], rel=1e-12, abs=1e-15)


def test_gpst_text_forms() -> None:
    t = gpst_from_calendar(2024, 6, 24, 8, 20, 0.0)
    assert gpst_text(t) == "2024/06/24 08:20:00"
    assert gpst_text(t + 0.25) == "2024/06/24 08:20:00.250"
    assert gpst_text(t, trim_zero_fraction=False) == "2024/06/24 08:20:00.000"
    assert gpst_text(t + 59.9996) == "2024/06/24 08:21:00"
    assert gpst_text(t + 0.005, 6, date_sep="-", trim_zero_fraction=False) == "2024-06-24 08:20:00.005000"
    assert gpst_text(t + 1.4, 0) == "2024/06/24 08:20:01"


@given(st.integers(min_value=0, max_value=2_000_000_000_000))
def test_gpst_text_round_trip(ms: int) -> None:
    t = ms / 1000.0
    text = gpst_text(t, trim_zero_fraction=False)
    date, clock = text.split()
    y, mo, d = (int(v) for v in date.split("/"))
    hh, mi, ss = clock.split(":")
    assert gpst_from_calendar(y, mo, d, int(hh), int(mi), float(ss)) == pytest.approx(t, abs=1e-6)
