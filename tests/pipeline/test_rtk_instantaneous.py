"""Single-epoch (instantaneous) ambiguity resolution in the RTK step.

With ``instantaneous = True`` every ambiguity is dropped and re-added diffuse at each
epoch, so the float update carries no position information from the phase: the float
position is the prediction and its covariance only grows. The next epoch has to start
from this epoch's *fixed* solution -- its mean and its covariance -- or the position
covariance keeps growing, the float ambiguity covariance of the following epochs grows
with it, the ratio test fails (the position then coasts on the prediction) or passes
on a wrong integer set, and the track drifts although no observation is faulty.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from robustrtk.core import ObsBatch
from robustrtk.geometry.surveyed import SurveyedSource
from robustrtk.pipeline.config import Config
from robustrtk.pipeline.engine import DDEngine, align_epochs
from robustrtk.pipeline.results import EpochInputs
from robustrtk.sim.pseudolite import SimResult, simulate
from robustrtk.sim.scenario import load_scenario

N_EPOCHS = 100


def _clean_rail(seed: int) -> SimResult:
    """The Li et al. (2019) rail (0.02 m/s along a straight line) without its gross errors."""
    sc = dataclasses.replace(load_scenario("li2019_rtk_rail"), gross=())
    return simulate(sc, np.random.default_rng(seed), n_epochs=N_EPOCHS)


def _cfg() -> Config:
    return Config.of(
        mode="rtk", robust="none", ar="lambda", dynamics="kinematic", hold=False, instantaneous=True
    )


def _engine(sim: SimResult, cfg: Config) -> tuple[DDEngine, ObsBatch, ObsBatch]:
    site = sim.site
    assert site.rover_initial_pos_m is not None
    eng = DDEngine(
        cfg,
        SurveyedSource(site.transmitters),
        site.base_pos_m,
        np.asarray(site.rover_initial_pos_m),
        reference=site.reference,
    )
    return eng, sim.batches["rover"], sim.batches["base"]


def _rail_offset_m(pos_m: np.ndarray, start_m: np.ndarray, end_m: np.ndarray) -> np.ndarray:
    """Horizontal distance of each position (T, 3) from the line start→end (m)."""
    u = (end_m - start_m)[:2] / np.linalg.norm((end_m - start_m)[:2])
    r = pos_m[:, :2] - start_m[:2]
    return np.asarray(np.abs(r[:, 0] * u[1] - r[:, 1] * u[0]))


def test_clean_rail_is_fixed_and_tracked_with_continuous_ar() -> None:
    """Control: the same data with continuous AR and fix-and-hold stay on the rail, so
    the simulation and the known-point start are sound."""
    sim = _clean_rail(0)
    cfg = _cfg().updated(instantaneous=False, hold=True)
    eng, rov, bas = _engine(sim, cfg)
    sols = [eng.step(EpochInputs(rov.epoch(i), bas.epoch(j))).solution for i, j in align_epochs(rov, bas)]
    pos = np.array([s.pos_m for s in sols])
    assert np.mean([s.status == "fixed" for s in sols]) >= 0.95
    assert np.max(np.linalg.norm(pos - sim.truth_pos_m, axis=1)) < 0.1


def test_next_epoch_starts_from_the_fixed_covariance() -> None:
    """After a fixed epoch the state handed to the next epoch is the fixed solution:
    same position mean and the same position covariance as the reported solution, which
    is only scaled by the phase residuals' variance factor (≥ 1, algorithms.md §37)."""
    sim = _clean_rail(0)
    eng, rov, bas = _engine(sim, _cfg())
    n_fixed = 0
    for i, j in align_epochs(rov, bas):
        sol = eng.step(EpochInputs(rov.epoch(i), bas.epoch(j))).solution
        if sol.status != "fixed":
            continue
        n_fixed += 1
        assert eng.state is not None
        np.testing.assert_allclose(eng.state.get("pos"), sol.pos_m, atol=1e-9)
        P = eng.state.cov("pos")
        f = float(np.trace(sol.cov_m2) / np.trace(P))
        assert f >= 1.0 - 1e-9
        np.testing.assert_allclose(f * P, sol.cov_m2, rtol=1e-6, atol=1e-12)
    assert n_fixed > 0


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_clean_rail_is_tracked_with_single_epoch_ar(seed: int) -> None:
    """Fault-free rail, single-epoch AR from a known start: (almost) every epoch fixed and
    the horizontal track within 5 cm of the rail (RTK with mm phase noise)."""
    sim = _clean_rail(seed)
    eng, rov, bas = _engine(sim, _cfg())
    sols = [eng.step(EpochInputs(rov.epoch(i), bas.epoch(j))).solution for i, j in align_epochs(rov, bas)]
    pos = np.array([s.pos_m for s in sols])
    tr = load_scenario("li2019_rtk_rail").trajectory
    assert tr.end_m is not None
    off = _rail_offset_m(pos, np.asarray(tr.start_m), np.asarray(tr.end_m))
    fixed = np.array([s.status == "fixed" for s in sols])
    assert fixed.mean() >= 0.95
    assert off.max() < 0.05
