"""Tests of the RINEX navigation reader."""

from __future__ import annotations

import gzip
import re
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from robustrtk.core import InputError
from robustrtk.io.rinex_nav import read_rinex_nav
from robustrtk.timeutil import gpst_from_calendar

NAV_FILES = [
    "geonet_0759_3040_static_3km/07590920.05n",
    "mosaicx5_static_1m/base.nav",
    "kamakura_kinematic_5km/SEPT2650.21P",
    "gsdc2021_mtv1_pixel5_phone/Pixel5/supplemental/hour1180.21n",
    "gnsslogger_static_2016/hour1820.16n",
    "android_parser_fixtures/rinex/nav/brdc1190.21n",
]


def _scan_counts(path: Path) -> Counter[str]:
    """Independent count of record first lines per system by a plain text scan."""
    lines = path.read_text().splitlines()
    version = float(lines[0][:9])
    body = lines[[i for i, ln in enumerate(lines) if "END OF HEADER" in ln][0] + 1 :]
    counts: Counter[str] = Counter()
    if version >= 3:
        for ln in body:
            m = re.match(r"^([GRECJSI])\d\d \d{4} ", ln)
            if m:
                counts[m.group(1)] += 1
    else:
        system = "R" if lines[0][20] == "G" else "G"
        for ln in body:
            if re.match(r"^[ \d]\d [ \d]\d [ \d]\d [ \d]\d ", ln):
                counts[system] += 1
    return counts


@pytest.mark.parametrize("rel", NAV_FILES)
def test_record_counts_match_text_scan(shared_data: Path, rel: str) -> None:
    path = shared_data / rel
    nav = read_rinex_nav(path)
    expected = _scan_counts(path)
    assert sum(expected.values()) > 0
    for system in "GRECJS":
        assert nav.n_records(system) == expected.get(system, 0), system
    assert sum(nav.skipped.values()) == expected.get("I", 0)
    assert sum(nav.record_counts.values()) == sum(expected.values()) - expected.get("I", 0)


def test_header_values_and_times(shared_data: Path) -> None:
    nav = read_rinex_nav(shared_data / "android_parser_fixtures/rinex/nav/brdc1190.21n")
    np.testing.assert_allclose(nav.ion_gps_alpha, [0.9313e-08, 0.1490e-07, -0.5960e-07, -0.1192e-06])
    np.testing.assert_allclose(nav.ion_gps_beta, [0.8806e05, 0.4915e05, -0.1311e06, -0.3277e06])
    assert nav.leap_s == 18
    g = nav.kepler["G"]
    # first record: G06 2021-04-29 17:59:44, toe 410384 s of week 2155
    assert g.sat_id[0] == "G06"
    assert g.toc_s[0] == gpst_from_calendar(2021, 4, 29, 17, 59, 44.0)
    assert g.toe_s[0] == 2155 * 604800 + 410384.0
    assert g.af0_s[0] == pytest.approx(0.112163834274e-04)
    assert g.sqrt_a_m05[0] == pytest.approx(0.515375577545e04)
    assert g.tgd1_s[0] == pytest.approx(0.419095158577e-08)
    assert g.iodc[0] == 34.0


def test_rinex3_mixed_systems(shared_data: Path) -> None:
    nav = read_rinex_nav(shared_data / "mosaicx5_static_1m/base.nav")
    assert nav.ion_gal is not None and nav.ion_gal.shape == (3,)
    c = nav.kepler["C"]
    # BeiDou epochs are BDT: toc - toe difference is within the hour, and toc is +14 s
    i = int(np.nonzero(c.sat_id == "C01")[0][0])
    assert (c.toc_s[i] - 14.0) % 60.0 == 0.0
    r = nav.glonass
    # first GLONASS record: R01 2024-06-24 08:15:00 UTC, X = -13736.88769531 km
    assert r.sat_id[0] == "R01"
    assert r.toe_s[0] == gpst_from_calendar(2024, 6, 24, 8, 15, 0) + 18.0
    assert r.pos_m[0, 0] == pytest.approx(-13736887.69531)
    channels = nav.glo_channels()
    assert channels["R01"] == 1 and channels["R02"] == -4
    assert all(-7 <= k <= 6 for k in channels.values())
    e = nav.kepler["E"]
    assert set(np.unique(e.code_or_source)) <= {517.0, 258.0, 513.0, 516.0}


