"""Metrics against hand-computed values and RTKLIB's own evaluation of the shared runs."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from robustrtk.core import InputError
from robustrtk.eval.metrics import (
    enu_errors,
    error_stats,
    extra_error,
    fix_rate,
    mean_extra_error,
    position_errors,
    removed_fraction,
    time_to_first_fix,
)
from robustrtk.geometry.frames import geodetic2ecef
from robustrtk.io.solution import SolutionTable, read_pos


def table(t: list[float], pos: list[list[float]]) -> SolutionTable:
    T = len(t)
    return SolutionTable(
        t_s=np.array(t, float),
        pos_m=np.array(pos, float),
        std_m=np.zeros((T, 3)),
        status=np.array(["fixed"] * T),
        n_used=np.zeros(T, np.int64),
        ratio=np.zeros(T),
        n_fixed=np.zeros(T, np.int64),
        n_amb=np.zeros(T, np.int64),
    )


def test_position_errors_static_and_trajectory() -> None:
    sol = table([0.0, 1.0, 2.0, 3.0], [[1, 1, 1], [2, 2, 2], [3, 3, 3], [4, 4, 4]])
    np.testing.assert_array_equal(position_errors(sol, None, [1.0, 1.0, 1.0])[:, 0], [0, 1, 2, 3])
    truth_t = [2.0004, 0.999, 10.0]  # unsorted; epoch 0 and 3 have no truth within 5 ms
    truth = [[3, 3, 2.5], [2, 1, 2], [0, 0, 0]]
    e = position_errors(sol, truth_t, truth, tol_s=0.005)
    assert np.isnan(e[0]).all() and np.isnan(e[3]).all()
    np.testing.assert_array_equal(e[1], [0, 1, 0])
    np.testing.assert_array_equal(e[2], [0, 0, 0.5])
    with pytest.raises(InputError):
        position_errors(sol, None, truth)


def test_error_stats_hand_values() -> None:
    err = np.array([[3.0, 4.0, 0.0], [0.0, 0.0, 0.0], [-3.0, 0.0, 4.0], [np.nan, 0, 0]])
    s = error_stats(err)
    assert s["n"] == 3
    assert s["mean_abs_x_m"] == pytest.approx(2.0)
    assert s["mean_abs_y_m"] == pytest.approx(4.0 / 3.0)
    assert s["mean_abs_z_m"] == pytest.approx(4.0 / 3.0)
    assert s["rms_3d_m"] == pytest.approx(math.sqrt(50.0 / 3.0))
    assert s["p50_3d_m"] == pytest.approx(5.0)
    assert s["p95_3d_m"] == pytest.approx(5.0)
    assert s["max_3d_m"] == pytest.approx(5.0)
    # At lat 0, lon 0: ECEF x is up, y east, z north.
    ref = geodetic2ecef(0.0, 0.0, 0.0)
    np.testing.assert_allclose(enu_errors([[1.0, 2.0, 3.0]], ref), [[2.0, 3.0, 1.0]], atol=1e-12)
    s2 = error_stats([[1.0, 2.0, 3.0], [-1.0, 0.0, 0.0]], ref)
    assert s2["H_rms_m"] == pytest.approx(math.sqrt(13.0 / 2.0))
    assert s2["V_rms_m"] == pytest.approx(1.0)
    assert s2["V_95_m"] == pytest.approx(1.0)


def test_fix_rate_and_ttff() -> None:
    st = np.array(["none", "float", "float", "fixed", "partial", "fixed"])
    t = np.arange(6.0) * 2.0
    assert fix_rate(st) == pytest.approx(2 / 5)
    assert fix_rate(st, fixed=("fixed", "partial")) == pytest.approx(3 / 5)
    assert fix_rate(st, n_total=10) == pytest.approx(0.2)
    assert time_to_first_fix(t, st) == 6.0
    assert time_to_first_fix(t, st, t0_s=-1.0) == 7.0
    assert time_to_first_fix(t, st, fixed=("partial",)) == 8.0
    assert math.isnan(time_to_first_fix(t, np.array(["float"] * 6)))


def test_extra_error_hand_values() -> None:
    e = np.array([1.0, 1.2, 5.0, 7.0, 1.1, np.nan, 3.0])
    m = np.array([True, False, True, True, False, False, True])
    x = extra_error(e, m)
    # epoch 0 has no clean epoch before it; epoch 6's last clean finite epoch is 4.
    np.testing.assert_allclose(x, [np.nan, np.nan, 3.8, 5.8, np.nan, np.nan, 1.9])
    assert mean_extra_error(e, m) == pytest.approx((3.8 + 5.8 + 1.9) / 3)
    better = np.where(m, e * 0.0 + np.array([0, 0, 1.5, 1.5, 0, 0, 1.2]), e)
    assert removed_fraction(e, better, m) == pytest.approx(
        1 - ((1.5 - 1.2) + (1.5 - 1.2) + (1.2 - 1.1)) / 3 / ((3.8 + 5.8 + 1.9) / 3)
    )


@pytest.mark.parametrize(
    ("name", "ttff_s"),
    [
        ("mosaicx5_static_1m", 31.0),
        ("kamakura_kinematic_5km", 48.0),
        ("geonet_0759_3040_static_3km", 420.0),
    ],  # fmt: skip
)
def test_ttff_matches_readme(shared_data: Path, name: str, ttff_s: float) -> None:
    tb = read_pos(shared_data / name / "rtklib" / "fh.pos")
    assert time_to_first_fix(tb.t_s, tb.status) == ttff_s


def test_stats_match_rtklib_eval_json(shared_data: Path) -> None:
    d = shared_data / "mosaicx5_static_1m"
    tb = read_pos(d / "rtklib" / "fh.pos")
    ref = json.loads((d / "rtklib" / "fh.eval.json").read_text())
    lat, lon, h = (float(v) for v in (d / "rover_position.txt").read_text().split())
    truth = geodetic2ecef(np.radians(lat), np.radians(lon), h)
    err = position_errors(tb, None, truth)
    fixed = tb.status == "fixed"
    s = error_stats(err[fixed], truth)
    assert s["n"] == ref["fixed"]["n"]
    for key, rk in (("H_rms_m", "H_rms_m"), ("H_95_m", "H_95_m"), ("V_rms_m", "V_rms_m"),
                    ("V_95_m", "V_95_m")):  # fmt: skip
        assert s[key] == pytest.approx(ref["fixed"][rk], abs=1.5e-4), key
    s_all = error_stats(err, truth)
    assert s_all["H_rms_m"] == pytest.approx(ref["all"]["H_rms_m"], abs=1.5e-4)
    assert fix_rate(tb.status) == pytest.approx(ref["fix_rate_pct_of_solved"] / 100, abs=5e-4)
