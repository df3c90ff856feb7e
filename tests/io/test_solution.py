"""Solution writers and readers: CSV, RTKLIB .pos, NMEA GGA, diagnostics CSV."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from robustrtk.core import InputError, Solution
from robustrtk.geometry.frames import geodetic2ecef
from robustrtk.io.solution import (
    DIAG_COLUMNS,
    gga_sentence,
    nmea_checksum,
    read_diagnostics_csv,
    read_pos,
    read_solution_csv,
    write_diagnostics_csv,
    write_nmea,
    write_pos,
    write_solution_csv,
)
from robustrtk.timeutil import gpst_from_calendar

# README table: epochs solved and fix rate (% of solved) of RTKLIB's fix-and-hold runs.
README_FH = {
    "mosaicx5_static_1m": (301, 89.7),
    "geonet_0759_3040_static_3km": (115, 87.8),
    "kamakura_kinematic_5km": (360, 86.7),
}


def random_solutions(rng: np.random.Generator, n: int, vel: bool = False) -> list[Solution]:
    base = geodetic2ecef(np.radians(35.1347), np.radians(136.9776), 104.86)
    t0 = gpst_from_calendar(2024, 6, 24, 8, 20, 0.0)
    statuses = ["fixed", "float", "dgnss", "single", "fixed", "partial", "code"]
    out = []
    for i in range(n):
        a = rng.normal(size=(3, 3)) * 0.01
        cov = a @ a.T + np.eye(3) * 1e-6
        out.append(
            Solution(
                t_s=t0 + 0.2 * i + 0.001 * rng.integers(0, 3),
                pos_m=base + rng.normal(0, 5.0, 3),
                cov_m2=cov,
                status=statuses[i % len(statuses)],
                n_used=int(rng.integers(4, 30)),
                ratio=float(rng.uniform(0, 50)) if i % 3 else float("nan"),
                n_fixed=int(rng.integers(0, 10)),
                n_amb=int(rng.integers(10, 20)),
                vel_m_s=rng.normal(size=3) if vel and i % 2 else None,
            )
        )
    return out


@pytest.mark.parametrize("name", sorted(README_FH))
def test_read_pos_shared_matches_readme(shared_data: Path, name: str) -> None:
    tb = read_pos(shared_data / name / "rtklib" / "fh.pos")
    n, rate = README_FH[name]
    assert len(tb) == n
    assert 100.0 * np.mean(tb.status == "fixed") == pytest.approx(rate, abs=0.05)
    assert set(tb.status.tolist()) == {"fixed", "float"}
    assert np.all(np.diff(tb.t_s) > 0)
    assert np.all(tb.n_fixed == -1)


def test_read_pos_positions_and_times(shared_data: Path) -> None:
    tb = read_pos(shared_data / "mosaicx5_static_1m" / "rtklib" / "fh.pos")
    # First line: 2024/06/24 08:20:00.000 GPST, last fixed epoch near the staged truth.
    assert tb.t_s[0] == gpst_from_calendar(2024, 6, 24, 8, 20, 0.0)
    assert tb.t_s[-1] - tb.t_s[0] == 300.0
    lat, lon, h = (float(v) for v in (shared_data / "mosaicx5_static_1m" /
                                      "rover_position.txt").read_text().split())  # fmt: skip
    truth = geodetic2ecef(np.radians(lat), np.radians(lon), h)
    assert np.linalg.norm(tb.pos_m[-1] - truth) < 0.01
    # ENU sigmas of the last line (0.0040 0.0039 0.0111, small correlations) -> ECEF 3D.
    assert np.sqrt(np.sum(tb.std_m[-1] ** 2)) == pytest.approx(
        math.sqrt(0.0040**2 + 0.0039**2 + 0.0111**2), rel=0.02
    )
    gz = read_pos(shared_data / "geonet_0759_3040_static_3km" / "rtklib" / "dgps.pos")
    assert set(gz.status.tolist()) == {"dgnss"}


@pytest.mark.parametrize("frame", ["llh", "ecef"])
def test_pos_round_trip(tmp_path: Path, frame: str) -> None:
    rng = np.random.default_rng(1)
    sols = random_solutions(rng, 60)
    sols.append(Solution(t_s=sols[-1].t_s + 1, pos_m=np.full(3, np.nan),
                         cov_m2=np.eye(3), status="none"))  # fmt: skip
    path = tmp_path / "out.pos"
    write_pos(sols, path, frame=frame, header_lines=["pos mode  : test"])
    text = path.read_text()
    assert "% pos mode  : test" in text
    tb = read_pos(path)
    assert len(tb) == 60  # the 'none' epoch is not written
    pos = np.array([s.pos_m for s in sols[:60]])
    assert np.max(np.abs(tb.pos_m - pos)) < 1e-4
    t = np.array([s.t_s for s in sols[:60]])
    np.testing.assert_allclose(tb.t_s, t, atol=5e-4)
    expect = {"fixed": "fixed", "partial": "fixed", "float": "float", "dgnss": "dgnss",
              "code": "dgnss", "single": "single"}  # fmt: skip
    assert tb.status.tolist() == [expect[s.status] for s in sols[:60]]
    assert tb.n_used.tolist() == [s.n_used for s in sols[:60]]
    std = np.array([np.sqrt(np.diag(s.cov_m2)) for s in sols[:60]])
    np.testing.assert_allclose(tb.std_m, std, atol=3e-4)
    ratio = np.array([0.0 if math.isnan(s.ratio) else s.ratio for s in sols[:60]])
    np.testing.assert_allclose(tb.ratio, ratio, atol=0.051)


def test_pos_rejects_local_frame_and_keeps_old_file(tmp_path: Path) -> None:
    path = tmp_path / "keep.pos"
    path.write_text("old content\n")
    local = [Solution(t_s=1.0, pos_m=np.array([1.0, 2.0, 0.5]), cov_m2=np.eye(3), status="fixed")]
    with pytest.raises(InputError, match="local-frame"):
        write_pos(local, path, pos_frame="local")
    with pytest.raises(InputError, match="local-frame"):
        write_nmea(local, tmp_path / "x.nmea", pos_frame="local")
    bad = random_solutions(np.random.default_rng(0), 3)
    bad.append(Solution(t_s=9e8, pos_m=bad[0].pos_m, cov_m2=np.eye(3), status="bogus"))
    with pytest.raises(InputError, match="status"):
        write_solution_csv(bad, path)
    assert path.read_text() == "old content\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.pos"]


def test_one_wild_epoch_does_not_make_an_ecef_run_unwritable(tmp_path: Path) -> None:
    """The writer takes the frame from the caller, not from the magnitudes: an ECEF run
    with one epoch far off the Earth is written whole (every epoch, the wild one too)."""
    sols = random_solutions(np.random.default_rng(1), 5)
    wild = Solution(
        t_s=sols[-1].t_s + 1.0, pos_m=np.array([3.0e7, 1.0e6, 2.0e6]), cov_m2=np.eye(3), status="single"
    )
    path = tmp_path / "run.pos"
    write_pos([*sols, wild], path)
    tb = read_pos(path)
    assert len(tb) == len(sols) + 1
    np.testing.assert_allclose(tb.pos_m[-1], wild.pos_m, rtol=1e-9)
    write_nmea([*sols, wild], tmp_path / "run.nmea")
    assert (tmp_path / "run.nmea").read_text().count("$GPGGA") == len(sols) + 1


def test_read_pos_errors(tmp_path: Path) -> None:
    p = tmp_path / "bad.pos"
    p.write_text("2024/06/24 08:20:00.000 1 2 3 1 5 0 0 0 0 0 0 0 0\n")
    with pytest.raises(InputError) as ei:
        read_pos(p)
    assert ei.value.line == 1
    p.write_text(
        "%  GPST                      x-ecef(m)      y-ecef(m)      z-ecef(m)   Q  ns\n"
        "2024/06/24 08:20:00.000 1 2 3 1\n"
    )
    with pytest.raises(InputError, match="7 fields") as ei:
        read_pos(p)
    assert ei.value.line == 2 and ei.value.path == str(p)
    # a short line (no σ, age, ratio columns) is read with NaN in their place
    p.write_text(
        "%  GPST                      x-ecef(m)      y-ecef(m)      z-ecef(m)   Q  ns\n"
        "2024/06/24 08:20:00.000 1 2 3 1 5\n"
    )
    tb = read_pos(p)
    np.testing.assert_array_equal(tb.pos_m, [[1.0, 2.0, 3.0]])
    assert tb.n_used.tolist() == [5] and np.isnan(tb.std_m).all() and np.isnan(tb.ratio).all()


def test_read_pos_utc_week_tow(tmp_path: Path) -> None:
    p = tmp_path / "utc.pos"
    x, y, z = -3961953.0179, 3381199.0448, 3668915.4167
    p.write_text(
        "%  UTC                       x-ecef(m)      y-ecef(m)      z-ecef(m)   Q  ns   sdx(m)"
        "   sdy(m)   sdz(m)  sdxy(m)  sdyz(m)  sdzx(m) age(s)  ratio\n"
        f"2176 282582.000 {x} {y} {z} 1 12 0.01 0.02 0.03 0 0 0 0.0 5.0\n"
    )
    tb = read_pos(p)
    assert tb.t_s[0] == 2176 * 604800 + 282582.0 + 18.0  # UTC -> GPST (18 leap seconds)
    np.testing.assert_array_equal(tb.pos_m[0], [x, y, z])
    np.testing.assert_array_equal(tb.std_m[0], [0.01, 0.02, 0.03])


def test_nmea_checksum_and_known_point(tmp_path: Path, shared_data: Path) -> None:
    # The textbook GGA example carries checksum 47.
    body = "GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,"
    assert nmea_checksum(body) == "47"
    tv = json.loads((shared_data / "testvectors" / "testvectors.json").read_text())
    c = tv["coord_ecef2pos"]
    t = gpst_from_calendar(2017, 1, 1, 0, 0, 18.0)  # = 2017-01-01 00:00:00 UTC
    s = gga_sentence(t, c["ecef"], "fixed", 12)
    core, cs = s[1:].split("*")
    assert nmea_checksum(core) == cs
    f = core.split(",")
    assert f[0] == "GPGGA" and f[1] == "000000.00"
    lat = int(f[2][:2]) + float(f[2][2:]) / 60.0
    lon = int(f[4][:3]) + float(f[4][3:]) / 60.0
    assert (f[3], f[5]) == ("N", "E")
    assert lat == pytest.approx(c["lat_deg"], abs=1e-8)
    assert lon == pytest.approx(c["lon_deg"], abs=1e-8)
    assert float(f[9]) == pytest.approx(c["h_m"], abs=1e-4)
    assert f[6] == "4" and f[7] == "12"
    # Southern / western hemisphere and file output.
    p_sw = geodetic2ecef(np.radians(-33.5), np.radians(-70.25), 500.0)
    s2 = gga_sentence(t, p_sw, "float", 7).split(",")
    assert s2[2:6] == ["3330.0000000", "S", "07015.0000000", "W"] and s2[6] == "5"
    sols = [Solution(t_s=t + i, pos_m=np.array(c["ecef"]), cov_m2=np.eye(3), status=st)
            for i, st in enumerate(["single", "dgnss", "none"])]  # fmt: skip
    path = tmp_path / "o.nmea"
    write_nmea(sols, path)
    raw = path.read_bytes().decode()
    lines = raw.split("\r\n")
    assert lines[-1] == "" and len(lines) == 3
    assert [ln.split(",")[6] for ln in lines[:2]] == ["1", "2"]
    assert lines[1].split(",")[1] == "000001.00"


@pytest.mark.parametrize("vel", [False, True])
def test_csv_round_trip(tmp_path: Path, vel: bool) -> None:
    sols = random_solutions(np.random.default_rng(3), 25, vel=vel)
    path = tmp_path / "s.csv"
    write_solution_csv(sols, path)
    header = path.read_text().splitlines()[0]
    assert header.endswith("n_amb,vx,vy,vz" if vel else "n_amb")
    tb = read_solution_csv(path)
    np.testing.assert_array_equal(tb.t_s, [s.t_s for s in sols])
    np.testing.assert_array_equal(tb.pos_m, [s.pos_m for s in sols])
    np.testing.assert_array_equal(tb.std_m, [np.sqrt(np.diag(s.cov_m2)) for s in sols])
    assert tb.status.tolist() == [s.status for s in sols]
    np.testing.assert_array_equal(tb.ratio, [s.ratio for s in sols])
    assert tb.n_amb.tolist() == [s.n_amb for s in sols]
    if vel:
        assert tb.vel_m_s is not None
        assert np.isnan(tb.vel_m_s[0]).all()
        np.testing.assert_array_equal(tb.vel_m_s[1], sols[1].vel_m_s)
    else:
        assert tb.vel_m_s is None


def test_csv_reader_errors(tmp_path: Path) -> None:
    p = tmp_path / "b.csv"
    p.write_text("time,x,y\n1,2,3\n")
    with pytest.raises(InputError, match="header") as ei:
        read_solution_csv(p)
    assert ei.value.line == 1
    p.write_text("time,x,y,z,sx,sy,sz,status,n_used,ratio,n_fixed,n_amb\n"
                 "1,2,3,4,0,0,0,fixed,5,nan,1,2\n1,2,oops,4,0,0,0,fixed,5,nan,1,2\n")  # fmt: skip
    with pytest.raises(InputError, match="'y'") as ei:
        read_solution_csv(p)
    assert ei.value.line == 3
    with pytest.raises(InputError, match="cannot read"):
        read_solution_csv(tmp_path / "missing.csv")


def test_diagnostics_round_trip_and_pivot(tmp_path: Path) -> None:
    rows: list[object] = [
        (10.0, "PL1-PL6", 0.1, 0.05, 0.5, 1.2, 1.0, 1),
        (10.0, "PL4-PL6", 9.0, 8.0, 12.0, 9.5, math.inf, 3),
        {
            "time": 10.5,
            "dd": "PL1-PL6",
            "residual": -0.2,
            "dv": 3.0,
            "factor": 2.5,
            "situation": 2,
        },  # fmt: skip
    ]
    path = tmp_path / "d.csv"
    write_diagnostics_csv(rows, path)  # type: ignore[arg-type]
    assert path.read_text().splitlines()[0] == ",".join(DIAG_COLUMNS)
    d = read_diagnostics_csv(path)
    assert d.dd.tolist() == ["PL1-PL6", "PL4-PL6", "PL1-PL6"]
    assert d.situation.tolist() == [1, 3, 2]
    assert math.isinf(d.factor[1]) and math.isnan(d.innovation[2])
    ep, labels, dv = d.pivot("dv")
    np.testing.assert_array_equal(ep, [10.0, 10.5])
    assert labels == ["PL1-PL6", "PL4-PL6"]
    np.testing.assert_array_equal(dv, [[1.2, 9.5], [3.0, np.nan]])
    with pytest.raises(InputError):
        write_diagnostics_csv([(1.0, "a,b", 0, 0, 0, 0, 0, 1)], tmp_path / "e.csv")
