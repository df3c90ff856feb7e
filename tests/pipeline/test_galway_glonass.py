"""GLONASS FDMA carrier phase on the galway u-blox M8P data (L1, GPS + GLONASS;
``../shared/data/galway_m8p_l1_lowcost``, skipped without it).

RTKLIB demo5 fix-and-hold with GLONASS AR on fixes 81.3 % (M8P base from its RTCM3), 93.2 %
(from its UBX) and 60.5 % (CORS GLW1) of the 1205 rover epochs.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from robustrtk.geometry.frames import ecef2enu_rotation, ecef2geodetic
from robustrtk.pipeline.rtk_gnss import RtkResult, rtk_gnss_config, solve_rtk

ROVER_TRUTH = np.array([3774088.6834, -601663.0382, 5089318.2298])
BASE_S1 = np.array([3774088.9004, -601662.8325, 5089318.0783])
GLW1 = np.array([3774050.9626, -601852.6734, 5089350.3688])
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


def _solve(galway: Path, base: str, **kw: object) -> RtkResult:
    path, pos, _ = BASES[base]
    s1 = galway / "s1_static"
    cfg = rtk_gnss_config(freqs="L1", systems="GR", **kw)
    return solve_rtk(
        s1 / "rover-20181004-1237.obs", galway / path, s1 / "base-20181004-1236_ubx.nav", pos, cfg
    )


def _fixed_horiz(res: RtkResult) -> np.ndarray:
    lat, lon, _ = ecef2geodetic(ROVER_TRUTH)
    rot = ecef2enu_rotation(float(lat), float(lon))
    fixed = [s for s in res.solutions if s.status in ("fixed", "partial")]
    return np.array([np.hypot(*(rot @ (s.pos_m - ROVER_TRUTH))[:2]) for s in fixed])


@pytest.mark.slow
@pytest.mark.parametrize(("base", "glonass_ar"), [("rtcm", "auto"), ("ubx", "on"), ("glw1", "auto")])
def test_gps_glonass_fixes_at_least_rtklib(galway: Path, base: str, glonass_ar: str) -> None:
    """GPS + GLONASS: fix rate at least RTKLIB's on the same base, no fixed epoch 10 cm off.
    ``auto`` keeps GLONASS float here (convbin leaves the u-blox REC # / TYPE empty; GLW1 is a
    Leica); ``on`` fixes it (both receivers are u-blox M8P)."""
    res = _solve(galway, base, glonass_ar=glonass_ar)
    assert res.info["glonass_ar"] == ("on" if glonass_ar == "on" else "off")
    horiz = _fixed_horiz(res)
    assert horiz.size >= BASES[base][2] * 1205
    assert np.all(horiz <= 0.10)


@pytest.mark.slow
def test_float_only_glonass_keeps_no_glonass_integers(galway: Path) -> None:
    """``glonass_ar = off``: at every epoch at most the non-GLONASS ambiguities are fixed; ``on``
    fixes GLONASS ones as well on the same data."""

    def excess(res: RtkResult) -> int:
        n_r: dict[float, int] = {}
        for d in res.run.diagnostics:
            if d.kind == "phase" and d.dd.startswith("R"):
                n_r[d.t_s] = n_r.get(d.t_s, 0) + 1
        return max(s.n_fixed - (s.n_amb - n_r.get(s.t_s, 0)) for s in res.solutions)

    assert excess(_solve(galway, "ubx", glonass_ar="off")) <= 0
    assert excess(_solve(galway, "ubx", glonass_ar="on")) > 0
