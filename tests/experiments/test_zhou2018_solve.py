"""The two-node loop of the zhou2018 experiment on the simulated sessions."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from robustrtk.experiments.zhou2018.solve import solve_pair
from robustrtk.io.rinex_nav import read_rinex_nav
from robustrtk.pipeline.config import ZHOU2018_PRESET
from robustrtk.sim.coop import CoopSimSpec, simulate_coop

T0 = 1403252400.0


@pytest.fixture(scope="module")
def nav(shared_data: Path):  # type: ignore[no-untyped-def]
    return read_rinex_nav(shared_data / "mosaicx5_static_1m" / "base.nav")


def test_node1_reuse_changes_nothing(nav) -> None:  # type: ignore[no-untyped-def]
    sim = simulate_coop(nav, CoopSimSpec(t0_s=T0, n_epochs=25), np.random.default_rng(4), degraded=True)
    cfg = ZHOU2018_PRESET
    for kind in ("ekf", "ukf"):
        off = solve_pair(sim, kind, "off", cfg)
        a = solve_pair(sim, kind, "improved", cfg)
        b = solve_pair(sim, kind, "improved", cfg, node1=off)
        np.testing.assert_array_equal(a.pos_m, b.pos_m)
        # node 1 solves alone unless mutual: the same in every mode
        np.testing.assert_array_equal(off.pos_m[0], a.pos_m[0])


def test_cooperation_helps_node2_and_solves_it(nav) -> None:  # type: ignore[no-untyped-def]
    cfg = ZHOU2018_PRESET
    alone, coop = [], []
    for seed in range(3):
        sim = simulate_coop(nav, CoopSimSpec(t0_s=T0, n_epochs=30), np.random.default_rng(seed))
        truth = sim.nodes[1].truth_ecef_m
        off = solve_pair(sim, "ekf", "off", cfg)
        imp = solve_pair(sim, "ekf", "improved", cfg, node1=off)
        assert np.isfinite(imp.pos_m[1, :, 0]).all()  # the range makes every epoch solvable
        alone.append(np.sqrt(np.nanmean(np.sum((off.pos_m[1] - truth) ** 2, axis=1))))
        coop.append(np.sqrt(np.nanmean(np.sum((imp.pos_m[1] - truth) ** 2, axis=1))))
        # the improved range row is inflated by at least 4 σ_set floor² = 1 m² (eq. 24 with eq. 29)
        s = imp.range_sigma_m[1][np.isfinite(imp.range_sigma_m[1])]
        assert s.size and np.all(s**2 >= 0.02**2 + 4 * 0.5**2 - 1e-12)
    assert np.mean(coop) < np.mean(alone)
