"""RINEX 3.04 writer: round trip through our reader, RTKLIB reads it."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from robustrtk.core import empty_batch
from robustrtk.geometry.frames import ecef2enu_deg
from robustrtk.io.readers import read_observations
from robustrtk.io.rinex_obs import read_rinex_obs
from robustrtk.io.rinex_write import obs_types_by_system, write_rinex_obs

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / ".." / "shared" / "data"
LOG2016 = DATA / "gnsslogger_static_2016"
FIX = DATA / "android_parser_fixtures"
RNX2RTKP = ROOT / ".." / "shared" / "tools" / "rtklib-demo5" / "rnx2rtkp"
TRUTH = (37.422578, -122.081678, -28.0)
# RINEX F14.3 resolution: half a unit of the third decimal
RES = 0.0005 + 1e-9


def _assert_round_trip(b, r) -> None:  # type: ignore[no-untyped-def]
    assert r.tx_ids == tuple(
        t
        for t in b.tx_ids
        if np.isfinite(b.code_m[:, b.tx_ids.index(t)]).any()
        or np.isfinite(b.cn0_dbhz[:, b.tx_ids.index(t)]).any()
    )
    keep = [b.tx_ids.index(t) for t in r.tx_ids]
    ks = [b.signals.index(s) for s in r.signals]
    rows = np.flatnonzero(
        np.isfinite(b.code_m).any(axis=(1, 2))
        | np.isfinite(b.phase_cyc).any(axis=(1, 2))
        | np.isfinite(b.cn0_dbhz).any(axis=(1, 2))
    )
    np.testing.assert_allclose(r.t_s, b.t_s[rows], rtol=0, atol=1e-7)
    for name in ("code_m", "phase_cyc", "doppler_hz", "cn0_dbhz"):
        x = getattr(b, name)[np.ix_(rows, keep, ks)]
        y = getattr(r, name)
        np.testing.assert_array_equal(np.isfinite(x), np.isfinite(y), err_msg=name)
        assert np.nanmax(np.abs(x - y)) <= RES, name
    lli = b.lli[np.ix_(rows, keep, ks)]
    lli = np.where(np.isfinite(b.phase_cyc[np.ix_(rows, keep, ks)]), lli, 0)
    np.testing.assert_array_equal(lli, r.lli)
    np.testing.assert_allclose(r.wavelength_m, b.wavelength_m[np.ix_(keep, ks)], equal_nan=True)


@pytest.mark.skipif(not LOG2016.is_dir(), reason="../shared/data/gnsslogger_static_2016 absent")
def test_round_trip_2016_log(tmp_path: Path) -> None:
    b = read_observations(LOG2016 / "pseudoranges_log_2016_08_22_14_45_50.txt")
    out = tmp_path / "phone.obs"
    stats = write_rinex_obs(b, out)
    assert stats["epochs"] == 207 and stats["values_not_fitting"] == 0
    r = read_rinex_obs(out)
    assert r.meta["rinex_version"] == pytest.approx(3.04)
    assert r.meta["obs_types"]["G"] == ["C1C", "L1C", "D1C", "S1C"]  # type: ignore[index]
    assert r.meta["obs_types"]["C"] == ["C2I", "L2I", "D2I", "S2I"]  # type: ignore[index]
    _assert_round_trip(b, r)


@pytest.mark.skipif(not FIX.is_dir(), reason="../shared/data/android_parser_fixtures absent")
def test_round_trip_glonass_and_two_bands(tmp_path: Path) -> None:
    b = read_observations(FIX / "google_decimeter_2021" / "Pixel4_GnssLog.txt")
    assert "R" in b.system and "5Q" in b.signals
    out = tmp_path / "p4.obs"
    write_rinex_obs(b, out)
    r = read_rinex_obs(out)
    assert r.meta["glonass_channels"] == b.meta["glonass_channels"]
    _assert_round_trip(b, r)


def test_synthetic_layout(tmp_path: Path) -> None:
    b = empty_batch(np.array([1.4e9, 1.4e9 + 1]), ("G01", "E02"), ("G", "E"), ("1C", "5Q"))
    b.code_m[0, 0, 0] = 2.1e7
    b.phase_cyc[0, 0, 0] = -123.4564
    b.lli[0, 0, 0] = 3
    b.cn0_dbhz[1, 1, 1] = 30.0
    b.doppler_hz[1, 1, 1] = 1e11  # does not fit F14.3
    assert [t for t, _, _ in obs_types_by_system(b)["G"]] == ["C1C", "L1C"]
    stats = write_rinex_obs(b, tmp_path / "s.obs")
    assert stats == {"epochs": 2, "records": 2, "values": 3, "values_not_fitting": 1}
    text = (tmp_path / "s.obs").read_text().splitlines()
    assert all(len(ln) <= 80 for ln in text)
    assert any(ln.startswith("E    2 D5Q S5Q") for ln in text)
    r = read_rinex_obs(tmp_path / "s.obs")
    assert r.lli[0, 0, 0] == 3 and r.phase_cyc[0, 0, 0] == pytest.approx(-123.456)
    assert r.cn0_dbhz[1, 1, 1] == 30.0 and np.isnan(r.doppler_hz[1, 1, 1])


def _rtklib_errors(tmp_path: Path, log: str, nav: str) -> np.ndarray:
    b = read_observations(LOG2016 / log)
    obs = tmp_path / "phone.obs"
    write_rinex_obs(b, obs)
    pos = tmp_path / "out.pos"
    subprocess.run(
        [str(RNX2RTKP), "-p", "0", "-o", str(pos), str(obs), str(LOG2016 / nav)],
        check=True,
        capture_output=True,
        timeout=120,
    )
    rows = [ln.split() for ln in pos.read_text().splitlines() if ln and not ln.startswith("%")]
    llh = np.array([[float(x[2]), float(x[3]), float(x[4])] for x in rows])
    from robustrtk.geometry.frames import geodetic2ecef_deg

    ecef = np.asarray(geodetic2ecef_deg(llh[:, 0], llh[:, 1], llh[:, 2]))
    return np.asarray(ecef2enu_deg(ecef, *TRUTH))


@pytest.mark.skipif(
    not RNX2RTKP.is_file() or shutil.which(str(RNX2RTKP)) is None, reason="RTKLIB demo5 rnx2rtkp absent"
)
@pytest.mark.skipif(not LOG2016.is_dir(), reason="../shared/data/gnsslogger_static_2016 absent")
@pytest.mark.parametrize(
    ("log", "nav", "n_min"),
    [
        ("pseudoranges_log_2016_08_22_14_45_50.txt", "hour2350.16n", 190),
        ("pseudoranges_log_2016_06_30_21_26_07.txt", "hour1820.16n", 200),
    ],
)
def test_rtklib_single_point_from_our_rinex(tmp_path: Path, log: str, nav: str, n_min: int) -> None:
    enu = _rtklib_errors(tmp_path, log, nav)
    assert enu.shape[0] >= n_min
    h = np.hypot(enu[:, 0], enu[:, 1])
    assert np.all(h < 50.0) and np.median(h) < 15.0
