"""Solution comparison: reference evaluations of the RTKLIB runs, truth files, synthetic cases."""

from __future__ import annotations

import json
import math
from functools import cache
from pathlib import Path

import numpy as np
import pytest

from robustrtk.core import InputError, Solution
from robustrtk.eval.compare import (
    Truth,
    compare_files,
    compare_solution,
    comparison_report,
    count_rover_epochs,
    default_labels,
    detail_table,
    error_group_stats,
    load_solution,
    parse_time_window,
    parse_truth,
    plot_comparison,
    read_truth_file,
    summary_table,
    truth_from_llh,
    truth_from_xyz,
    write_json,
)
from robustrtk.eval.plots import save_figure
from robustrtk.geometry.frames import enu2ecef_deg, geodetic2ecef_deg
from robustrtk.io.solution import SolutionTable, read_pos, write_pos, write_solution_csv
from robustrtk.timeutil import gpst_from_calendar

# dataset folder -> (truth file, rover observation file)
DATASETS = {
    "geonet_0759_3040_static_3km": ("truth_and_base.txt", "07590920.05o"),
    "mosaicx5_static_1m": ("rover_position.txt", "rover.obs"),
    "kamakura_kinematic_5km": ("truth_and_base.txt", "SEPT265G.21O"),
}
EVAL_FILES = [(ds, run) for ds in DATASETS for run in ("comb_fh", "cont", "dgps", "fh", "inst")]
GROUP_FLOATS = ("H_rms_m", "H_95_m", "V_rms_m", "V_95_m", "H_max_m", "V_max_m")


@cache
def _rover_epochs(obs_path: str) -> int:
    return count_rover_epochs(obs_path)


def _reference(shared_data: Path, ds: str, run: str) -> dict:
    path = shared_data / ds / "rtklib" / f"{run}.eval.json"
    if not path.is_file():
        pytest.skip(f"{path} not present")
    return json.loads(path.read_text())


def _assert_matches_reference(got: dict, ref: dict, tol: float = 0.0) -> None:
    """Every statistic of ``ref`` (printed to 4 decimals in m, 2 in %) equals ``got`` rounded alike."""
    assert got["epochs_solved"] == ref["epochs_solved"]
    assert got["Q_hist"] == ref["Q_hist"]
    assert round(got["fix_rate_pct_of_solved"], 2) == ref["fix_rate_pct_of_solved"]
    assert got["rover_epochs"] == ref["rover_epochs"]
    assert round(got["fix_rate_pct_of_rover_epochs"], 2) == ref["fix_rate_pct_of_rover_epochs"]
    for group in ("fixed", "float", "all"):
        r, g = ref[group], got[group]
        if r is None:
            assert g is None, group
            continue
        assert g is not None, group
        assert g["n"] == r["n"], group
        assert g["n_3d_err_gt_0.10m"] == r["n_3d_err_gt_0.10m"], group
        for key in GROUP_FLOATS:
            if tol:
                assert abs(g[key] - r[key]) <= tol, (group, key, g[key], r[key])
            else:
                assert round(g[key], 4) == r[key], (group, key, g[key], r[key])
        for k in range(3):
            if tol:
                assert abs(g["mean_enu_m"][k] - r["mean_enu_m"][k]) <= tol, (group, k)
            else:
                assert round(g["mean_enu_m"][k], 4) == r["mean_enu_m"][k], (group, k)


def _compare_run(shared_data: Path, ds: str, pos_path: Path, ref: dict) -> dict:
    truth_name, obs_name = DATASETS[ds]
    truth = read_truth_file(shared_data / ds / truth_name)
    window = ",".join(ref["truth_window"]) if "truth_window" in ref else None
    (res,) = compare_files(
        [pos_path], truth, rover_epochs=_rover_epochs(str(shared_data / ds / obs_name)), window=window
    )
    return res.to_dict()


# ----------------------------------------------------------------- reference numbers
@pytest.mark.parametrize(("ds", "run"), EVAL_FILES)
def test_reproduces_reference_evaluation(shared_data: Path, ds: str, run: str) -> None:
    ref = _reference(shared_data, ds, run)
    got = _compare_run(shared_data, ds, shared_data / ds / "rtklib" / ref["pos"], ref)
    _assert_matches_reference(got, ref)


def test_every_reference_evaluation_is_covered(shared_data: Path) -> None:
    found = {(p.parent.parent.name, p.name.removesuffix(".eval.json"))
             for ds in DATASETS for p in (shared_data / ds / "rtklib").glob("*.eval.json")}  # fmt: skip
    assert found == set(EVAL_FILES)


