"""Cooperative positioning on real data (geonet 0759–3040, 3.3 km): node 1 the base (open
sky), node 2 the rover behind a seeded windowsill occlusion, the inter-node range from our own
RTK on the unmasked data. Acceptance lines of the cooperative-positioning issue, plus the
scenario helpers and the range-file reader."""

from __future__ import annotations

import warnings
from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest

from robustrtk.core import InputError, ObsBatch
from robustrtk.pipeline.config import COOP_PRESET, Config
from robustrtk.pipeline.coop import (
    CoopNode,
    RangeLink,
    horizontal_errors,
    read_range_file,
    rtk_range_link,
    solve_coop,
    solve_coop_central,
)
from robustrtk.pipeline.coop.scenarios import inject_code_bias, windowsill_mask
from robustrtk.pipeline.gnss_inputs import load_obs, nav_source

DATA = Path(__file__).resolve().parents[2] / ".." / "shared" / "data" / "geonet_0759_3040_static_3km"
BASE = np.array([-3978241.958, 3382840.234, 3649900.853])
ROVER = np.array([-3976219.1879, 3382371.6056, 3652511.1425])  # RTKLIB static fix, 3 mm spread
SEED = 0  # the documented windowsill seed (docs/coop.md)

needs_data = pytest.mark.skipif(
    not (DATA / "07590920.05o").exists(), reason="geonet data not in ../shared/data"
)


@lru_cache(maxsize=1)
def coop_config(**kw: object) -> Config:
    """The cooperative preset with ``[coop]`` and shared settings (``filter``: the node filter)."""
    if "filter" in kw:
        kw["coop_filter"] = kw.pop("filter")
    return COOP_PRESET.updated(**kw).validate()


def _inputs():
    eph = nav_source([DATA / "07590920.05n"])
    n1 = load_obs(DATA / "30400920.05o", None)
    n2 = load_obs(DATA / "07590920.05o", None)
    return eph, n1, n2


@lru_cache(maxsize=1)
def _rtk_link() -> RangeLink:
    eph, n1, n2 = _inputs()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        link, info = rtk_range_link(n2, n1, eph, a="node2", b="node1", b_pos_m=BASE, session=True)
    return link


@lru_cache(maxsize=4)
def _mask(max_sats: int) -> np.ndarray:
    eph, _, n2 = _inputs()
    vis, _ = windowsill_mask(n2, eph, n2.approx_pos_m, max_sats=max_sats, seed=SEED)
    return vis


def _run(
    filter_: str, cooperation: str, max_sats: int, n1: ObsBatch | None = None, epochs: int | None = None
):
    eph, n1_clean, n2 = _inputs()
    n1 = n1_clean if n1 is None else n1
    vis = _mask(max_sats)
    if epochs is not None:
        n1, n2, vis = n1.select_epochs(slice(0, epochs)), n2.select_epochs(slice(0, epochs)), vis[:epochs]
    cfg = coop_config(filter=filter_, cooperation=cooperation)
    res = solve_coop([CoopNode("node1", n1), CoopNode("node2", n2, vis)], [_rtk_link()], eph, cfg)
    err = horizontal_errors(res.positions("node2"), ROVER)
    return res, err


def _h95(err: np.ndarray) -> float:
    return float(np.nanpercentile(err, 95)) if np.isfinite(err).any() else float("inf")


# ---------------------------------------------------------------------- helpers
@needs_data
def test_windowsill_mask_keeps_one_sector_and_at_most_k():
    eph, _, n2 = _inputs()
    vis, az = windowsill_mask(n2, eph, n2.approx_pos_m, max_sats=3, seed=SEED)
    vis2, az2 = windowsill_mask(n2, eph, n2.approx_pos_m, max_sats=3, seed=SEED)
    np.testing.assert_array_equal(vis, vis2)
    assert az == az2 and 0.0 <= az < 360.0
    assert vis.shape == (len(n2), len(n2.tx_ids))
    assert vis.sum(axis=1).max() <= 3
    # every visible satellite is within 90° of the sector centre (recomputed independently)
    from robustrtk.measurement.undifferenced import epoch_geometry
    from robustrtk.pipeline.spp_common import select_band1

    b1 = select_band1(n2)
    lat = np.arctan2(n2.approx_pos_m[2], np.hypot(*n2.approx_pos_m[:2]))
    lon = np.arctan2(n2.approx_pos_m[1], n2.approx_pos_m[0])
    east = np.array([-np.sin(lon), np.cos(lon), 0.0])
    north = np.array([-np.sin(lat) * np.cos(lon), -np.sin(lat) * np.sin(lon), np.cos(lat)])
    for k in range(0, len(n2), 17):
        g = epoch_geometry(b1, k, eph)
        for j, sid in enumerate(g.ids):
            if vis[k, n2.tx_ids.index(sid)]:
                d = g.sat_pos_m[j] - n2.approx_pos_m
                a = np.degrees(np.arctan2(d @ east, d @ north)) % 360.0
                assert abs((a - az + 180.0) % 360.0 - 180.0) <= 90.0 + 1e-6
    other, az3 = windowsill_mask(n2, eph, n2.approx_pos_m, max_sats=3, seed=SEED + 1)
    assert az3 != az


