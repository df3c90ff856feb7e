"""The rover's Doppler velocity in the DGNSS filter (algorithms.md §44), on galway s3 (u-blox
M8P rover walking and cycling, M8P base from its RTCM3, L1): the filter's velocity follows the
chip's own fixes' velocity, and the position error against those fixes drops. Reference: the
chip's real-time fixes (GGA quality 4), relative to the base's broadcast position."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from robustrtk.eval.truth import read_truth_file
from robustrtk.pipeline.gnss import dgnss_config, solve_dgnss

BASE_S3 = np.array([3774696.5547, -596647.9083, 5089485.6511])  # the base's broadcast position
LEAP_S = 18.0  # GPS − UTC in 2018


def chip_fixes(path: Path) -> dict[int, np.ndarray]:
    """The chip's fixed GGA positions (quality 4; ECEF, m) by rounded GPS second of day: the
    log has no date (UTC seconds of day, GPS = UTC + 18 s)."""
    truth = read_truth_file(path, fixed_only=True)
    assert truth.t_s is not None and truth.utc_time_of_day
    return {round(float(t) + LEAP_S): p for t, p in zip(truth.t_s, truth.pos_m, strict=True)}


def _errors(sols: list, chip: dict[int, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:  # type: ignore[type-arg]
    """Position errors (m) at the chip's fixes, and velocity errors (m/s) against the
    velocity of consecutive chip fixes one second apart (central difference)."""
    pos = {round(s.t_s % 86400.0): s.pos_m for s in sols if s.status == "dgnss"}
    dp = np.array([np.linalg.norm(p - chip[k]) for k, p in pos.items() if k in chip])
    dv = []
    for k in pos:
        if k - 1 in chip and k + 1 in chip and k - 1 in pos and k + 1 in pos:
            v_sol = (pos[k + 1] - pos[k - 1]) / 2.0
            v_ref = (chip[k + 1] - chip[k - 1]) / 2.0
            dv.append(np.linalg.norm(v_sol - v_ref))
    return dp, np.asarray(dv)


@pytest.mark.slow
def test_doppler_velocity_on_galway_s3(shared_data: Path) -> None:
    s3 = shared_data / "galway_m8p_l1_lowcost" / "s3_kinematic"
    if not (s3 / "rover-20181009-1221.obs").is_file():
        pytest.skip(f"galway_m8p_l1_lowcost not found in {shared_data}")
    chip = chip_fixes(s3 / "rover-20181009-1221_GGA.nmea")
    rover, base, nav = (s3 / f for f in ("rover-20181009-1221.obs", "base-20181009-1220_rtcm.obs",
                                         "rover-20181009-1221.nav"))  # fmt: skip
    out = {}
    for name, over in (
        ("off", {"dgnss_doppler": False}),
        ("velocity", {}),
        ("carry", {"dgnss_doppler_jerk_m_s3": 1.0}),
    ):
        # the Doppler alone: no TDCP carry (algorithms.md §45)
        res = solve_dgnss(rover, base, nav, BASE_S3, dgnss_config(freqs="L1", dgnss_tdcp_carry=False, **over))
        out[name] = _errors(res.solutions, chip)
    v_off, (p_vel, v_vel), v_car = out["off"][1], out["velocity"], out["carry"][1]
    assert p_vel.size > 500 and v_vel.size > 400
    # the epoch-to-epoch motion of the track is closer to the chip's
    assert np.median(v_vel) < 0.75 * np.median(v_off)  # 0.28 m/s, 0.44 without
    assert np.median(v_car) < 0.5 * np.median(v_vel)
    p95 = {k: float(np.percentile(v[0], 95)) for k, v in out.items()}
    assert p95["velocity"] < 0.75 * p95["off"]  # 4.2 m, 7.8 without
    assert p95["carry"] < 0.85 * p95["velocity"]  # 3.0 m