def test_gzip_and_multiple_files(shared_data: Path, tmp_path: Path) -> None:
    src = shared_data / "mosaicx5_static_1m/base.nav"
    gz = tmp_path / "base.nav.gz"
    gz.write_bytes(gzip.compress(src.read_bytes()))
    a = read_rinex_nav(src)
    b = read_rinex_nav(gz)
    for s in "GRECJ":
        assert a.n_records(s) == b.n_records(s)
    np.testing.assert_array_equal(a.kepler["E"].m0_rad, b.kepler["E"].m0_rad)
    both = read_rinex_nav([src, shared_data / "kamakura_kinematic_5km/SEPT2650.21P"])
    assert both.n_records("E") == a.n_records("E") + 253


_R2_HEADER = (
    "     2              NAVIGATION DATA                         RINEX VERSION / TYPE\n"
    "    0.9313D-08  0.1490D-07 -0.5960D-07 -0.1192D-06          ION ALPHA           \n"
    "                                                            END OF HEADER       \n"
)
_R2_RECORD = (
    " 6 21  4 29 17 59 44.0 0.112163834274D-04 0.329691829393D-11 0.000000000000D+00\n"
    "    0.340000000000D+02-0.122843750000D+03 0.377408577725D-08 0.291016870089D+00\n"
    "   -0.645034015179D-05 0.225092296023D-02 0.979937613010D-05 0.515375577545D+04\n"
    "    0.410384000000D+06 0.186264514923D-08-0.294573169812D+01-0.186264514923D-08\n"
    "    0.983894919813D+00 0.204593750000D+03-0.983002402270D+00-0.770496379981D-08\n"
    "   -0.197865384745D-09 0.100000000000D+01 0.215500000000D+04 0.000000000000D+00\n"
    "    0.200000000000D+01 0.000000000000D+00 0.419095158577D-08 0.340000000000D+02\n"
    "    0.409092000000D+06 0.400000000000D+01 0.000000000000D+00 0.000000000000D+00\n"
)


def _write(tmp_path: Path, text: str, name: str = "x.21n") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def test_synthetic_good_file(tmp_path: Path) -> None:
    nav = read_rinex_nav(_write(tmp_path, _R2_HEADER + _R2_RECORD + _R2_RECORD))
    assert nav.n_records("G") == 2
    assert nav.kepler["G"].e[1] == pytest.approx(0.225092296023e-02)


def test_malformed_number_names_line(tmp_path: Path) -> None:
    bad = _R2_RECORD.replace("0.225092296023D-02", "0.2250922960x3D-02")
    p = _write(tmp_path, _R2_HEADER + _R2_RECORD + bad)
    with pytest.raises(InputError) as ei:
        read_rinex_nav(p)
    assert ei.value.line == 3 + 8 + 3
    assert str(p) in str(ei.value) and "number" in str(ei.value)


def test_truncated_record(tmp_path: Path) -> None:
    truncated = "".join(_R2_RECORD.splitlines(keepends=True)[:5])
    p = _write(tmp_path, _R2_HEADER + _R2_RECORD + truncated)
    with pytest.raises(InputError) as ei:
        read_rinex_nav(p)
    assert ei.value.line == 12 and "broadcast-orbit lines" in str(ei.value)