@needs_data
def test_inject_code_bias_hits_the_stretch_only():
    _, n1, _ = _inputs()
    bad, hit = inject_code_bias(n1, 20.0, 2, slice(40, 80), seed=0)
    assert len(hit) == 2
    d = bad.code_m - n1.code_m
    rows = [n1.tx_ids.index(h) for h in hit]
    fin = np.isfinite(d)
    assert np.allclose(d[40:80][:, rows][fin[40:80][:, rows]], 20.0)
    mask = np.ones(d.shape, bool)
    mask[40:80, rows] = False
    assert np.all(d[mask & fin] == 0.0)


def test_range_file_reader(tmp_path):
    p = tmp_path / "r.txt"
    p.write_text("# gpst range sigma\n100 6.5 0.02\n101, 6.6\n\n102 6.7 0.03 # note\n")
    lk = read_range_file(p, "a", "b", default_sigma_m=0.05)
    np.testing.assert_array_equal(lk.t_s, [100.0, 101.0, 102.0])
    np.testing.assert_allclose(lk.var_m2, [0.02**2, 0.05**2, 0.03**2])
    assert lk.at(101.2) == (6.6, pytest.approx(0.0025))
    assert np.isnan(lk.at(105.0)[0])
    c = RangeLink.constant("a", "b", 6.5, 0.1)
    assert c.at(1e9) == (6.5, pytest.approx(0.01))
    for text, line in (("100 6.5\n99 6.5\n", 2), ("100 x\n", 1), ("100 -1\n", 1), ("1 2 3 4\n", 1)):
        p.write_text(text)
        with pytest.raises(InputError) as ei:
            read_range_file(p, "a", "b")
        assert f"r.txt:{line}:" in str(ei.value)
    p.write_text("# nothing\n")
    with pytest.raises(InputError, match="no rows"):
        read_range_file(p, "a", "b")


def test_settings_refuse_unknown_choices():
    with pytest.raises(InputError, match="filter"):
        coop_config(filter="kf")
    with pytest.raises(InputError, match="cooperation"):
        coop_config(cooperation="both")


# ---------------------------------------------------------------------- short runs
@needs_data
def test_rtk_range_matches_the_reference_baseline():
    link = _rtk_link()
    assert link.range_m[0] == pytest.approx(float(np.linalg.norm(ROVER - BASE)), abs=0.02)
    assert np.sqrt(link.var_m2[0]) < 0.05


@needs_data
@pytest.mark.parametrize("filter_", ["ekf", "pf"])
def test_three_satellites_need_cooperation_short(filter_):
    res_off, err_off = _run(filter_, "off", 3, epochs=12)
    assert res_off.solved_fraction("node2") == 0.0
    res, err = _run(filter_, "improved", 3, epochs=12)
    assert res.solved_fraction("node2") == 1.0
    ep = res.epochs["node2"]
    assert all(e.n_sats == 3 for e in ep)
    # node 1 is processed first, so node 2 has its broadcast from the first epoch on
    assert all(e.n_ranges == 1 for e in ep)
    assert all(np.isfinite(e.range_residual_m) and e.trace_p_m2 > 0 for e in ep[1:])
    if filter_ == "pf":
        assert all(1.0 <= e.ess <= 10_000 for e in ep[1:])
    else:
        assert all(np.isnan(e.ess) for e in ep)
    assert _h95(err) < 15.0


# ---------------------------------------------------------------------- acceptance (slow)
@needs_data
@pytest.mark.slow
@pytest.mark.parametrize("filter_", ["ekf", "ukf", "pf", "ls"])
def test_acceptance_three_satellites(filter_):
    res_off, _ = _run(filter_, "off", 3)
    assert res_off.solved_fraction("node2") == 0.0  # alone: no solution
    res, err = _run(filter_, "improved", 3)
    assert res.solved_fraction("node2") >= 0.95
    assert _h95(err) <= 10.0