@pytest.mark.parametrize(
    ("ds", "ttff_fh_s"),
    [("geonet_0759_3040_static_3km", 420.0), ("mosaicx5_static_1m", 31.0), ("kamakura_kinematic_5km", 48.0)],
)
def test_time_to_first_fix_matches_readme(shared_data: Path, ds: str, ttff_fh_s: float) -> None:
    res = compare_files([shared_data / ds / "rtklib" / "fh.pos", shared_data / ds / "rtklib" / "inst.pos"])
    assert [r.ttff_s for r in res] == [ttff_fh_s, 0.0]
    assert res[0].groups == {}  # no truth: no error statistics


def test_kamakura_against_pseudo_reference_trajectory(shared_data: Path) -> None:
    """README: fh fixed epochs vs the forward+backward trajectory, H 0.1 / 0.1 cm, V 0.9 / 2.4 cm."""
    folder = shared_data / "kamakura_kinematic_5km" / "rtklib"
    truth = read_truth_file(folder / "pseudoref_comb_fh_traj.txt")
    assert not truth.is_point and truth.ecef and truth.pos_m.shape == (360, 3)
    comb = read_pos(folder / "comb_fh.pos")
    np.testing.assert_allclose(truth.t_s, comb.t_s, atol=1e-6)  # week/tow decoded to the same GPST
    (res,) = compare_files([folder / "fh.pos"], truth)
    fx = res.groups["fixed"]
    assert fx is not None and fx["n"] == 312
    got_cm = [round(100.0 * fx[k], 1) for k in ("H_rms_m", "H_95_m", "V_rms_m", "V_95_m")]
    assert got_cm == [0.1, 0.1, 0.9, 2.4]
    # comb_fh against itself (as .pos truth): zero error at every epoch
    (self_res,) = compare_files([folder / "comb_fh.pos"], parse_truth(str(folder / "comb_fh.pos")))
    assert self_res.groups["all"] is not None and self_res.groups["all"]["H_max_m"] < 1e-6


def _solutions_of(table: SolutionTable) -> list[Solution]:
    return [Solution(t_s=float(table.t_s[i]), pos_m=table.pos_m[i], cov_m2=np.diag(table.std_m[i] ** 2),
                     status=str(table.status[i]), n_used=int(table.n_used[i]), ratio=float(table.ratio[i]))
            for i in range(len(table))]  # fmt: skip


def test_xyz_pos_and_our_csv_give_the_same_statistics(shared_data: Path, tmp_path: Path) -> None:
    ds = "geonet_0759_3040_static_3km"
    ref = _reference(shared_data, ds, "fh")
    sols = _solutions_of(read_pos(shared_data / ds / "rtklib" / "fh.pos"))
    write_pos(sols, tmp_path / "fh_xyz.pos", frame="ecef")
    write_solution_csv(sols, tmp_path / "fh.csv")
    assert "x-ecef(m)" in (tmp_path / "fh_xyz.pos").read_text()
    # xyz written to 0.1 mm: statistics within 0.2 mm of the reference
    _assert_matches_reference(_compare_run(shared_data, ds, tmp_path / "fh_xyz.pos", ref), ref, tol=2e-4)
    # CSV keeps full precision: exact reproduction, including the Q histogram from statuses
    got = _compare_run(shared_data, ds, tmp_path / "fh.csv", ref)
    _assert_matches_reference(got, ref)
    assert got["status_hist"] == {"fixed": 101, "float": 14}


# ----------------------------------------------------------------- truth files
def test_truth_files_of_the_datasets(shared_data: Path) -> None:
    geo = read_truth_file(shared_data / "geonet_0759_3040_static_3km" / "truth_and_base.txt")
    np.testing.assert_array_equal(geo.pos_m, [-3976219.1879, 3382371.6056, 3652511.1425])  # rover, not base
    assert geo.is_point and geo.ecef and geo.note is None
    mos = read_truth_file(shared_data / "mosaicx5_static_1m" / "rover_position.txt")
    np.testing.assert_allclose(mos.pos_m, geodetic2ecef_deg(35.13469901, 136.97757549, 104.8626), atol=1e-9)
    kam = read_truth_file(shared_data / "kamakura_kinematic_5km" / "truth_and_base.txt")
    np.testing.assert_allclose(kam.pos_m, geodetic2ecef_deg(35.342058098, 139.521986657, 47.5515), atol=1e-9)
    assert kam.note is not None and "06:30:00-06:30:34" in kam.note


