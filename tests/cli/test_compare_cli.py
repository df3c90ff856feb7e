"""``robustrtk compare``: table, JSON and figure on the RTKLIB runs; one-line errors."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner, Result

from robustrtk.cli.compare import compare
from robustrtk.core import Solution
from robustrtk.geometry.frames import enu2ecef_deg
from robustrtk.io.solution import write_solution_csv
from robustrtk.timeutil import gpst_from_calendar

GEONET = "geonet_0759_3040_static_3km"
KAMAKURA = "kamakura_kinematic_5km"


def _run(*args: object) -> Result:
    return CliRunner().invoke(compare, [str(a) for a in args])


def _row(stdout: str, label: str) -> list[str]:
    summary = stdout.split("\n\n")[0]  # the per-solution table (--details adds a second one)
    rows = [ln.split() for ln in summary.splitlines() if ln.split()[:1] == [label]]
    assert len(rows) == 1, stdout
    return rows[0]


def test_geonet_table_json_and_plot(shared_data: Path, tmp_path: Path) -> None:
    d = shared_data / GEONET
    out_json, out_png = tmp_path / "cmp.json", tmp_path / "cmp.png"
    res = _run(d / "rtklib" / "fh.pos", d / "rtklib" / "inst.pos", "--truth", d / "truth_and_base.txt",
               "--rover-obs", d / "07590920.05o", "--json", out_json, "--plot", out_png)  # fmt: skip
    assert res.exit_code == 0, res.output
    # solution solved Q-hist fix% fix%-rover TTFF | fixed n, H rms, H 95, V rms, V 95 (cm) | all ...
    assert _row(res.stdout, "fh")[:12] == ["fh", "115", "1:101", "2:14", "87.83", "84.17", "420", "101",
                                           "0.54", "0.80", "1.11", "1.48"]  # fmt: skip
    assert _row(res.stdout, "inst")[:11] == ["inst", "115", "1:111", "2:4", "96.52", "92.50", "0", "111",
                                             "0.72", "1.63", "1.82"]  # fmt: skip
    report = json.loads(out_json.read_text())
    for got in report["solutions"]:
        ref = json.loads((d / "rtklib" / f"{got['label']}.eval.json").read_text())
        assert got["Q_hist"] == ref["Q_hist"] and got["rover_epochs"] == 120
        for group in ("fixed", "float", "all"):
            for key in ("H_rms_m", "H_95_m", "V_rms_m", "V_95_m", "H_max_m", "V_max_m"):
                assert round(got[group][key], 4) == ref[group][key]
    assert report["truth"]["kind"] == "point" and report["truth"]["source"].endswith(
        "(rover_xyz_selfderived)"
    )
    assert out_png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cmp.json", "cmp.png"]  # no temporary files left


def test_kamakura_window_and_note(shared_data: Path) -> None:
    d = shared_data / KAMAKURA
    args = [d / "rtklib" / "fh.pos", d / "rtklib" / "inst.pos", "--truth", d / "truth_and_base.txt",
            "--rover-epochs", "360"]  # fmt: skip
    res = _run(*args, "--truth-window", "06:30:00,06:30:34", "--details")
    assert res.exit_code == 0, res.output
    assert "window 2021/09/22 06:30:00 to 2021/09/22 06:30:34 GPST" in res.stdout
    assert res.stderr == ""
    # fh: no fixed epoch in the window; all 35 float. inst: 35 fixed, H 2.05 / 2.20 cm, V 0.82 / 1.27 cm
    assert _row(res.stdout, "fh")[6:9] == ["48", "0", "-"]
    assert _row(res.stdout, "inst")[6:12] == ["0", "35", "2.05", "2.20", "0.82", "1.27"]
    res = _run(*args)  # without the window the file's validity remark is shown
    assert res.exit_code == 0 and "valid only while static" in res.stderr and "--truth-window" in res.stderr


def test_trajectory_truth_and_llh_truth(shared_data: Path) -> None:
    d = shared_data / KAMAKURA
    res = _run(d / "rtklib" / "fh.pos", "--truth", d / "rtklib" / "pseudoref_comb_fh_traj.txt")
    assert res.exit_code == 0, res.output
    assert "360 epochs" in res.stdout and _row(res.stdout, "fh")[5] == "-"  # no rover count: no rover %
    assert _row(res.stdout, "fh")[7:12] == ["312", "0.10", "0.14", "0.93", "2.36"]
    m = shared_data / "mosaicx5_static_1m"
    res = _run(m / "rtklib" / "fh.pos", "--truth-llh", "35.13469901,136.97757549,104.8626", "--label", "FH")
    assert res.exit_code == 0, res.output
    assert _row(res.stdout, "FH")[4:12] == ["89.70", "-", "31", "270", "0.10", "0.17", "0.15", "0.27"]


def _synthetic_csv(path: Path, n: int = 10) -> None:
    t0 = gpst_from_calendar(2024, 1, 2, 3, 0, 0.0)
    sols = [Solution(t_s=t0 + k, pos_m=enu2ecef_deg([0.01 * k, 0.0, 0.02], 35.0, 139.0, 50.0),
                     cov_m2=np.eye(3) * 1e-4, status="float" if k < 3 else "fixed")
            for k in range(n)]  # fmt: skip
    write_solution_csv(sols, path)


def test_synthetic_csv_without_shared_data(tmp_path: Path) -> None:
    sol = tmp_path / "ours.csv"
    _synthetic_csv(sol)
    res = _run(sol, "--truth-llh", "35,139,50", "--rover-epochs", "20", "--json", tmp_path / "o.json")
    assert res.exit_code == 0, res.output
    assert _row(res.stdout, "ours")[:8] == ["ours", "10", "1:7", "2:3", "70.00", "35.00", "3", "7"]
    got = json.loads((tmp_path / "o.json").read_text())["solutions"][0]
    assert got["fixed"]["V_rms_m"] == pytest.approx(0.02, abs=1e-9)
    assert got["fixed"]["H_max_m"] == pytest.approx(0.09, abs=1e-9)
    res = _run(sol)  # no truth: fix rate and time to first fix only
    assert res.exit_code == 0 and _row(res.stdout, "ours")[4:7] == ["70.00", "-", "3"]


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--truth", "1,2"], "--truth: expected X,Y,Z"),
        (["--truth", "1,2,3", "--truth-llh", "1,2,3"], "either --truth or --truth-llh"),
        (["--truth-llh", "95,139,50"], "latitude -90..90"),
        (["--truth-llh", "35,139,50", "--truth-window", "later"], "--truth-window: expected START,END"),
        (["--plot", "x.png"], "need a truth"),
        (["--rover-epochs", "5"], "5 rover epochs given but the solution has 10"),
        (["--rover-epochs", "5", "--rover-obs", "x.obs"], "either --rover-epochs or --rover-obs"),
        (["--label", "a", "--label", "b"], "--label given 2 times for 1"),
        (["--truth-llh", "35,139,50", "--json", "/no/such/dir/o.json"], "output directory does not exist"),
        (["--truth-llh", "35,139,50", "--plot", "x.jpeg"], "expected a file ending in .png, .pdf or .svg"),
        (["--truth-llh", "35,139,50", "--plot", "/"], "--plot: is a directory"),
        (["--rover-obs", "/"], "is a directory"),
    ],
)
def test_bad_options_are_one_line(tmp_path: Path, extra: list[str], message: str) -> None:
    sol = tmp_path / "ours.csv"
    _synthetic_csv(sol)
    res = _run(sol, *extra)
    assert res.exit_code == 2, res.output
    assert res.stderr.startswith("error: ") and res.stderr.count("\n") == 1 and message in res.stderr
    assert "Traceback" not in res.output


def test_bad_files_are_one_line(tmp_path: Path) -> None:
    res = _run(tmp_path)
    assert res.exit_code == 2 and res.stderr == f"error: {tmp_path}: is a directory, expected a file\n"
    res = _run(tmp_path / "missing.pos")
    assert res.exit_code == 2 and res.stderr.startswith(f"error: {tmp_path / 'missing.pos'}: cannot read")
    bad = tmp_path / "bad.pos"
    bad.write_text(
        "% program : x\n%  GPST  latitude(deg) longitude(deg) height(m)\n2024/01/02 00:00:00 35 1\n"
    )
    res = _run(bad)
    want = f"error: {bad}:3: expected at least 7 fields (time, 3 coordinates, Q, ns), got 4"
    assert res.exit_code == 2 and res.stderr.strip() == want
    sol = tmp_path / "ours.csv"
    _synthetic_csv(sol)
    truth = tmp_path / "truth.txt"
    truth.write_text("rover_xyz 1 2 x\n")
    res = _run(sol, "--truth", truth)
    assert res.exit_code == 2 and res.stderr.startswith(f"error: {truth}:1: expected a point")
    assert res.stderr.count("\n") == 1