@needs_data
@pytest.mark.slow
def test_acceptance_four_or_five_satellites():
    vis = _mask(5)
    assert set(np.unique(vis.sum(axis=1))) <= {3, 4, 5}
    h95 = {}
    for f in ("ekf", "ukf", "pf"):
        _, err_alone = _run(f, "off", 5)
        _, err_coop = _run(f, "improved", 5)
        h95[f] = _h95(err_coop)
        assert h95[f] <= 0.5 * _h95(err_alone), f
    assert h95["pf"] <= 1.10 * h95["ekf"]
    assert h95["ukf"] <= 1.10 * h95["ekf"]


@needs_data
@pytest.mark.slow
@pytest.mark.parametrize("filter_", ["ekf", "ukf", "pf"])
def test_acceptance_node1_corruption_three_satellites(filter_):
    """+20 m on two of node 1's satellites over epochs 40–79 (seed 0): with 'improved' node
    2's H95 stays within 1.5× of its clean value (EKF, UKF, PF; LS does not, docs/coop.md)."""
    _, n1, _ = _inputs()
    bad, _ = inject_code_bias(n1, 20.0, 2, slice(40, 80), seed=0)
    _, clean = _run(filter_, "improved", 3)
    _, corrupt = _run(filter_, "improved", 3, n1=bad)
    assert _h95(corrupt) <= 1.5 * _h95(clean)


@needs_data
@pytest.mark.slow
def test_centralised_reference_agrees_with_peer_to_peer():
    eph, n1, n2 = _inputs()
    vis = _mask(3)
    cfg = coop_config(filter="ekf", cooperation="traditional")
    central = solve_coop_central([CoopNode("node1", n1), CoopNode("node2", n2, vis)], [_rtk_link()], eph, cfg)
    err_c = horizontal_errors(central.positions("node2"), ROVER)
    assert central.solved_fraction("node2") >= 0.95
    _, err_p = _run("ekf", "improved", 3)
    assert _h95(err_c) <= 10.0
    assert abs(_h95(err_c) - _h95(err_p)) <= 0.5 * _h95(err_p)
    off = solve_coop_central(
        [CoopNode("node1", n1), CoopNode("node2", n2, vis)],
        [_rtk_link()],
        eph,
        coop_config(cooperation="off"),
    )
    assert off.solved_fraction("node2") == 0.0


@needs_data
def test_three_nodes_peer_to_peer_use_both_peers():
    """N > 2: node 2 ranges to two peers (a second receiver at node 1's antenna, the same
    file under another name); every node runs its own filter and sees both others."""
    eph, n1, n2 = _inputs()
    k = 8
    a, b, c = n1.select_epochs(slice(0, k)), n2.select_epochs(slice(0, k)), n1.select_epochs(slice(0, k))
    vis = _mask(3)[:k]
    r = float(_rtk_link().range_m[0])
    links = [RangeLink.constant("node2", "node1", r, 0.01), RangeLink.constant("node2", "node3", r, 0.01)]
    nodes = [CoopNode("node1", a), CoopNode("node2", b, vis), CoopNode("node3", c)]
    res = solve_coop(nodes, links, eph, coop_config(filter="ekf"))
    # node 3 runs after node 2, so its first broadcast reaches node 2 at the second epoch
    assert [e.n_ranges for e in res.epochs["node2"]] == [1] + [2] * (k - 1)
    assert all(e.n_ranges == 1 for e in res.epochs["node1"][1:])
    assert all(e.n_ranges == 1 for e in res.epochs["node3"])
    assert res.solved_fraction("node2") == 1.0
    err = horizontal_errors(res.positions("node2"), ROVER)
    assert float(np.nanmax(err)) < 20.0
    with pytest.raises(InputError, match="node4"):
        solve_coop(nodes, [RangeLink.constant("node2", "node4", r, 0.01)], eph)


@needs_data
@pytest.mark.slow
def test_moving_base_range_matches_fixed_base():
    """Neither receiver surveyed: the moving-base RTK baseline length agrees with the
    fixed-base one within centimetres (the baseline, not the base position, is resolved)."""
    eph, n1, n2 = _inputs()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        moving, info = rtk_range_link(n2, n1, eph, a="node2", b="node1", b_pos_m=None, session=True)
    assert info["rtk_fixed"] > 0
    assert moving.range_m[0] == pytest.approx(float(_rtk_link().range_m[0]), abs=0.05)
