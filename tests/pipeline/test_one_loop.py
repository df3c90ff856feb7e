"""One epoch loop: every mode (RTK, DGNSS, DPL, least-squares SPP by epoch and by block,
Kalman SPP, cooperative peer-to-peer and central) solves its epochs through
``pipeline.loop.EpochLoop.step``, each with its own stage; re-initialisation streaks and
segment smoothing are the ones of ``pipeline.reinit``."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from robustrtk.core import ObsBatch
from robustrtk.estimation.smoother import FilterStep, rts_smooth
from robustrtk.pipeline import loop as loop_mod
from robustrtk.pipeline.reinit import Streak, gap_exceeded, smooth_steps

GEONET_BASE = np.array([-3978241.958, 3382840.234, 3649900.853])
EPOCHS = 8


class _StepSpy:
    """Wraps ``EpochLoop.step``: the stage type of each call."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        self.stages: list[str] = []
        real = loop_mod.EpochLoop.step

        def step(loop: loop_mod.EpochLoop, item: Any) -> Any:
            self.stages.append(type(loop.stage).__name__)
            return real(loop, item)

        monkeypatch.setattr(loop_mod.EpochLoop, "step", step)

    def count(self, stage: str) -> int:
        return self.stages.count(stage)


@pytest.fixture
def spy(monkeypatch: pytest.MonkeyPatch) -> _StepSpy:
    return _StepSpy(monkeypatch)


@pytest.fixture(scope="module")
def geonet(shared_data: Path) -> tuple[Path, ObsBatch, ObsBatch]:
    from robustrtk.pipeline.gnss_inputs import load_obs

    d = shared_data / "geonet_0759_3040_static_3km"
    if not (d / "07590920.05o").is_file():
        pytest.skip(f"geonet data not in {shared_data}")
    rover = load_obs(d / "07590920.05o", None).select_epochs(slice(0, EPOCHS))
    base = load_obs(d / "30400920.05o", None).select_epochs(slice(0, EPOCHS))
    return d, rover, base


def test_dd_modes_run_through_the_loop(geonet: tuple[Path, ObsBatch, ObsBatch], spy: _StepSpy) -> None:
    from robustrtk.pipeline.api import solve_dgnss, solve_rtk

    d, rover, base = geonet
    for solve in (solve_rtk, solve_dgnss):
        spy.stages.clear()
        series = solve(rover, base, d / "30400920.05n", GEONET_BASE)
        assert len(series) == EPOCHS
        assert spy.count("DDEngine") == EPOCHS, solve.__name__


def test_pseudolite_dpl_runs_through_the_loop(tmp_path: Path, spy: _StepSpy) -> None:
    from robustrtk.pipeline.config import Config
    from robustrtk.pipeline.solve import solve_pseudolite
    from robustrtk.sim.files import run_simulate

    run_simulate("demo", 4, tmp_path)
    res = solve_pseudolite(tmp_path / "obs.csv", tmp_path / "site.toml", Config.of(robust="igg3"))
    assert len(res.solutions) > 0
    assert spy.count("DDEngine") == len(res.solutions)


def test_spp_modes_run_through_the_loop(geonet: tuple[Path, ObsBatch, ObsBatch], spy: _StepSpy) -> None:
    from robustrtk.pipeline.config import preset
    from robustrtk.pipeline.spp import solve_spp, solve_spp_chunks, solve_spp_epochwise
    from robustrtk.pipeline.spp_kalman import solve_spp_kalman

    d, rover, _ = geonet
    nav = d / "07590920.05n"
    from robustrtk.pipeline.gnss_inputs import nav_source

    eph = nav_source([nav])
    block = solve_spp(rover, eph, block_epochs=3)
    assert spy.count("BlockSolver") == 3  # 8 epochs in blocks of 3
    one = solve_spp_epochwise(rover, eph)
    assert spy.count("EpochwiseSpp") == EPOCHS
    np.testing.assert_allclose([e.pos_ecef_m for e in block], [e.pos_ecef_m for e in one], atol=1e-5)
    chunks = list(solve_spp_chunks([rover], eph, block_epochs=4))
    assert spy.count("BlockSolver") == 3 + 2 and sum(map(len, chunks)) == EPOCHS
    kal = solve_spp_kalman(rover, eph, preset("spp").updated(filter="ekf", smoother=True))
    assert spy.count("KalmanSppStage") == EPOCHS and len(kal) == EPOCHS


