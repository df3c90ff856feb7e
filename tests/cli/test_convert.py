"""``robustrtk convert``: GnssLogger log to RINEX 3.04, one-line errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from robustrtk.cli.main import main
from robustrtk.io.readers import read_observations
from robustrtk.io.rinex_obs import read_rinex_obs

DATA = Path(__file__).resolve().parents[2] / ".." / "shared" / "data"
LOG = DATA / "gnsslogger_static_2016" / "pseudoranges_log_2016_08_22_14_45_50.txt"
DEVICE = DATA / "android_parser_fixtures" / "google_decimeter_2022" / "device_gnss.csv"


@pytest.mark.skipif(not LOG.is_file(), reason="../shared/data/gnsslogger_static_2016 absent")
def test_convert_log(tmp_path: Path) -> None:
    out = tmp_path / "phone.obs"
    res = CliRunner().invoke(main, ["convert", str(LOG), "--out", str(out), "--systems", "G"])
    assert res.exit_code == 0, res.output
    assert "207 epochs" in res.output
    r = read_rinex_obs(out)
    b = read_observations(LOG, systems="G")
    assert r.tx_ids == b.tx_ids and set(r.system) == {"G"}
    assert np.nanmax(np.abs(r.code_m - b.code_m)) <= 0.0005 + 1e-9


@pytest.mark.skipif(not DEVICE.is_file(), reason="../shared/data/android_parser_fixtures absent")
def test_convert_device_gnss(tmp_path: Path) -> None:
    out = tmp_path / "d.obs"
    res = CliRunner().invoke(main, ["convert", str(DEVICE), "--out", str(out)])
    assert res.exit_code == 0, res.output
    assert read_rinex_obs(out).signals == ("1C", "2I", "5X")


def test_convert_errors(tmp_path: Path) -> None:
    bad = tmp_path / "bad.txt"
    bad.write_text(
        "# Raw,TimeNanos,FullBiasNanos,Svid,State,ReceivedSvTimeNanos,ConstellationType\nRaw,1,2\n"
    )
    res = CliRunner().invoke(main, ["convert", str(bad), "--out", str(tmp_path / "x.obs")])
    assert res.exit_code == 2
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and f"{bad}:2:" in lines[0] and "fields" in lines[0]
    assert not (tmp_path / "x.obs").exists()
    res = CliRunner().invoke(main, ["convert", str(bad), "--out", str(tmp_path / "no" / "x.obs")])
    assert res.exit_code == 2


GALWAY = DATA / "galway_m8p_l1_lowcost" / "s1_static"


@pytest.mark.skipif(not GALWAY.is_dir(), reason="../shared/data/galway_m8p_l1_lowcost absent")
def test_convert_ubx_and_rtcm3_like_convbin(tmp_path: Path) -> None:
    from robustrtk.io.rinex_nav import read_rinex_nav

    obs, nav = tmp_path / "rover.obs", tmp_path / "rover.nav"
    res = CliRunner().invoke(
        main,
        ["convert", str(GALWAY / "rover-20181004-1237.ubx.gz"), "--out", str(obs), "--nav-out", str(nav)],
    )
    assert res.exit_code == 0, res.output
    assert "1205 epochs" in res.output and "ephemerides G 14, R 8" in res.output
    ours = read_rinex_obs(obs)
    ref = read_rinex_obs(GALWAY / "rover-20181004-1237.obs")
    np.testing.assert_array_equal(ours.meta["t_ns"], ref.meta["t_ns"])  # epoch lines to 100 ns
    assert ours.tx_ids == ref.tx_ids
    for f in ("code_m", "phase_cyc", "doppler_hz", "cn0_dbhz", "lli"):
        np.testing.assert_array_equal(getattr(ours, f), getattr(ref, f), err_msg=f)
    n = read_rinex_nav(nav)
    assert len(n.kepler["G"]) == 14 and len(n.glonass) == 8
    base = tmp_path / "base.obs"
    res = CliRunner().invoke(
        main,
        [
            "convert",
            str(GALWAY / "base-20181004-1236.rtcm3"),
            "--out",
            str(base),
            "--time-ref",
            "2018/10/04 12:00:00",
        ],
    )
    assert res.exit_code == 0, res.output
    b = read_rinex_obs(base)
    assert len(b) == 623 and b.approx_pos_m is not None


def test_convert_raw_options_refused(tmp_path: Path) -> None:
    p = tmp_path / "x.rtcm3"
    p.write_bytes(b"\xd3\x00\x00\x47\xea\x4b" * 3)  # three empty RTCM 3 frames (CRC of 0xD3 0 0)
    res = CliRunner().invoke(main, ["convert", str(p), "--out", str(tmp_path / "o.obs")])
    assert res.exit_code == 2 and "week" in res.output
    res = CliRunner().invoke(
        main, ["convert", str(p), "--out", str(tmp_path / "o.obs"), "--time-ref", "yesterday"]
    )
    assert res.exit_code == 2 and "--time-ref" in res.output