def test_truth_point_forms(tmp_path: Path) -> None:
    p = geodetic2ecef_deg(35.0, 139.0, 50.0)
    assert truth_from_xyz(f"{p[0]},{p[1]},{p[2]}").ecef
    np.testing.assert_allclose(truth_from_llh("35,139,50").pos_m, p)
    assert not truth_from_xyz("1.5,2.0,0.3").ecef  # local (pseudolite) frame
    f = tmp_path / "pt.txt"
    f.write_text("# comment\nstation_xyz 1.0 2.0 3.0\n")  # a name ending in xyz forces Cartesian
    t = read_truth_file(f)
    assert not t.ecef and list(t.pos_m) == [1.0, 2.0, 3.0]
    f.write_text(f"{p[0]:.4f}, {p[1]:.4f}, {p[2]:.4f}\n")
    np.testing.assert_allclose(read_truth_file(f).pos_m, p, atol=1e-4)
    f.write_text("base_llh 35 139 50\nrover_llh 35.001 139 50\n")
    np.testing.assert_allclose(read_truth_file(f).pos_m, geodetic2ecef_deg(35.001, 139.0, 50.0))
    assert parse_truth(str(f)).source.endswith("(rover_llh)")


@pytest.mark.parametrize(
    ("text", "where", "what"),
    [
        ("a_xyz 1 2 3\nb_xyz 4 5 6\n", ":", "several points"),
        ("rover_xyz 1 2\n", ":1:", "expected a point"),
        ("# x\n2176 100.0 1 2 3\n2176 101.0 1 2\n", ":3:", "expected 5 numbers"),
        ("rover_llh 135 10 50\n", ":1:", "latitude"),
        ("# nothing\n", ":", "no truth data lines"),
        ("time,x,y,z\n0,1,2,three\n", ":2:", "expected numbers time,x,y,z"),
    ],
)
def test_bad_truth_files_are_one_line_errors(tmp_path: Path, text: str, where: str, what: str) -> None:
    f = tmp_path / "truth.txt"
    f.write_text(text)
    with pytest.raises(InputError) as exc:
        read_truth_file(f)
    msg = str(exc.value)
    assert "\n" not in msg and msg.startswith(str(f) + where) and what in msg


def test_parse_truth_rejects_non_file_non_xyz() -> None:
    with pytest.raises(InputError, match="--truth: expected X,Y,Z"):
        parse_truth("/no/such/file.txt")
    with pytest.raises(InputError, match="three comma-separated"):
        truth_from_llh("35,139")


def test_time_windows() -> None:
    t_ref = gpst_from_calendar(2021, 9, 22, 6, 0, 0.0)
    a = gpst_from_calendar(2021, 9, 22, 6, 30, 0.0)
    b = gpst_from_calendar(2021, 9, 22, 6, 30, 34.0)
    assert parse_time_window("2021/09/22 06:30:00,2021/09/22 06:30:34", t_ref) == (a, b)
    assert parse_time_window("2021-09-22T06:30:00, 2021-09-22T06:30:34", t_ref) == (a, b)
    assert parse_time_window("06:30:00,06:30:34", t_ref) == (a, b)
    start, end = parse_time_window("23:59:50,00:00:10", t_ref)
    assert end - start == 20.0
    assert parse_time_window("10,20.5", t_ref) == (10.0, 20.5)
    for bad in ("06:30:00", "6.30,7.30,8", "yesterday,today", "20,10"):
        with pytest.raises(InputError, match="--truth-window"):
            parse_time_window(bad, t_ref)


# ----------------------------------------------------------------- synthetic cases
LAT, LON, H = 35.0, 139.0, 50.0
T0 = gpst_from_calendar(2024, 1, 2, 3, 0, 0.0)


def _table(enu_m: np.ndarray, status: list[str], t_s: np.ndarray | None = None) -> SolutionTable:
    n = len(status)
    t = T0 + np.arange(n, dtype=float) if t_s is None else t_s
    sols = [Solution(t_s=float(t[i]), pos_m=enu2ecef_deg(enu_m[i], LAT, LON, H), cov_m2=np.eye(3) * 1e-4,
                     status=status[i]) for i in range(n)]  # fmt: skip
    return SolutionTable.from_solutions(sols)


def _q(table: SolutionTable) -> np.ndarray:
    return np.array([{"fixed": 1, "partial": 1, "float": 2, "single": 5, "none": 0}[s] for s in table.status])