def test_bad_epoch_and_header(tmp_path: Path) -> None:
    bad = _R2_RECORD.replace(" 6 21  4 29 17", " 6 21 13 29 17")
    with pytest.raises(InputError, match="epoch") as ei:
        read_rinex_nav(_write(tmp_path, _R2_HEADER + bad))
    assert ei.value.line == 4
    with pytest.raises(InputError, match="END OF HEADER"):
        read_rinex_nav(_write(tmp_path, _R2_HEADER.replace("END OF HEADER", "COMMENT      ")))
    with pytest.raises(InputError, match="RINEX VERSION"):
        read_rinex_nav(_write(tmp_path, _R2_RECORD))
    obs = _R2_HEADER.replace("NAVIGATION DATA", "OBSERVATION DATA")
    with pytest.raises(InputError, match="file type"):
        read_rinex_nav(_write(tmp_path, obs + _R2_RECORD))
    with pytest.raises(InputError, match="cannot read"):
        read_rinex_nav(tmp_path / "missing.nav")


def test_rinex3_unknown_system_and_sbas_read(tmp_path: Path) -> None:
    hdr = (
        "     3.04           N: GNSS NAV DATA    M: MIXED            RINEX VERSION / TYPE\n"
        "                                                            END OF HEADER       \n"
    )
    sbas = (
        "S27 2024 06 24 10 00 00 0.000000000000E+00 0.000000000000E+00 0.000000000000E+00\n"
        "     1.000000000000E+04 0.000000000000E+00 0.000000000000E+00 0.000000000000E+00\n"
        "     1.000000000000E+04 0.000000000000E+00 0.000000000000E+00 0.000000000000E+00\n"
        "     1.000000000000E+04 0.000000000000E+00 0.000000000000E+00 0.000000000000E+00\n"
    )
    nav = read_rinex_nav(_write(tmp_path, hdr + sbas, "a.rnx"))
    assert nav.skipped == {} and nav.n_records("G") == 0
    assert nav.record_counts == {"EPH S SBAS": 1}
    np.testing.assert_array_equal(nav.sbas.pos_m, [[1e7, 1e7, 1e7]])
    assert nav.sbas.toe_s[0] == gpst_from_calendar(2024, 6, 24, 10, 0, 0)
    with pytest.raises(InputError, match="unknown satellite system") as ei:
        read_rinex_nav(_write(tmp_path, hdr + sbas + sbas.replace("S27", "X27"), "b.rnx"))
    assert ei.value.line == 7


def test_time_scales_used_by_the_reader() -> None:
    from robustrtk.timeutil import (
        bdt2gpst,
        calendar_from_gpst,
        glot2gpst,
        gps_week_tow,
        gpst2utc,
        leap_seconds_at_gpst,
        utc2gpst,
    )

    # GPS week 2155, tow 410384 s is 2021-04-29 17:59:44 (first record of brdc1190.21n)
    week, tow = gps_week_tow(gpst_from_calendar(2021, 4, 29, 17, 59, 44.0))
    assert (int(week), float(tow)) == (2155, 410384.0)
    assert calendar_from_gpst(gpst_from_calendar(2016, 2, 29, 23, 59, 59.5)) == (2016, 2, 29, 23, 59, 59.5)
    # leap seconds: 17 s during 2016, 18 s from 2017-01-01 UTC
    assert float(utc2gpst(gpst_from_calendar(2016, 12, 31, 23, 59, 59))) == gpst_from_calendar(
        2017, 1, 1, 0, 0, 16
    )
    assert float(utc2gpst(gpst_from_calendar(2017, 1, 1))) == gpst_from_calendar(2017, 1, 1, 0, 0, 18)
    assert float(leap_seconds_at_gpst(gpst_from_calendar(1980, 1, 6))) == 0.0
    t = gpst_from_calendar(2024, 6, 24, 8, 20, 0)
    assert float(gpst2utc(utc2gpst(t))) == t
    # BDT origin 2006-01-01 00:00:00 BDT is GPST week 1356 + 14 s
    assert float(bdt2gpst(gpst_from_calendar(2006, 1, 1))) == 1356 * 604800.0 + 14.0
    # GLONASS time is UTC + 3 h
    assert float(glot2gpst(gpst_from_calendar(2024, 6, 24, 11, 15, 0))) == gpst_from_calendar(
        2024, 6, 24, 8, 15, 18
    )
