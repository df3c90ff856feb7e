"""The two-node simulation of Zhou et al. (2018): geometry, visibility, noise, fault."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from robustrtk.core import CLIGHT
from robustrtk.geometry.frames import ecef2geodetic_deg
from robustrtk.geometry.los import OMEGA_E_RAD_S
from robustrtk.io.rinex_nav import read_rinex_nav
from robustrtk.sim.coop import CoopNodeSpec, CoopSimSpec, simulate_coop

T0 = 1403252400.0  # 2024-06-24 08:20:00 GPST, inside the mosaicx5 nav file


@pytest.fixture(scope="module")
def nav(shared_data: Path):  # type: ignore[no-untyped-def]
    return read_rinex_nav(shared_data / "mosaicx5_static_1m" / "base.nav")


def test_baseline_and_sites(nav) -> None:  # type: ignore[no-untyped-def]
    sim = simulate_coop(nav, CoopSimSpec(t0_s=T0, n_epochs=5), np.random.default_rng(1))
    d = sim.nodes[1].truth_ecef_m - sim.nodes[0].truth_ecef_m
    assert np.linalg.norm(d) == pytest.approx(6.5488, abs=1e-3)  # the paper's baseline
    assert sim.true_range_m == pytest.approx(float(np.linalg.norm(d)))
    lat, lon, h = ecef2geodetic_deg(sim.nodes[0].truth_ecef_m)
    assert float(lat) == pytest.approx(34.0314, abs=1e-3) and float(lon) == pytest.approx(108.7635, abs=1e-3)
    # the range noise is that of the spec
    sim2 = simulate_coop(nav, CoopSimSpec(t0_s=T0, n_epochs=400), np.random.default_rng(2))
    r = sim2.range_m - sim2.true_range_m
    assert abs(r.mean()) < 4 * 0.02 / np.sqrt(400) and 0.017 < r.std() < 0.023


def test_windowsill_counts(nav) -> None:  # type: ignore[no-untyped-def]
    for seed in range(3):
        sim = simulate_coop(nav, CoopSimSpec(t0_s=T0), np.random.default_rng(seed))
        g, c = sim.nodes[1].n_seen("G"), sim.nodes[1].n_seen("C")
        assert g.max() <= 3  # fewer than four GPS satellites at every epoch
        assert c.max() <= 5 and np.mean((c >= 4) & (c <= 5)) > 0.5
        # node 1 open sky: every satellite above the mask, far more than four per system
        n1 = sim.nodes[0]
        assert n1.n_seen("G").min() >= 5 and n1.n_seen("C").min() >= 10
        el = n1.elev_rad[np.isfinite(n1.code_m)]
        assert np.degrees(el).min() >= 10.0


def test_noise_is_eq25_and_unit_after_whitening(nav) -> None:  # type: ignore[no-untyped-def]
    quiet = CoopNodeSpec(multipath_sigma_m=0.0)
    spec = CoopSimSpec(t0_s=T0, n_epochs=60, node1=quiet)
    sim = simulate_coop(nav, spec, np.random.default_rng(3))
    n = sim.nodes[0]
    seen = np.isfinite(n.code_m)
    # eq. 25 in metres, written out here
    var = 1.0**2 * 10 ** (0.1 * (45.0 - n.cn0_dbhz)) / np.sin(n.elev_rad) ** 2
    np.testing.assert_allclose(n.var_m2[seen], var[seen], rtol=1e-9)
    p = n.truth_ecef_m
    s = n.sat_pos_m
    geo = np.linalg.norm(s - p, axis=2) + OMEGA_E_RAD_S * (s[..., 0] * p[1] - s[..., 1] * p[0]) / CLIGHT
    clk = np.where(np.array([i[0] == "G" for i in n.sat_ids])[None, :], n.clock_m[:, :1], n.clock_m[:, 1:])
    w = ((n.code_m - geo - clk) / np.sqrt(n.var_m2))[seen]
    m = w.size
    assert abs(w.mean()) < 4 / np.sqrt(m)
    assert abs(w.var() - 1.0) < 4 * np.sqrt(2.0 / m)


def test_fault_is_the_only_difference(nav) -> None:  # type: ignore[no-untyped-def]
    spec = CoopSimSpec(t0_s=T0)
    a = simulate_coop(nav, spec, np.random.default_rng(7))
    b = simulate_coop(nav, spec, np.random.default_rng(7), degraded=True)
    d = np.nan_to_num(b.nodes[0].code_m - a.nodes[0].code_m)
    cols = np.flatnonzero(np.any(d != 0, axis=0))
    assert cols.size == 2
    rows = np.flatnonzero(np.any(d != 0, axis=1))
    assert rows.min() == 20 and rows.max() == 34
    np.testing.assert_allclose(d[20:35][:, cols], 20.0, atol=1e-9)
    np.testing.assert_array_equal(np.nan_to_num(b.nodes[1].code_m), np.nan_to_num(a.nodes[1].code_m))
    np.testing.assert_array_equal(b.range_m, a.range_m)


def test_spec_is_checked() -> None:
    from robustrtk.core import InputError

    with pytest.raises(InputError, match="n_epochs"):
        CoopSimSpec(t0_s=T0, n_epochs=1)
    with pytest.raises(InputError, match="dt_s"):
        replace(CoopSimSpec(t0_s=T0), dt_s=0.0)