def test_coop_modes_run_through_the_loop(geonet: tuple[Path, ObsBatch, ObsBatch], spy: _StepSpy) -> None:
    from robustrtk.pipeline.coop import CoopNode, RangeLink, solve_coop, solve_coop_central

    d, rover, base = geonet
    nodes = [CoopNode("node1", base), CoopNode("node2", rover)]
    link = [RangeLink.constant("node1", "node2", 3335.389, 0.05)]
    p2p = solve_coop(nodes, link, d / "07590920.05n")
    assert spy.count("PeerNetwork") == EPOCHS  # one step: every node's epoch
    assert p2p.solved_fraction("node2") == 1.0
    central = solve_coop_central(nodes, link, d / "07590920.05n")
    assert spy.count("JointFilter") == EPOCHS
    assert central.solved_fraction("node2") == 1.0


def test_zhou2018_runs_through_the_loop(shared_data: Path, spy: _StepSpy) -> None:
    from robustrtk.experiments.zhou2018.solve import solve_pair
    from robustrtk.io.rinex_nav import read_rinex_nav
    from robustrtk.pipeline.config import ZHOU2018_PRESET
    from robustrtk.sim.coop import CoopSimSpec, simulate_coop

    nav = read_rinex_nav(shared_data / "mosaicx5_static_1m" / "base.nav")
    sim = simulate_coop(nav, CoopSimSpec(t0_s=1403252400.0, n_epochs=6), np.random.default_rng(7))
    solve_pair(sim, "ekf", "improved", ZHOU2018_PRESET, mutual=True)
    assert spy.count("PeerNetwork") == 6


def test_streak_restarts_after_a_run_only() -> None:
    s = Streak(3)
    hits = [True, True, False, True, True, True]
    for hit, due in zip(hits, [False, False, False, False, False, True], strict=True):
        s.update(hit)
        assert s.due == due
    s.reset()
    assert not s.due
    never = Streak(0)
    for _ in range(10):
        never.update(True)
    assert not never.due
    assert gap_exceeded(10.5, 0.0, 10.0) and not gap_exceeded(10.0, 0.0, 10.0)


def _step(rng: np.random.Generator, first: bool) -> FilterStep:
    x = rng.normal(size=2)
    A = rng.normal(size=(2, 2))
    P = A @ A.T + np.eye(2)
    F = None if first else np.eye(2) + 0.1 * rng.normal(size=(2, 2))
    return FilterStep(F, x + 0.1, P + np.eye(2), x, P)


def test_smooth_steps_is_rts_per_segment() -> None:
    """Segments end at a missing record and before a restart; each is smoothed on its own."""
    rng = np.random.default_rng(3)
    steps: list[FilterStep | None] = [_step(rng, True), _step(rng, False), _step(rng, False), None]
    steps += [_step(rng, True), _step(rng, False), _step(rng, True), _step(rng, False)]
    got = smooth_steps(steps)
    assert got[3] is None
    for seg in ([0, 1, 2], [4, 5], [6, 7]):
        want = rts_smooth([s for s in (steps[k] for k in seg) if s is not None])
        for k, (x, P) in zip(seg, want, strict=True):
            g = got[k]
            assert g is not None
            np.testing.assert_array_equal(g[0], x)
            np.testing.assert_array_equal(g[1], P)
    # the last epoch of a segment keeps its filtered estimate; an earlier one changes
    last = steps[2]
    assert last is not None and got[2] is not None and np.array_equal(got[2][0], last.x_post)
    first = steps[0]
    assert first is not None and got[0] is not None and not np.array_equal(got[0][0], first.x_post)
