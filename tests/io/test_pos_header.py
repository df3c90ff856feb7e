"""The ``.pos`` header in RTKLIB's layout: the program once, the input files, the reference
position; RTKLIB's own ``fh.pos`` files are the reference for the layout of each line."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from robustrtk.cli.entry import run
from robustrtk.core import InputError, Solution
from robustrtk.geometry.frames import ecef2geodetic, geodetic2ecef
from robustrtk.io.solution_pos import pos_header, read_pos, write_pos

BASE_ECEF_M = np.array([-3978241.958, 3382840.234, 3649900.853])  # geonet base (data README)


def _rtklib_header(path: Path) -> list[str]:
    return [ln.rstrip("\n") for ln in path.read_text().splitlines() if ln.startswith("%")]


@pytest.mark.parametrize(
    "name", ["kamakura_kinematic_5km", "mosaicx5_static_1m", "geonet_0759_3040_static_3km"]
)
def test_ref_pos_and_input_lines_as_rtklib_writes_them(shared_data: Path, name: str) -> None:
    head = _rtklib_header(shared_data / name / "rtklib" / "fh.pos")
    ref = [ln for ln in head if ln.startswith("% ref pos")]
    inputs = [ln.split(":", 1)[1].strip() for ln in head if ln.startswith("% inp file")]
    assert len(ref) == 1 and inputs
    lat, lon, h = (float(v) for v in ref[0].split(":", 1)[1].split())
    ecef = geodetic2ecef(math.radians(lat), math.radians(lon), h)
    ours = pos_header(inputs, ecef, "llh")
    assert ours[0].startswith("% program   : robustrtk")
    # the same input lines and, from the same position, the same reference line byte for byte
    assert [ln for ln in ours if ln.startswith("% inp file")] == [
        ln for ln in head if ln.startswith("% inp file")
    ]
    assert [ln for ln in ours if ln.startswith("% ref pos")] == ref
    assert ours[-1] == "%"


def _sols(n: int = 3) -> list[Solution]:
    rover = BASE_ECEF_M + np.array([2000.0, -500.0, 2600.0])
    return [
        Solution(t_s=1.4e9 + i, pos_m=rover + 0.01 * i, cov_m2=np.eye(3) * 1e-4, status="fixed", n_used=9)
        for i in range(n)
    ]


@pytest.mark.parametrize("frame", ["llh", "ecef"])
def test_written_header_program_once_inputs_ref_then_columns(tmp_path: Path, frame: str) -> None:
    out = tmp_path / f"{frame}.pos"
    write_pos(
        _sols(), out, frame=frame, inputs=["rover.obs", "base.obs", "nav.nav"], ref_pos_ecef_m=BASE_ECEF_M
    )
    lines = out.read_text().splitlines()
    assert sum(ln.startswith("% program") for ln in lines) == 1
    assert lines[1:4] == ["% inp file  : rover.obs", "% inp file  : base.obs", "% inp file  : nav.nav"]
    ref = lines[4].split(":", 1)[1].split()
    if frame == "llh":
        lat, lon, h = (float(v) for v in ecef2geodetic(BASE_ECEF_M))
        assert ref == [f"{math.degrees(lat):.9f}", f"{math.degrees(lon):.9f}", f"{h:.4f}"]
    else:
        assert ref == [f"{v:.4f}" for v in BASE_ECEF_M]
    assert lines[5] == "%" and lines[6].startswith("% (")
    back = read_pos(out)
    np.testing.assert_allclose(back.pos_m, np.array([s.pos_m for s in _sols()]), atol=1e-3)


def test_no_ref_line_without_a_reference_and_bad_reference_refused(tmp_path: Path) -> None:
    out = tmp_path / "a.pos"
    write_pos(_sols(), out)
    head = [ln for ln in out.read_text().splitlines() if ln.startswith("%")]
    assert head[0].startswith("% program") and head[1] == "%"
    assert not any(ln.startswith(("% ref pos", "% inp file")) for ln in head)
    with pytest.raises(InputError, match="ref pos"):
        write_pos(_sols(), out, ref_pos_ecef_m=[1.0, math.nan, 2.0])


def test_solve_names_its_inputs_and_the_base_position(shared_data: Path, tmp_path: Path) -> None:
    d = shared_data / "geonet_0759_3040_static_3km"
    rover, base, nav = d / "07590920.05o", d / "30400920.05o", d / "07590920.05n"
    out = tmp_path / "rtk.pos"
    xyz = ",".join(f"{v:.3f}" for v in BASE_ECEF_M)
    argv = ["solve", str(rover), "--base", str(base), "--nav", str(nav), f"--base-pos={xyz}", "--mode", "rtk"]
    assert run([*argv, "--quiet", "--out", str(out)]) == 0
    head = [ln for ln in out.read_text().splitlines() if ln.startswith("%")]
    assert [ln.split(":", 1)[1].strip() for ln in head if ln.startswith("% inp file")] == [
        str(rover),
        str(base),
        str(nav),
    ]
    assert head.count(pos_header((), BASE_ECEF_M)[1]) == 1  # the --base-pos, as RTKLIB's line
    assert sum(ln.startswith("% program") for ln in head) == 1
