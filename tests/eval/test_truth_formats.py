"""Truth files in foreign formats: GSDC ground truth, NMEA GGA, ``time,lat,lon,h`` CSV, short .pos."""

from __future__ import annotations

import datetime as dt
import re
from functools import reduce
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from robustrtk.cli.compare import compare
from robustrtk.core import InputError
from robustrtk.eval.truth import read_truth_file
from robustrtk.geometry.frames import ecef2enu_deg, ecef2geodetic, geodetic2ecef_deg
from robustrtk.timeutil import gpst_from_calendar

PIXEL = "gsdc2021_mtv1_pixel5_phone/Pixel5"
GALWAY_S1 = "galway_m8p_l1_lowcost/s1_static"
GPS_EPOCH = dt.datetime(1980, 1, 6, tzinfo=dt.UTC)


def _nmea(body: str) -> str:
    """``$body*CS`` with the XOR checksum of the characters between ``$`` and ``*``."""
    cs = reduce(lambda a, c: a ^ ord(c), body, 0)
    return f"${body}*{cs:02X}"


def _gga(hhmmss: str, lat: str, ns: str, lon: str, ew: str, q: int, alt: float, sep: float) -> str:
    return _nmea(f"GPGGA,{hhmmss},{lat},{ns},{lon},{ew},{q},10,0.9,{alt:.1f},M,{sep:.1f},M,,")


def test_gsdc_2021_ground_truth_is_gps_milliseconds(shared_data: Path) -> None:
    path = shared_data / PIXEL / "ground_truth.csv"
    truth = read_truth_file(path)
    raw = np.genfromtxt(path, delimiter=",", skip_header=1, usecols=(2, 3, 4, 5))
    assert truth.kind == "gsdc" and truth.ecef and truth.t_s is not None
    assert truth.t_s.shape == (raw.shape[0],)
    np.testing.assert_allclose(truth.t_s, raw[:, 0] / 1000.0, rtol=0, atol=1e-9)
    want = geodetic2ecef_deg(raw[:, 1], raw[:, 2], raw[:, 3]).reshape(-1, 3)
    np.testing.assert_allclose(truth.pos_m, want, rtol=0, atol=1e-6)


def test_gsdc_2022_unix_milliseconds_become_gpst(tmp_path: Path) -> None:
    """UnixTimeMillis is UTC: GPST = UTC + 18 s in 2021 (a reference from the standard library)."""
    path = tmp_path / "ground_truth.csv"
    path.write_text(
        "MessageType,Provider,LatitudeDegrees,LongitudeDegrees,AltitudeMeters,SpeedMps,AccuracyMeters,"
        "BearingDegrees,UnixTimeMillis\n"
        "Fix,GT,37.395817,-122.102916,-4.488,0.0014,0.1,118.02,1619735725999\n"
        "Fix,GT,37.3958171,-122.102916,-4.488,0.0019,0.1,118.01,1619735726999\n"
    )
    truth = read_truth_file(path)
    utc = dt.datetime.fromtimestamp(1619735725.999, tz=dt.UTC)
    want = (utc - GPS_EPOCH).total_seconds() + 18.0
    assert truth.kind == "gsdc" and truth.t_s is not None
    assert truth.t_s[0] == pytest.approx(want, abs=1e-6)
    assert truth.t_s[1] - truth.t_s[0] == pytest.approx(1.0, abs=1e-9)
    lat, lon, h = ecef2geodetic(truth.pos_m[0])
    assert np.degrees(lat) == pytest.approx(37.395817, abs=1e-9)
    assert np.degrees(lon) == pytest.approx(-122.102916, abs=1e-9)
    assert h == pytest.approx(-4.488, abs=1e-4)