def test_hand_made_errors_give_exact_statistics() -> None:
    # 20 epochs: East error 0.01 i (i = 1..20), North 0, Up alternating ±0.002 i
    i = np.arange(1, 21, dtype=float)
    enu = np.stack([0.01 * i, np.zeros(20), 0.002 * i * (-1.0) ** i], axis=1)
    status = ["float"] * 4 + ["fixed"] * 16
    tab = _table(enu, status)
    res = compare_solution(tab, _q(tab), truth_from_llh(f"{LAT},{LON},{H}"), label="hand", rover_epochs=25)
    a = res.groups["all"]
    assert a is not None and a["n"] == 20
    assert a["H_rms_m"] == pytest.approx(0.01 * math.sqrt(np.mean(i**2)), abs=1e-9)  # sqrt(143.5) cm
    # linear percentile: p = 0.95 * 19 = 18.05 -> x(18) + 0.05 (x(19) - x(18)) = 0.19 + 0.0005
    assert a["H_95_m"] == pytest.approx(0.1905, abs=1e-9)
    assert a["V_95_m"] == pytest.approx(0.038 + 0.05 * 0.002, abs=1e-9)
    assert a["V_rms_m"] == pytest.approx(0.002 * math.sqrt(143.5), abs=1e-9)
    assert a["mean_enu_m"] == pytest.approx([0.105, 0.0, 0.002 * 10 / 20], abs=1e-9)  # sum (-1)^i i = 10
    assert a["H_max_m"] == pytest.approx(0.20, abs=1e-9) and a["V_max_m"] == pytest.approx(0.04, abs=1e-9)
    assert a["n_3d_err_gt_0.10m"] == 11  # |e| > 0.10 m from i = 10 (0.1002 m) on
    f = res.groups["fixed"]
    assert f is not None and f["n"] == 16 and f["H_max_m"] == pytest.approx(0.20, abs=1e-9)
    # fixed epochs i = 5..20: p = 0.95 * 15 = 14.25 -> 0.19 + 0.25 * 0.01
    assert f["H_95_m"] == pytest.approx(0.1925, abs=1e-9)
    fl = res.groups["float"]
    assert fl is not None and fl["n"] == 4 and fl["H_rms_m"] == pytest.approx(0.01 * math.sqrt(7.5), abs=1e-9)
    assert res.ttff_s == 4.0
    assert res.fix_rate_pct_of_solved == 80.0 and res.fix_rate_pct_of_rover_epochs == 64.0
    assert res.q_hist == {1: 16, 2: 4}


def test_group_statistics_of_nothing_and_of_nan_rows() -> None:
    assert error_group_stats(np.empty((0, 3))) is None
    assert error_group_stats(np.full((3, 3), np.nan)) is None
    g = error_group_stats(np.array([[0.3, 0.4, -0.12], [np.nan, 0.0, 0.0]]))
    assert g is not None and g["n"] == 1 and g["H_95_m"] == pytest.approx(0.5) and g["V_rms_m"] == 0.12


def test_partial_is_fixed_and_none_is_not_solved() -> None:
    enu = np.zeros((6, 3))
    tab = _table(enu, ["none", "single", "float", "partial", "fixed", "none"])
    res = compare_solution(tab, _q(tab), None, label="x")
    assert res.epochs_solved == 4 and res.n_fixed == 2
    assert res.q_hist == {1: 2, 2: 1, 5: 1}
    assert res.ttff_s == 2.0  # first solved epoch at T0 + 1, first (partial) fix at T0 + 3
    assert res.fix_rate_pct_of_rover_epochs is None


def test_trajectory_match_tolerance_and_window() -> None:
    n = 10
    t = T0 + np.arange(n, dtype=float)
    enu = np.zeros((n, 3))
    enu[:, 0] = 0.01
    tab = _table(enu, ["fixed"] * n, t)
    truth_pos = np.array([enu2ecef_deg([0.0, 0.0, 0.0], LAT, LON, H)] * n)
    truth_t = t + np.where(np.arange(n) % 2 == 0, 0.04, 0.06)  # even epochs within 0.05 s, odd not
    truth = Truth(pos_m=truth_pos, t_s=truth_t, ecef=True, source="traj")
    res = compare_solution(tab, _q(tab), truth, label="x", rover_epochs=n)
    assert res.groups["all"] is not None and res.groups["all"]["n"] == 5
    assert res.groups["all"]["H_rms_m"] == pytest.approx(0.01, abs=1e-9)
    assert res.fix_rate_pct_of_rover_epochs == 100.0  # epochs without truth still count for the fix rate
    res = compare_solution(tab, _q(tab), truth, label="x", tol_s=0.1, window_s=(T0 + 2.0, T0 + 5.0))
    assert res.groups["all"] is not None and res.groups["all"]["n"] == 4  # window inclusive
    res = compare_solution(tab, _q(tab), truth, label="x", window_s=(T0 + 100.0, T0 + 200.0))
    assert res.groups["all"] is None and res.warnings


