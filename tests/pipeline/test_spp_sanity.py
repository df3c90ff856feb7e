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


def test_kalman_output_check_writes_implausible_epochs_as_none() -> None:
    """The Kalman SPP's last step (:func:`reported`): a solved epoch off the Earth, with a
    σ over the bound or a non-finite position becomes ``none`` with its reason; the others
    pass unchanged."""
    from robustrtk.geometry.frames import geodetic2ecef
    from robustrtk.pipeline.spp_common import SppEpoch, reported

    ground = np.asarray(geodetic2ecef(np.radians(35.0), np.radians(139.0), 50.0), float)
    space = np.asarray(geodetic2ecef(np.radians(35.0), np.radians(139.0), 2.0e7), float)

    def ep(pos: np.ndarray, sigma_m: float, status: str = "single") -> SppEpoch:
        return SppEpoch(0.0, pos, {"G": 0.0}, np.eye(3) * sigma_m**2, 8, status, (), True)

    good = ep(ground, 3.0)
    out = reported([good, ep(space, 3.0), ep(ground, 2.0 * MAX_SIGMA_M), ep(np.full(3, np.nan), 3.0)])
    assert out[0] is good
    assert [e.status for e in out] == ["single", "none", "none", "none"]
    assert out[1].reason.startswith("height") and out[2].reason.startswith("position sigma")
    assert out[3].reason == "non-finite position"
    assert not any(e.chi2_ok for e in out[1:])
    none = ep(space, 3.0, status="none")
    assert reported([none])[0] is none  # an unsolved epoch keeps its own reason