def test_gsdc_row_too_short_names_file_and_line(tmp_path: Path) -> None:
    path = tmp_path / "ground_truth.csv"
    path.write_text(
        "collectionName,phoneName,millisSinceGpsEpoch,latDeg,lngDeg,heightAboveWgs84EllipsoidM\n"
        "a,b,1303683562430,37.39\n"
    )
    with pytest.raises(InputError, match=r"ground_truth\.csv:2: expected at least 6 fields"):
        read_truth_file(path)


def test_nmea_gga_with_rmc_date_bad_checksum_and_invalid_fix(tmp_path: Path) -> None:
    lines = [
        _nmea("GPRMC,235959.00,A,5316.82807,N,00903.46967,W,0.0,0.0,041018,,,A"),
        _gga("235959.00", "5316.82807", "N", "00903.46967", "W", 4, 11.8, 56.0),
        _gga("000000.00", "5316.82807", "N", "00903.46967", "W", 0, 11.8, 56.0),  # invalid fix
        _gga("000001.00", "5316.82807", "N", "00903.46967", "W", 1, 12.8, 56.0)[:-2] + "00",  # bad checksum
        _nmea("GPRMC,000002.00,A,5316.82807,N,00903.46967,W,0.0,0.0,051018,,,A"),
        _gga("000002.00", "5316.82900", "N", "00903.46900", "W", 2, 13.0, 56.0),
    ]
    path = tmp_path / "fixes.nmea"
    path.write_text("\n".join(lines) + "\n")
    truth = read_truth_file(path)
    assert truth.kind == "nmea" and not truth.utc_time_of_day and truth.t_s is not None
    want0 = gpst_from_calendar(2018, 10, 4, 23, 59, 59.0) + 18.0
    np.testing.assert_allclose(truth.t_s, [want0, want0 + 3.0], rtol=0, atol=1e-6)
    lat = 53.0 + 16.82807 / 60.0
    lon = -(9.0 + 3.46967 / 60.0)
    np.testing.assert_allclose(truth.pos_m[0], geodetic2ecef_deg(lat, lon, 11.8 + 56.0).reshape(3), atol=1e-6)


def test_nmea_gga_without_date_is_anchored_to_the_solutions_day(tmp_path: Path) -> None:
    path = tmp_path / "gga_only.nmea"
    path.write_text(
        "\n".join(
            [
                _gga("235959.00", "5316.82807", "N", "00903.46967", "W", 1, 11.8, 56.0),
                _gga("000000.00", "5316.82807", "N", "00903.46967", "W", 1, 11.8, 56.0),
            ]
        )
    )
    truth = read_truth_file(path)
    assert truth.utc_time_of_day
    sol_t = np.array([gpst_from_calendar(2018, 10, 4, 23, 59, 59.0) + 18.0 + 0.01])
    want0 = gpst_from_calendar(2018, 10, 4, 23, 59, 59.0) + 18.0
    np.testing.assert_allclose(truth.anchored_t_s(sol_t), [want0, want0 + 1.0], rtol=0, atol=1e-6)
    # a solution epoch that matches gets the fix's error: zero here
    err = truth.enu_errors(sol_t, truth.pos_m[:1])
    np.testing.assert_allclose(err, 0.0, atol=1e-6)


def test_nmea_gga_of_the_m8p_rover_agrees_with_its_surveyed_position(shared_data: Path) -> None:
    """The chip's own fixes of a static rover lie near its surveyed position in all three axes
    (a wrong hemisphere sign or a missing geoid separation would be metres to km off)."""
    text = (shared_data / "galway_m8p_l1_lowcost/truth.txt").read_text()
    m = re.search(r"^ROVER_S1_STATIC\s+(\S+)\s+(\S+)\s+(\S+)", text, re.M)
    assert m is not None
    ref = np.array([float(v) for v in m.groups()])
    truth = read_truth_file(shared_data / GALWAY_S1 / "rover-20181004-1237_GGA.nmea")
    assert truth.t_s is not None and truth.t_s.size > 1000
    lat, lon, h = ecef2geodetic(ref)
    enu = ecef2enu_deg(truth.pos_m, float(np.degrees(lat)), float(np.degrees(lon)), float(h))
    med = np.median(enu, axis=0)
    assert np.hypot(med[0], med[1]) < 3.0 and abs(med[2]) < 5.0


