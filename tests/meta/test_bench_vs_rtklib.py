"""The side-by-side bench's reading of a dataset folder: the base position of RTKLIB's
``fh.conf`` becomes the matching ``solve`` arguments for every position type it can take."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

from robustrtk.geometry.frames import geodetic2ecef_deg

BENCH = Path(__file__).resolve().parents[2] / "bench" / "bench_vs_rtklib.py"


@pytest.fixture(scope="module")
def bench() -> ModuleType:
    spec = importlib.util.spec_from_file_location("bench_vs_rtklib", BENCH)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod  # dataclasses look their module up
    spec.loader.exec_module(mod)
    return mod


def _folder(tmp_path: Path, postype: str, pos: tuple[str, str, str] = ("", "", "")) -> Path:
    (tmp_path / "rtklib").mkdir(parents=True)
    for name in ("rover.obs", "base.obs", "base.nav"):
        (tmp_path / name).write_text("")
    lines = [f"ant2-postype       ={postype}  # (0:llh,1:xyz,2:single,3:posfile,4:rinexhead)"]
    lines += [f"ant2-pos{i}          ={v}" for i, v in enumerate(pos, 1)]
    (tmp_path / "rtklib" / "fh.conf").write_text("\n".join(lines) + "\n")
    inp = "".join(f"% inp file  : {n}\n" for n in ("rover.obs", "base.obs", "base.nav"))
    (tmp_path / "rtklib" / "fh.pos").write_text(inp + "% obs start : x\n2005/04/02 00:00:00.000 1 2 3 1 5\n")
    return tmp_path


def _cmd(bench: ModuleType, folder: Path) -> list[str]:
    ds = bench.find_dataset(folder)
    assert not isinstance(ds, str), ds
    return list(bench.robustrtk_cmd(ds, folder / "out.pos"))


def test_xyz_and_llh_bases_go_as_base_pos(bench: ModuleType, tmp_path: Path) -> None:
    cmd = _cmd(bench, _folder(tmp_path / "a", "xyz", ("-3978241.958", "3382840.234", "3649900.853")))
    assert cmd[cmd.index("--base-pos") + 1] == "-3978241.9580,3382840.2340,3649900.8530"
    cmd = _cmd(bench, _folder(tmp_path / "b", "0", ("35.134707705", "139.6", "45.0")))
    got = np.array([float(v) for v in cmd[cmd.index("--base-pos") + 1].split(",")])
    np.testing.assert_allclose(got, np.ravel(geodetic2ecef_deg(35.134707705, 139.6, 45.0)), atol=1e-4)
    assert "--base-position" not in cmd


def test_rinexhead_leaves_the_header_position_and_single_the_moving_base(
    bench: ModuleType, tmp_path: Path
) -> None:
    cmd = _cmd(bench, _folder(tmp_path / "a", "rinexhead"))
    assert "--base-pos" not in cmd and "--base-position" not in cmd
    cmd = _cmd(bench, _folder(tmp_path / "b", "2"))
    assert "--base-pos" not in cmd
    assert cmd[cmd.index("--base-position") + 1] == "moving"


def test_the_matching_run_takes_the_conf_and_the_default_run_does_not(
    bench: ModuleType, tmp_path: Path
) -> None:
    folder = _folder(tmp_path, "rinexhead")
    ds = bench.find_dataset(folder)
    conf = bench.robustrtk_cmd(ds, folder / "o.pos", "conf")
    assert conf[conf.index("--rtklib-conf") + 1] == str(folder / "rtklib" / "fh.conf")
    assert "--rtklib-conf" not in bench.robustrtk_cmd(ds, folder / "o.pos", "default")


def test_input_paths_of_another_machine_are_found_by_name_in_the_folder(
    bench: ModuleType, tmp_path: Path
) -> None:
    folder = _folder(tmp_path, "rinexhead")
    pos = folder / "rtklib" / "fh.pos"
    pos.write_text(pos.read_text().replace("% inp file  : ", "% inp file  : /home/survey/data/"))
    ds = bench.find_dataset(folder)
    assert not isinstance(ds, str), ds
    assert (ds.rover, ds.base, ds.navs) == (folder / "rover.obs", folder / "base.obs", (folder / "base.nav",))
    win = _folder(tmp_path / "win", "rinexhead")
    pos = win / "rtklib" / "fh.pos"
    pos.write_text(pos.read_text().replace("% inp file  : ", "% inp file  : C:\\gnss\\run 1\\"))
    ds = bench.find_dataset(win)
    assert not isinstance(ds, str), ds
    assert (ds.rover, ds.base, ds.navs) == (win / "rover.obs", win / "base.obs", (win / "base.nav",))
    (folder / "base.nav").unlink()
    why = bench.find_dataset(folder)
    assert isinstance(why, str) and "base.nav" in why


def test_other_position_types_are_skipped_with_a_reason(bench: ModuleType, tmp_path: Path) -> None:
    why = bench.find_dataset(_folder(tmp_path / "a", "posfile"))
    assert isinstance(why, str) and "posfile" in why
    why = bench.find_dataset(_folder(tmp_path / "b", "xyz", ("1", "2", "")))
    assert isinstance(why, str) and "ant2-pos" in why


def test_short_runs_end_both_programs_at_the_same_second(bench: ModuleType, tmp_path: Path) -> None:
    folder = _folder(tmp_path, "rinexhead")
    pos = folder / "rtklib" / "fh.pos"
    body = "".join(f"2005/04/02 00:{m:02d}:{s:02d}.003 1 2 3 1 5\n" for m in range(0, 60) for s in (0, 30))
    pos.write_text(pos.read_text().split("2005/")[0] + body)
    span = bench.pos_span_text(pos)
    assert span == ("2005/04/02 00:00:00.003", "2005/04/02 00:59:30.003")
    assert bench.span_second(*span, 0.5) == "2005/04/02 00:29:45"
    end = bench.span_second(*span)
    assert end == "2005/04/02 00:05:57"  # a tenth of 59 min 30 s, rounded down
    ds = bench.find_dataset(folder)
    r = bench.rtklib_cmd(Path("rnx2rtkp"), ds, folder / "h.pos", end)
    assert r[r.index("-te") + 1 : r.index("-te") + 3] == ["2005/04/02", "00:05:57"]
    o = bench.robustrtk_cmd(ds, folder / "h.pos", "conf", end)
    assert o[o.index("--time-end") + 1] == end
    assert "-te" not in bench.rtklib_cmd(Path("rnx2rtkp"), ds, folder / "f.pos")
    assert "--time-end" not in bench.robustrtk_cmd(ds, folder / "f.pos")


def test_marginal_cost_is_the_slope_between_the_two_spans(bench: ModuleType) -> None:
    full = bench.Runs(wall_s=[2.0, 2.2, 2.1], epochs=300)
    short = bench.Runs(wall_s=[1.2, 1.1, 1.3], epochs=30)
    assert bench.marginal_s(full, short) == pytest.approx((2.1 - 1.2) / 270)
    assert np.isnan(bench.marginal_s(full, bench.Runs(wall_s=[1.0], epochs=300)))
    assert np.isnan(bench.marginal_s(full, bench.Runs(wall_s=[1.0], epochs=100, failed="exit 2")))


def test_floor_bound_is_the_ratio_with_only_numpy_start_up(bench: ModuleType) -> None:
    # 0.1 s floor + 120 epochs at 1 ms against RTKLIB's 0.11 s: 0.22 / 0.11 = 2
    assert bench.floor_bound(0.1, 120, 0.001, 0.11) == pytest.approx(2.0)
    # the floor alone beats RTKLIB only when it is shorter than RTKLIB's whole run
    assert bench.floor_bound(0.1, 0, 0.001, 0.05) > 1.0
    assert bench.floor_bound(0.1, 0, 0.001, 0.2) < 1.0
    assert np.isnan(bench.floor_bound(0.1, 120, float("nan"), 0.11))
    assert np.isnan(bench.floor_bound(float("nan"), 120, 0.001, 0.11))
    assert np.isnan(bench.floor_bound(0.1, 120, 0.001, 0.0))


def test_the_floor_imports_numpy_and_nothing_of_ours(bench: ModuleType) -> None:
    cmd = bench.FLOOR_CMD
    assert cmd[0] == sys.executable and cmd[1] == "-c"
    assert "numpy" in cmd[2] and "robustrtk" not in cmd[2]


def test_markdown_header_has_one_separator_per_column(
    bench: ModuleType, capsys: pytest.CaptureFixture[str]
) -> None:
    rows = bench.start_table("a  b  c", "| a | b | c |")
    assert rows == ["| a | b | c |", "|---|---|---|"]
    assert capsys.readouterr().out == "a  b  c\n-------\n"
