"""Held-out pair for cooperative positioning: mosaicx5 (0.99 m apart, 1 Hz), node 2 masked by
the same seeded windowsill (three GPS satellites), the range from our RTK on the unmasked data.
The acceptance line of the three-satellite case must hold here too."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from robustrtk.geometry.frames import geodetic2ecef_deg
from robustrtk.pipeline.config import COOP_PRESET, Config
from robustrtk.pipeline.coop import (
    CoopNode,
    horizontal_errors,
    rtk_range_link,
    solve_coop,
)
from robustrtk.pipeline.coop.scenarios import windowsill_mask
from robustrtk.pipeline.gnss_inputs import load_obs, nav_source

DATA = Path(__file__).resolve().parents[2] / ".." / "shared" / "data" / "mosaicx5_static_1m"
EPOCHS = slice(0, 120)


def coop_config(**kw: object) -> Config:
    """The cooperative preset with ``[coop]`` and shared settings (``filter``: the node filter)."""
    if "filter" in kw:
        kw["coop_filter"] = kw.pop("filter")
    return COOP_PRESET.updated(**kw).validate()


def _llh(name: str) -> np.ndarray:
    lat, lon, h = (float(v) for v in (DATA / name).read_text().split()[:3])
    return geodetic2ecef_deg(lat, lon, h)


@pytest.mark.slow
@pytest.mark.skipif(not (DATA / "rover.obs").exists(), reason="mosaicx5 data not in ../shared/data")
def test_heldout_three_gps_satellites_solved_with_cooperation():
    eph = nav_source([DATA / "base.nav"])
    n1 = load_obs(DATA / "base.obs", None).select_epochs(EPOCHS)
    n2 = load_obs(DATA / "rover.obs", None).select_epochs(EPOCHS)
    base, truth = _llh("base_position.txt"), _llh("rover_position.txt")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        link, _ = rtk_range_link(n2, n1, eph, a="node2", b="node1", b_pos_m=base, session=True)
    assert link.range_m[0] == pytest.approx(float(np.linalg.norm(truth - base)), abs=0.02)
    g2 = n2.select_systems("G")
    vis_g, _ = windowsill_mask(g2, eph, n2.approx_pos_m, max_sats=3, seed=0)
    vis = np.zeros((len(n2), len(n2.tx_ids)), bool)
    for j, sid in enumerate(g2.tx_ids):
        vis[:, n2.tx_ids.index(sid)] = vis_g[:, j]
    assert vis.sum(axis=1).max() == 3
    nodes = [CoopNode("node1", n1), CoopNode("node2", n2, vis)]
    off = solve_coop(nodes, [link], eph, coop_config(filter="ekf", cooperation="off", systems="G"))
    assert off.solved_fraction("node2") == 0.0
    for f in ("ekf", "ukf", "pf"):
        res = solve_coop(nodes, [link], eph, coop_config(filter=f, cooperation="improved", systems="G"))
        err = horizontal_errors(res.positions("node2"), truth)
        assert res.solved_fraction("node2") >= 0.95, f
        assert float(np.nanpercentile(err, 95)) <= 10.0, f