def test_time_lat_lon_h_csv(tmp_path: Path) -> None:
    path = tmp_path / "truth.csv"
    path.write_text("time,lat,lon,h\n100.0,53.28,-9.06,67.8\n101.0,53.28001,-9.06,67.9\n")
    truth = read_truth_file(path)
    assert truth.t_s is not None
    np.testing.assert_allclose(truth.t_s, [100.0, 101.0])
    np.testing.assert_allclose(truth.pos_m[1], geodetic2ecef_deg(53.28001, -9.06, 67.9).reshape(3), atol=1e-6)
    path.write_text("time,lat,lon,h\n100.0,153.28,-9.06,67.8\n")
    with pytest.raises(InputError, match=r"truth\.csv:2: expected latitude -90\.\.90"):
        read_truth_file(path)


def test_short_pos_truth_without_sigma_columns(tmp_path: Path) -> None:
    path = tmp_path / "short.pos"
    path.write_text(
        "%  GPST                  latitude(deg) longitude(deg)  height(m)   Q  ns\n"
        "2018/10/04 12:37:51.000   53.280467833   -9.057827833    67.8000   1  12\n"
        "2018/10/04 12:37:52.000   53.280467834   -9.057827834    67.8100   2  12\n"
    )
    truth = read_truth_file(path)
    assert truth.t_s is not None and truth.t_s.shape == (2,)
    assert truth.t_s[1] - truth.t_s[0] == pytest.approx(1.0)
    np.testing.assert_allclose(
        truth.pos_m[0], geodetic2ecef_deg(53.280467833, -9.057827833, 67.8).reshape(3), atol=1e-4
    )


def test_compare_prints_the_gsdc_score_of_a_phone_run(shared_data: Path, tmp_path: Path) -> None:
    """The score printed for a GSDC truth is the mean of the horizontal p50 and p95 computed
    independently here from the same solution and the CSV."""
    from robustrtk.geometry.ephemeris import EphemerisSource
    from robustrtk.io.rinex_nav import read_rinex_nav
    from robustrtk.io.rinex_obs import read_rinex_obs
    from robustrtk.io.solution import write_pos
    from robustrtk.pipeline.spp import solve_spp_kalman

    b = read_rinex_obs(shared_data / PIXEL / "supplemental/Pixel5_GnssLog.21o")
    eph = EphemerisSource(read_rinex_nav(shared_data / PIXEL / "supplemental/hour1180.21n"))
    sols = solve_spp_kalman(b, eph)
    pos = tmp_path / "phone.pos"
    write_pos([s.to_solution() for s in sols], pos)
    gt_path = shared_data / PIXEL / "ground_truth.csv"
    res = CliRunner().invoke(compare, [str(pos), "--truth", str(gt_path)])
    assert res.exit_code == 0, res.output
    m = re.search(r"GSDC score phone: (\d+\.\d+) m", res.output)
    assert m is not None, res.output
    gt = np.genfromtxt(gt_path, delimiter=",", skip_header=1, usecols=(2, 3, 4, 5))
    tg = gt[:, 0] / 1000.0
    errs = []
    for s in sols:
        j = int(np.argmin(np.abs(tg - s.t_s)))
        if abs(tg[j] - s.t_s) < 0.05 and s.status != "none" and np.all(np.isfinite(s.pos_ecef_m)):
            e = ecef2enu_deg(s.pos_ecef_m, gt[j, 1], gt[j, 2], gt[j, 3])
            errs.append(np.hypot(e[0], e[1]))
    p50, p95 = np.percentile(errs, [50, 95])
    # the .pos rounds latitude/longitude to 1e-9 deg (≤ 0.1 mm): the score agrees to 1 cm
    assert float(m.group(1)) == pytest.approx(0.5 * (p50 + p95), abs=0.01)


