"""Least-squares SPP never reports a wild epoch as ``single``: an epoch whose solution fails
its sanity check (residuals, height, σ, an unverifiable jump) is ``none`` with its reason,
and the rest of the run is solved as before."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from robustrtk.io.rinex_obs import read_rinex_obs
from robustrtk.pipeline.gnss_inputs import nav_source
from robustrtk.pipeline.spp import HEIGHT_RANGE_M, MAX_SIGMA_M, solve_spp
from robustrtk.pipeline.spp_common import select_band1


@pytest.fixture(scope="module")
def geonet(shared_data: Path) -> tuple[object, object]:
    d = shared_data / "geonet_0759_3040_static_3km"
    return select_band1(read_rinex_obs(d / "30400920.05o")), nav_source([str(d / "30400920.05n")])


def test_corrupted_epochs_are_none_never_wild_singles(geonet: tuple[object, object]) -> None:
    batch, eph = geonet
    clean = solve_spp(batch, eph)  # type: ignore[arg-type]
    truth = np.median([e.pos_ecef_m for e in clean], axis=0)
    rng = np.random.default_rng(1)
    code = batch.code_m.copy()  # type: ignore[attr-defined]
    bad = list(range(5, len(clean), 2))
    for k in bad:  # 4 to 6 satellites, each pseudorange off by ~200 km
        rows = np.flatnonzero(np.isfinite(code[k, :, 0]))
        keep = int(rng.integers(4, 7))
        code[k, rows[keep:], 0] = np.nan
        code[k, rows[:keep], 0] += rng.normal(0.0, 2e5, keep)
    sols = solve_spp(dataclasses.replace(batch, code_m=code), eph)  # type: ignore[arg-type]
    assert len(sols) == len(clean)
    for k, e in enumerate(sols):
        if e.status == "none":
            assert e.reason and np.all(np.isnan(e.pos_ecef_m))
            continue
        # every reported epoch is within a few σ of the truth; none is 100 km off
        assert np.linalg.norm(e.pos_ecef_m - truth) < 1e3
        if k not in bad:
            np.testing.assert_allclose(e.pos_ecef_m, clean[k].pos_ecef_m, atol=1e-6)
    reasons = {e.reason.split(" ")[0] for e in sols if e.status == "none"}
    assert {"residuals", "height"} <= reasons
    untouched = [k for k in range(len(sols)) if k not in bad]
    assert all(sols[k].status == "single" for k in untouched)


def test_bounds_are_physical() -> None:
    assert HEIGHT_RANGE_M[0] < -400.0 and HEIGHT_RANGE_M[1] > 20_000.0  # Dead Sea, airliners
    assert MAX_SIGMA_M >= 300.0  # a phone's worst honest SPP σ on the Pixel 5 drive is 319 m
