"""SPP: synthetic recovery and fault exclusion, and the Pixel 5 drive against SPAN truth."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.geometry.frames import ecef2enu_deg
from robustrtk.geometry.los import geometric_range
from robustrtk.io.rinex_nav import read_rinex_nav
from robustrtk.io.rinex_obs import read_rinex_obs
from robustrtk.pipeline.spp import SppConfig, select_band1, solve_spp, solve_spp_kalman

PIXEL = "gsdc2021_mtv1_pixel5_phone/Pixel5"
GEONET = "geonet_0759_3040_static_3km"


def _synthetic(shared: Path, fault_m: float) -> tuple:
    """Noise-free pseudoranges of the geonet rover epochs from the broadcast orbits."""
    nav = read_rinex_nav(shared / GEONET / "30400920.05n")
    eph = EphemerisSource(nav)
    b = select_band1(read_rinex_obs(shared / GEONET / "07590920.05o"))
    b = replace(b, t_s=b.t_s[:5], code_m=b.code_m[:5].copy(), phase_cyc=b.phase_cyc[:5],
                doppler_hz=b.doppler_hz[:5], cn0_dbhz=b.cn0_dbhz[:5], lli=b.lli[:5])
    truth = np.array([-3976219.1879, 3382371.6056, 3652511.1425])
    clk_m = 12345.6
    for i in range(len(b)):
        have = np.isfinite(b.code_m[i, :, 0])
        ids = [b.tx_ids[j] for j in np.flatnonzero(have)]
        code = b.code_m[i, have, 0]
        for _ in range(3):  # transmission time consistent with the synthetic range
            pos, sat_clk = eph.positions(float(b.t_s[i]), ids, code)
            rng, _ = geometric_range(pos, truth)
            code = rng + clk_m - sat_clk
        b.code_m[i, have, 0] = code
    b.code_m[:, 3, 0] += fault_m
    cfg = SppConfig(iono=False, tropo=False, code_sigma_m=0.3, use_cn0=False, elev_mask_deg=0.0)
    return b, eph, truth, clk_m, cfg


def test_spp_recovers_synthetic_position_and_clock(shared_data: Path) -> None:
    b, eph, truth, clk_m, cfg = _synthetic(shared_data, 0.0)
    sols = solve_spp(b, eph, cfg)
    for s in sols:
        assert s.status == "single"
        assert np.linalg.norm(s.pos_ecef_m - truth) < 1e-3
        assert s.clock_m["G"] == pytest.approx(clk_m, abs=1e-3)
        assert s.excluded == ()


def test_fde_excludes_a_faulty_satellite(shared_data: Path) -> None:
    b, eph, truth, _, cfg = _synthetic(shared_data, 60.0)
    bad = b.tx_ids[3]
    without = solve_spp(b, eph, replace(cfg, raim=False))
    with_fde = solve_spp(b, eph, cfg)
    for s0, s1 in zip(without, with_fde, strict=True):
        assert np.linalg.norm(s0.pos_ecef_m - truth) > 5.0
        assert s1.excluded == (bad,)
        assert np.linalg.norm(s1.pos_ecef_m - truth) < 1e-3
        assert s1.chi2_ok


def test_band1_selection_keeps_one_l1_column_per_system(shared_data: Path) -> None:
    b = read_rinex_obs(shared_data / "kamakura_kinematic_5km/3034265G.21O")
    one = select_band1(b, "GE")
    assert one.signals == ("1",) and set(one.system) == {"G", "E"}
    assert one.meta["signal_by_system"] == {"G": "1C", "E": "1X"}
    k = b.signals.index("1X")
    e = b.tx_ids.index(next(t for t in b.tx_ids if t[0] == "E"))
    np.testing.assert_array_equal(one.code_m[:, one.tx_ids.index(b.tx_ids[e]), 0], b.code_m[:, e, k])


def _pixel_errors(shared: Path, sols: list) -> tuple[float, float]:
    gt = np.genfromtxt(shared / PIXEL / "ground_truth.csv", delimiter=",", skip_header=1,
                       usecols=(2, 3, 4, 5))
    tg = gt[:, 0] / 1000.0
    errs = []
    for s in sols:
        j = int(np.argmin(np.abs(tg - s.t_s)))
        if abs(tg[j] - s.t_s) < 0.05 and s.status == "single":
            e = ecef2enu_deg(s.pos_ecef_m, gt[j, 1], gt[j, 2], gt[j, 3])
            errs.append(np.hypot(e[0], e[1]))
    assert len(errs) > 0.95 * len(sols)
    p50, p95 = np.percentile(errs, [50, 95])
    return float(p50), float(p95)


@pytest.fixture(scope="module")
def pixel(shared_data: Path) -> tuple:
    b = read_rinex_obs(shared_data / PIXEL / "supplemental/Pixel5_GnssLog.21o")
    nav = read_rinex_nav(shared_data / PIXEL / "supplemental/hour1180.21n")
    return b, EphemerisSource(nav), SppConfig(elev_mask_deg=10.0)


def test_pixel5_wls_horizontal_error(shared_data: Path, pixel: tuple) -> None:
    b, eph, cfg = pixel
    p50, p95 = _pixel_errors(shared_data, solve_spp(b, eph, cfg))
    print(f"\nPixel5 WLS+FDE: p50 {p50:.2f} m, p95 {p95:.2f} m, mean {(p50 + p95) / 2:.2f} m")
    assert p50 < 9.0 and p95 < 30.0


def test_pixel5_robust_kalman_beats_wls(shared_data: Path, pixel: tuple) -> None:
    b, eph, cfg = pixel
    p50, p95 = _pixel_errors(shared_data, solve_spp_kalman(b, eph, cfg))
    w50, w95 = _pixel_errors(shared_data, solve_spp(b, eph, cfg))
    print(f"\nPixel5 robust EKF: p50 {p50:.2f} m, p95 {p95:.2f} m, mean {(p50 + p95) / 2:.2f} m")
    assert (p50 + p95) / 2 < 10.0
    assert (p50 + p95) < 0.7 * (w50 + w95)


def test_kalman_states_are_finite_and_used(pixel: tuple) -> None:
    """Kalman clocks per system are finite and the code innovations are used (n_used >= 4)."""
    b, eph, cfg = pixel
    sols = solve_spp_kalman(b, eph, cfg)[:50]
    assert all(s.n_used >= 4 for s in sols if s.status == "single")
    assert all(np.isfinite(s.clock_m["G"]) for s in sols)
    v = np.array([s.vel_ecef_m_s for s in sols])
    assert np.all(np.isfinite(v))
