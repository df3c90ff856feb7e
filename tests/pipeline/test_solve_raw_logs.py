"""``solve`` from the raw galway logs (rover UBX, base RTCM 3, ephemerides from the UBX) gives
the solution of the RINEX files convbin made from them (skipped without the shared data).

Differences allowed: the raw observations are not rounded to RINEX's 1 mm / 0.001 cycle and
the decoded Klobuchar coefficients are not rounded to convbin's 4 digits, which moves float
positions by millimetres; epochs and solution types must be the same.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from robustrtk.cli.main import main


def _rows(path: Path) -> list[list[str]]:
    return [ln.split() for ln in path.read_text().splitlines() if ln.strip() and not ln.startswith("%")]


def test_solve_raw_equals_solve_convbin_rinex(shared_data: Path, tmp_path: Path) -> None:
    g = shared_data / "galway_m8p_l1_lowcost"
    d = g / "s1_static"
    if not d.is_dir():
        pytest.skip(f"{d} absent")
    common = [
        "--mode", "rtk", "--rtklib-conf", str(g / "rtklib" / "s1_fh_m8pbase.conf"),
        "--time-end", "2018/10/04 12:46:00", "--quiet",
    ]  # fmt: skip
    out_r, out_b = tmp_path / "rinex.pos", tmp_path / "raw.pos"
    res = CliRunner().invoke(
        main,
        ["solve", str(d / "rover-20181004-1237.obs"), "--base", str(d / "base-20181004-1236_rtcm.obs"),
         "--nav", str(d / "rover-20181004-1237.nav"), "--out", str(out_r), *common],
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    res = CliRunner().invoke(
        main,
        ["solve", str(d / "rover-20181004-1237.ubx.gz"), "--base", str(d / "base-20181004-1236.rtcm3"),
         "--nav", str(d / "rover-20181004-1237.ubx.gz"), "--out", str(out_b), *common],
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    a, b = _rows(out_r), _rows(out_b)
    assert len(a) == len(b) > 100
    assert [r[:2] + [r[5]] for r in a] == [r[:2] + [r[5]] for r in b]  # epochs and Q
    assert sum(r[5] == "1" for r in a) > 50  # fixed epochs in the window
    pa = np.array([[float(x) for x in r[2:5]] for r in a])
    pb = np.array([[float(x) for x in r[2:5]] for r in b])
    assert np.max(np.abs(pa[:, :2] - pb[:, :2])) < 1e-7  # degrees: ~1 cm
    assert np.max(np.abs(pa[:, 2] - pb[:, 2])) < 0.01
