"""The state-discrepancy adaptive factor in the Kalman SPP on the Pixel 5 drive (algorithms.md
§23): the preset's single pass widens the prior in a few epochs and costs little (GSDC score
2.75 m against 2.46 m without it; ten passes would give 6.64 m, as phone code carries NLOS
biases that a measurement-only fit follows), and ``adaptive_alpha`` reports it per epoch."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.geometry.frames import ecef2enu_deg
from robustrtk.io.rinex_nav import read_rinex_nav
from robustrtk.io.rinex_obs import read_rinex_obs
from robustrtk.pipeline.config import preset
from robustrtk.pipeline.spp import solve_spp_kalman

pytestmark = pytest.mark.slow

PIXEL = "gsdc2021_mtv1_pixel5_phone/Pixel5"


def _score(shared: Path, sols: list) -> float:  # type: ignore[type-arg]
    """Mean of the horizontal p50 and p95 against the SPAN truth (GPS-millisecond tags)."""
    gt = np.genfromtxt(
        shared / PIXEL / "ground_truth.csv", delimiter=",", skip_header=1, usecols=(2, 3, 4, 5)
    )
    tg = gt[:, 0] / 1000.0
    errs = []
    for s in sols:
        j = int(np.argmin(np.abs(tg - s.t_s)))
        if abs(tg[j] - s.t_s) < 0.05 and s.status == "single":
            e = ecef2enu_deg(s.pos_ecef_m, gt[j, 1], gt[j, 2], gt[j, 3])
            errs.append(np.hypot(e[0], e[1]))
    assert len(errs) > 0.95 * len(sols)
    p50, p95 = np.percentile(errs, [50, 95])
    return float(p50 + p95) / 2


def test_pixel5_kalman_spp_with_the_adaptive_factor(shared_data: Path) -> None:
    b = read_rinex_obs(shared_data / PIXEL / "supplemental/Pixel5_GnssLog.21o")
    eph = EphemerisSource(read_rinex_nav(shared_data / PIXEL / "supplemental/hour1180.21n"))
    cfg = preset("spp").updated(filter="ekf", adaptive="state")
    assert cfg.estimator.adaptive_max_iter == 1
    sols = solve_spp_kalman(b, eph, cfg)
    alpha = np.array([s.adaptive_alpha for s in sols])
    score = _score(shared_data, sols)
    print(
        f"\nPixel5 Kalman SPP + adaptive (one pass): score {score:.2f} m, α < 1 in {(alpha < 1).sum()} epochs"
    )
    assert np.all((alpha > 0) & (alpha <= 1.0))
    assert 0 < np.count_nonzero(alpha < 1.0) < 0.05 * alpha.size
    assert score <= 3.0  # without the factor 2.46 m (tests/pipeline/test_spp.py bounds it at 4 m)