def test_evaluate_reports_enu_errors_against_a_geodetic_truth(tmp_path: Path) -> None:
    from robustrtk.cli.main import main
    from robustrtk.core import Solution
    from robustrtk.geometry.frames import enu2ecef_deg
    from robustrtk.io.solution import write_pos

    lat, lon, h = 53.28, -9.06, 60.0
    t0 = gpst_from_calendar(2018, 10, 4, 12, 0, 0.0)
    offsets = np.array([[1.0, -2.0, 3.0], [-1.0, 2.0, -3.0]])
    sols = [
        Solution(
            t_s=t0 + k,
            pos_m=enu2ecef_deg(off, lat, lon, h).reshape(3),
            cov_m2=np.eye(3) * 1e-4,
            status="float",
        )
        for k, off in enumerate(offsets)
    ]
    pos = tmp_path / "sol.pos"
    write_pos(sols, pos)
    truth = tmp_path / "truth.txt"
    truth.write_text(f"rover_llh {lat} {lon} {h}\n")
    res = CliRunner().invoke(main, ["evaluate", str(pos), "--truth", str(truth)])
    assert res.exit_code == 0, res.output
    header, _, row = res.output.splitlines()[:3]
    assert "mean|E| m" in header and "mean|U| m" in header
    vals = [float(v) for v in row.split()[2:5]]
    np.testing.assert_allclose(vals, [1.0, 2.0, 3.0], atol=1e-3)


def test_truth_fixed_keeps_only_the_fixed_epochs(tmp_path: Path) -> None:
    """``--truth-fixed``: GGA quality 4 only (5 = RTK float is not), .pos Q = 1 only; a truth
    with no quality is refused, not silently used whole."""
    gga = tmp_path / "chip.nmea"
    gga.write_text(
        "\n".join(
            [
                _nmea("GPRMC,120000.00,A,5316.82807,N,00903.46967,W,0.0,0.0,041018,,,A"),
                _gga("120000.00", "5316.82807", "N", "00903.46967", "W", 4, 11.8, 56.0),
                _gga("120001.00", "5316.82807", "N", "00903.46967", "W", 5, 11.8, 56.0),
                _gga("120002.00", "5316.82807", "N", "00903.46967", "W", 1, 11.8, 56.0),
                _gga("120003.00", "5316.82807", "N", "00903.46967", "W", 4, 11.8, 56.0),
            ]
        )
        + "\n"
    )
    every, fixed = read_truth_file(gga), read_truth_file(gga, fixed_only=True)
    assert every.t_s is not None and fixed.t_s is not None
    assert every.t_s.size == 4
    np.testing.assert_allclose(fixed.t_s - every.t_s[0], [0.0, 3.0])
    pos = tmp_path / "ref.pos"
    pos.write_text(
        "%  GPST                  latitude(deg) longitude(deg)  height(m)   Q  ns\n"
        "2018/10/04 12:37:51.000   53.280467833   -9.057827833    67.8000   2  12\n"
        "2018/10/04 12:37:52.000   53.280467834   -9.057827834    67.8100   1  12\n"
        "2018/10/04 12:37:53.000   53.280467834   -9.057827834    67.8100   5  12\n"
    )
    t = read_truth_file(pos, fixed_only=True)
    assert t.t_s is not None and t.t_s.size == 1
    assert t.t_s[0] == pytest.approx(read_truth_file(pos).t_s[1])  # type: ignore[index]
    point = tmp_path / "point.txt"
    point.write_text("rover_llh 53.28 -9.06 60.0\n")
    with pytest.raises(InputError, match="no solution quality"):
        read_truth_file(point, fixed_only=True)
    res = CliRunner().invoke(compare, [str(pos), "--truth", "1,2,3", "--truth-fixed"])
    assert res.exit_code == 2 and "--truth-fixed" in res.output
