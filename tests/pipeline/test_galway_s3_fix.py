"""No fix without a snapshot (algorithms.md §37): on galway s3 (u-blox M8P rover walking and
cycling, M8P base from its RTCM3, L1) the first fix used to come at an epoch with too few
code rows for a snapshot, and its integers, held, put the rover 1.07 m from the chip's own
fixes for 35 epochs (213–239 s from the start). Reference: the chip's real-time fixes (GGA
quality 4), relative to the base's broadcast position."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from robustrtk.eval.truth import read_truth_file
from robustrtk.pipeline.rtk_gnss import rtk_gnss_config, solve_rtk

BASE_S3 = np.array([3774696.5547, -596647.9083, 5089485.6511])
LEAP_S = 18.0  # GPS − UTC in 2018


def _chip_fixes(path: Path) -> dict[int, np.ndarray]:
    """The chip's fixed GGA positions (quality 4; ECEF, m) by rounded GPS second of day: the
    log has no date (UTC seconds of day, GPS = UTC + 18 s)."""
    truth = read_truth_file(path, fixed_only=True)
    assert truth.t_s is not None and truth.utc_time_of_day
    return {round(float(t) + LEAP_S): p for t, p in zip(truth.t_s, truth.pos_m, strict=True)}


@pytest.mark.slow
def test_no_held_wrong_fix_on_galway_s3(shared_data: Path) -> None:
    s3 = shared_data / "galway_m8p_l1_lowcost" / "s3_kinematic"
    if not (s3 / "rover-20181009-1221.obs").is_file():
        pytest.skip(f"galway_m8p_l1_lowcost not found in {shared_data}")
    res = solve_rtk(
        s3 / "rover-20181009-1221.obs", s3 / "base-20181009-1220_rtcm.obs", s3 / "base-20181009-1220_ubx.nav",
        BASE_S3, rtk_gnss_config(freqs="L1"),
    )  # fmt: skip
    chip = _chip_fixes(s3 / "rover-20181009-1221_GGA.nmea")
    t0 = res.solutions[0].t_s
    far, common, early = 0, 0, 0
    for s in res.solutions:
        ref = chip.get(round(s.t_s % 86400.0))
        if s.status in ("fixed", "partial") and ref is not None:
            common += 1
            d = float(np.linalg.norm(s.pos_m - ref))
            far += d > 0.10
            early += 200.0 <= s.t_s - t0 <= 240.0 and d > 0.10
    assert common > 500
    assert early == 0  # 35 epochs 1.07 m off before
    assert far <= 20  # 42 before; 15 remain (10–20 cm partial fixes, 1623–1757 s)