def test_local_frame_truth_uses_xyz_as_enu() -> None:
    pos = np.array([[1.0, 2.0, 3.0], [1.1, 2.0, 3.0], [1.0, 2.0, 2.5]])
    tab = SolutionTable(t_s=np.arange(3.0), pos_m=pos,
                        std_m=np.zeros((3, 3)), status=np.array(["fixed", "float", "fixed"]),
                        n_used=np.zeros(3, np.int64), ratio=np.zeros(3), n_fixed=np.zeros(3, np.int64),
                        n_amb=np.zeros(3, np.int64))  # fmt: skip
    res = compare_solution(tab, _q(tab), truth_from_xyz("1,2,3"), label="room")
    a = res.groups["all"]
    assert a is not None and a["H_max_m"] == pytest.approx(0.1) and a["V_max_m"] == pytest.approx(0.5)
    np.testing.assert_allclose(res.enu_err_m, [[0, 0, 0], [0.1, 0, 0], [0, 0, -0.5]], atol=1e-12)
    with pytest.raises(InputError, match="same frame"):
        compare_solution(tab, _q(tab), truth_from_llh("35,139,50"), label="room")


def test_rover_epochs_below_solved_is_an_error() -> None:
    tab = _table(np.zeros((5, 3)), ["fixed"] * 5)
    with pytest.raises(InputError, match="4 rover epochs"):
        compare_solution(tab, _q(tab), None, label="x", rover_epochs=4)


def test_load_solution_errors_name_file_and_line(tmp_path: Path) -> None:
    bad = tmp_path / "bad.txt"
    bad.write_text("\nhello world\n")
    with pytest.raises(InputError, match=r"bad\.txt:2: expected an RTKLIB \.pos"):
        load_solution(bad)
    pos = tmp_path / "bad.pos"
    pos.write_text("%  GPST  latitude(deg) longitude(deg) height(m) Q ns\n2024/01/01 00:00:00.000 35 139\n")
    with pytest.raises(InputError, match=r"bad\.pos:2: expected at least 7 fields"):
        load_solution(pos)
    with pytest.raises(InputError, match="cannot read file"):
        load_solution(tmp_path / "missing.pos")


def test_labels_tables_json_and_plot(tmp_path: Path) -> None:
    assert default_labels(["a/fh.pos", "b/fh.pos", "c/inst.csv"]) == ["a/fh", "b/fh", "inst"]
    assert default_labels(["a/fh.pos", "a/fh.pos"]) == ["a/fh#1", "a/fh#2"]
    i = np.arange(1, 21, dtype=float)
    enu = np.stack([0.01 * i, np.zeros(20), 0.002 * i], axis=1)
    write_solution_csv(_solutions_of(_table(enu, ["float"] * 4 + ["fixed"] * 16)), tmp_path / "one.csv")
    write_solution_csv(_solutions_of(_table(enu / 2, ["fixed"] * 20)), tmp_path / "two.csv")
    truth = truth_from_llh(f"{LAT},{LON},{H}")
    res = compare_files([tmp_path / "one.csv", tmp_path / "two.csv"], truth, labels=["A"], rover_epochs=20)
    assert [r.label for r in res] == ["A", "two"]
    table = summary_table(res).splitlines()
    assert table[0].split()[:4] == ["solution", "solved", "Q", "hist"]
    row = table[2].split()
    assert row[:7] == ["A", "20", "1:16", "2:4", "80.00", "80.00", "4"]
    assert "-" not in table[3].split()[6]  # two: fixed from the start -> TTFF 0
    assert len(detail_table(res).splitlines()) == 2 + 6 + 1
    report = comparison_report(res, truth)
    write_json(report, tmp_path / "out.json")
    back = json.loads((tmp_path / "out.json").read_text())
    assert back["solutions"][0]["all"]["H_95_m"] == pytest.approx(0.1905)
    assert back["solutions"][1]["float"] is None and back["truth"]["kind"] == "point"
    fig = plot_comparison(res, title="synthetic", range_m=0.155)
    axes = fig.get_axes()
    assert len(axes) == 8
    for ax in axes:
        assert ax.get_xlabel().endswith("(s)") or ax.get_xlabel() == "East error (m)"
        assert "(m)" in ax.get_ylabel() and ax.get_title()
    assert axes[0].get_legend() is not None and axes[3].get_legend() is not None
    assert axes[0].get_title() == "A: East error (5 off-scale)"  # East errors 0.16 .. 0.20 m > 0.155 m
    out = save_figure(fig, tmp_path / "cmp.png")
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cmp.png", "one.csv", "out.json", "two.csv"]
