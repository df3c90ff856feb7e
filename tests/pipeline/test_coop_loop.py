"""The one peer-to-peer loop: RINEX cooperative runs and the zhou2018 study both run through
``pipeline.coop.loops.peer_to_peer``, and a replayed node feeds its peers exactly as it did
when it was solved."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from robustrtk.experiments.zhou2018 import solve as zhou_solve
from robustrtk.io.rinex_nav import read_rinex_nav
from robustrtk.pipeline.config import ZHOU2018_PRESET
from robustrtk.pipeline.coop import loops, rinex
from robustrtk.pipeline.coop.types import CoopNode, RangeLink
from robustrtk.pipeline.gnss_inputs import load_obs
from robustrtk.sim.coop import CoopSimSpec, simulate_coop

T0 = 1403252400.0


class _Spy:
    def __init__(self) -> None:
        self.calls: list[tuple[str, ...]] = []

    def __call__(self, t_s: Any, network: Any) -> Any:
        self.calls.append(tuple(nd.name for nd in network.nodes))
        return loops.peer_to_peer(t_s, network)


@pytest.fixture(scope="module")
def sim(shared_data: Path):  # type: ignore[no-untyped-def]
    nav = read_rinex_nav(shared_data / "mosaicx5_static_1m" / "base.nav")
    return simulate_coop(nav, CoopSimSpec(t0_s=T0, n_epochs=12), np.random.default_rng(7), degraded=True)


def test_zhou2018_runs_the_pipeline_loop(sim, monkeypatch: pytest.MonkeyPatch) -> None:  # type: ignore[no-untyped-def]
    spy = _Spy()
    monkeypatch.setattr(zhou_solve, "peer_to_peer", spy)
    zhou_solve.solve_pair(sim, "ekf", "improved", ZHOU2018_PRESET, mutual=True)
    assert spy.calls == [("node1", "node2")]


def test_replayed_node_feeds_its_peer_as_when_solved(sim) -> None:  # type: ignore[no-untyped-def]
    for kind in ("ekf", "pf"):
        live = zhou_solve.solve_pair(sim, kind, "improved", ZHOU2018_PRESET.updated(n_particles=200))
        again = zhou_solve.solve_pair(
            sim, kind, "improved", ZHOU2018_PRESET.updated(n_particles=200), node1=live
        )
        np.testing.assert_array_equal(live.pos_m, again.pos_m)
        np.testing.assert_array_equal(live.range_sigma_m, again.range_sigma_m)
        # node 1 broadcast after each of its solved epochs, and only then
        solved1 = np.isfinite(live.pos_m[0, :, 0])
        assert np.array_equal(np.isfinite(live.bc_x[:, 0]), solved1) and solved1.any()


def test_rinex_cooperation_runs_the_pipeline_loop(shared_data: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    d = shared_data / "geonet_0759_3040_static_3km"
    if not (d / "07590920.05o").exists():
        pytest.skip("geonet data not in the shared data")
    spy = _Spy()
    monkeypatch.setattr(rinex, "peer_to_peer", spy)
    n1 = load_obs(d / "30400920.05o", None)
    n2 = load_obs(d / "07590920.05o", None)
    res = rinex.solve_coop(
        [CoopNode("node1", n1), CoopNode("node2", n2)],
        [RangeLink.constant("node1", "node2", 3335.389, 0.05)],
        d / "07590920.05n",
    )
    assert spy.calls == [("node1", "node2")]
    assert res.solved_fraction("node2") == 1.0


def test_range_link_interpolates_across_a_short_gap_only() -> None:
    link = RangeLink("a", "b", np.array([0.0, 1.0, 3.0, 40.0]), np.array([5.0, 5.2, 5.6, 9.0]),
                     np.array([0.01, 0.04, 0.02, 0.01]), max_gap_s=30.0)  # fmt: skip
    assert link.at(1.3) == (5.2, 0.04)  # within tol_s: the series epoch
    r, v = link.at(2.0)  # halfway between 1 s and 3 s
    assert r == pytest.approx(5.4) and v == pytest.approx(0.04 + 0.2**2)
    assert all(np.isnan(link.at(t)).all() for t in (20.0, -5.0, 50.0))  # gap > 30 s, outside
    never = RangeLink("a", "b", link.t_s, link.range_m, link.var_m2)
    assert np.isnan(never.at(2.0)).all()
