"""galway u-blox M8P L1 GPS + GLONASS with the default RTK systems (GLONASS among them, its
ambiguities float unless both receivers are known to be of one make); data in
``../shared/data/galway_m8p_l1_lowcost`` (skipped without it).

RTKLIB demo5 fix-and-hold, L1 GPS + GLONASS with GLONASS AR on, on the same files: s1 81.3 %
(M8P base, RINEX from its RTCM 3), 93.2 % (from its UBX), 60.5 % (CORS GLW1) of the 1205 rover
epochs, every one solved; s3 783 fixed epochs, 45 of its 305 fixes common with the chip's own
more than 10 cm from them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from robustrtk.geometry.frames import ecef2enu_rotation, ecef2geodetic
from robustrtk.io.rinex_obs import read_rinex_obs
from robustrtk.pipeline.gnss_inputs import select_time_window
from robustrtk.pipeline.rtk_gnss import RTK_SYSTEMS, rtk_gnss_config, solve_rtk

ROVER_TRUTH = np.array([3774088.6834, -601663.0382, 5089318.2298])
BASE_S1 = np.array([3774088.9004, -601662.8325, 5089318.0783])
GLW1 = np.array([3774050.9626, -601852.6734, 5089350.3688])
ARP_S3 = np.array([3774696.5547, -596647.9083, 5089485.6511])
BASES = {
    "rtcm": ("s1_static/base-20181004-1236_rtcm.obs", BASE_S1, 0.813),
    "ubx": ("s1_static/base-20181004-1236_ubx.obs", BASE_S1, 0.932),
    "glw1": ("cors_glw1/glw1277m.18o", GLW1, 0.605),
}


@pytest.fixture(scope="module")
def galway(shared_data: Path) -> Path:
    d = shared_data / "galway_m8p_l1_lowcost"
    if not (d / "cors_glw1" / "glw1277m.18o").is_file():
        pytest.skip(f"galway_m8p_l1_lowcost not found in {shared_data}")
    return d


def _horizontal_m(pos_m: np.ndarray, ref_m: np.ndarray) -> float:
    lat, lon, _ = ecef2geodetic(ref_m)
    rot = ecef2enu_rotation(float(lat), float(lon))
    return float(np.hypot(*(rot @ (pos_m - ref_m))[:2]))


def test_glonass_among_default_systems() -> None:
    assert "R" in RTK_SYSTEMS and set("GECJ") <= set(RTK_SYSTEMS)


def test_epoch_without_phase_gets_a_code_solution(galway: Path) -> None:
    """s1 rover epoch 12:54:53.992 carries code and Doppler but no carrier phase: it is solved
    from the DD code (status ``code``, RTKLIB's Q = 4), between phase solutions."""
    s1 = galway / "s1_static"
    cfg = rtk_gnss_config(freqs="L1", time_start="2018/10/04 12:54:40", time_end="2018/10/04 12:55:05")
    rover = select_time_window(read_rinex_obs(s1 / "rover-20181004-1237.obs"), cfg.gnss)
    nav = s1 / "base-20181004-1236_ubx.nav"
    res = solve_rtk(rover, s1 / "base-20181004-1236_rtcm.obs", nav, BASE_S1, cfg)
    with_sats = int(np.count_nonzero(np.isfinite(rover.code_m).any(axis=(1, 2))))
    assert len(res.solutions) == with_sats
    by_sod = {round(s.t_s % 86400): s for s in res.solutions}
    sod_gap = 12 * 3600 + 54 * 60 + 54  # 12:54:53.992
    gap = by_sod[sod_gap]
    assert gap.status == "code" and gap.n_used >= 3
    assert _horizontal_m(gap.pos_m, ROVER_TRUTH) < 3.0 * np.sqrt(np.trace(gap.cov_m2[:2, :2])) + 0.5
    assert all(s.status in ("fixed", "partial", "float") for t, s in by_sod.items() if t != sod_gap)


@pytest.mark.slow
@pytest.mark.parametrize("base", sorted(BASES))
def test_s1_default_systems_fix_at_least_rtklib(galway: Path, base: str) -> None:
    """Default systems (GLONASS float: convbin leaves the u-blox REC # / TYPE empty, GLW1 is
    a Leica): every rover epoch solved, fix rate at least RTKLIB's on the same base, no fixed
    epoch more than 10 cm from the truth."""
    path, pos, rtklib = BASES[base]
    s1 = galway / "s1_static"
    res = solve_rtk(
        s1 / "rover-20181004-1237.obs", galway / path, s1 / "base-20181004-1236_ubx.nav", pos,
        rtk_gnss_config(freqs="L1"),
    )  # fmt: skip
    assert res.info["systems"] == RTK_SYSTEMS and res.info["glonass_ar"] == "off"
    assert len(res.solutions) == 1205 and all(s.status != "none" for s in res.solutions)
    fixed = [s for s in res.solutions if s.status in ("fixed", "partial")]
    assert len(fixed) >= rtklib * 1205
    assert max(np.linalg.norm(s.pos_m - ROVER_TRUTH) for s in fixed) <= 0.10


@pytest.mark.slow
def test_s3_default_systems_fix_more_than_rtklib_and_agree_with_the_chip(galway: Path) -> None:
    s3 = galway / "s3_kinematic"
    res = solve_rtk(
        s3 / "rover-20181009-1221.obs", s3 / "base-20181009-1220_rtcm.obs", s3 / "base-20181009-1220_ubx.nav",
        ARP_S3, rtk_gnss_config(freqs="L1"),
    )  # fmt: skip
    fixed = [s for s in res.solutions if s.status in ("fixed", "partial")]
    assert len(fixed) >= 783
    chip: dict[int, np.ndarray] = {}
    for line in (s3 / "rover-20181009-1221_GGA.nmea").read_text().splitlines():
        f = line.split(",")
        if len(f) > 9 and f[6] == "4":  # the chip's own RTK fixes, UTC (GPST = UTC + 18 s)
            sod = round(int(f[1][:2]) * 3600 + int(f[1][2:4]) * 60 + float(f[1][4:]) + 18)
            lat = np.radians(int(f[2][:2]) + float(f[2][2:]) / 60)
            lon = -np.radians(int(f[4][:3]) + float(f[4][3:]) / 60)
            chip[sod] = np.array([lat, lon])
    d = []
    for s in fixed:
        ref = chip.get(round(s.t_s % 86400))
        if ref is not None:
            la, lo, _ = ecef2geodetic(s.pos_m)
            dn = (float(la) - ref[0]) * 6_371_000.0
            de = (float(lo) - ref[1]) * 6_371_000.0 * np.cos(float(la))
            d.append(np.hypot(dn, de))
    diffs = np.array(d)
    assert diffs.size >= 305 and np.median(diffs) <= 0.03
    assert np.mean(diffs > 0.10) < 45 / 305
