"""SPP: synthetic recovery and fault exclusion, and the Pixel 5 drive against SPAN truth."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.geometry.frames import ecef2enu_deg, ecef2enu_rotation
from robustrtk.geometry.los import geometric_range
from robustrtk.io.rinex_nav import read_rinex_nav
from robustrtk.io.rinex_obs import read_rinex_obs
from robustrtk.pipeline.config import preset
from robustrtk.pipeline.spp import select_band1, solve_spp, solve_spp_kalman
from robustrtk.pipeline.spp_kalman import spp_signals

PIXEL = "gsdc2021_mtv1_pixel5_phone/Pixel5"
GEONET = "geonet_0759_3040_static_3km"


def _synthetic(shared: Path, fault_m: float) -> tuple:
    """Noise-free pseudoranges of the geonet rover epochs from the broadcast orbits."""
    nav = read_rinex_nav(shared / GEONET / "30400920.05n")
    eph = EphemerisSource(nav)
    b = select_band1(read_rinex_obs(shared / GEONET / "07590920.05o"))
    b = replace(
        b,
        t_s=b.t_s[:5],
        code_m=b.code_m[:5].copy(),
        phase_cyc=b.phase_cyc[:5],
        doppler_hz=b.doppler_hz[:5],
        cn0_dbhz=b.cn0_dbhz[:5],
        lli=b.lli[:5],
    )
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
    cfg = preset("spp").updated(iono="off", tropo="off", code_sigma_m=0.3, use_cn0=False, elev_mask_deg=0.0)
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
    without = solve_spp(b, eph, cfg.updated(raim=False))
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


def _kalman_synthetic(shared: Path, code_fault_m: float = 0.0, slip_cyc: float = 0.0) -> tuple:
    """Ten geonet epochs with noise-free code and carrier phase of a static receiver (no
    atmosphere, Doppler absent, loss-of-lock flags clear). ``code_fault_m`` is added to the
    code of satellite row 3 at every epoch, ``slip_cyc`` to its phase from epoch 5 on."""
    eph = EphemerisSource(read_rinex_nav(shared / GEONET / "30400920.05n"))
    b0 = select_band1(read_rinex_obs(shared / GEONET / "07590920.05o"))
    n, m = 10, len(b0.tx_ids)
    b = replace(
        b0,
        t_s=b0.t_s[:n],
        code_m=b0.code_m[:n].copy(),
        phase_cyc=np.full((n, m, 1), np.nan),
        doppler_hz=np.full((n, m, 1), np.nan),
        cn0_dbhz=b0.cn0_dbhz[:n],
        lli=np.zeros((n, m, 1)),
    )
    truth = np.array([-3976219.1879, 3382371.6056, 3652511.1425])
    clk_m = 12345.6
    bias_m = np.random.default_rng(7).uniform(-1e5, 1e5, size=m)
    wl = b.wavelength_m[:, 0]
    for i in range(n):
        have = np.isfinite(b.code_m[i, :, 0])
        ids = [b.tx_ids[j] for j in np.flatnonzero(have)]
        code = b.code_m[i, have, 0]
        for _ in range(3):
            pos, sat_clk = eph.positions(float(b.t_s[i]), ids, code)
            rng, _ = geometric_range(pos, truth)
            code = rng + clk_m - sat_clk
        b.code_m[i, have, 0] = code
        # phase clock 3 m/epoch away from the code clock, one arbitrary bias per satellite
        b.phase_cyc[i, have, 0] = (rng + clk_m + 3.0 * i + bias_m[have] - sat_clk) / wl[have]
    b.code_m[:, 3, 0] += code_fault_m
    b.phase_cyc[5:, 3, 0] += slip_cyc
    cfg = preset("spp").updated(
        filter="ekf",
        iono="off",
        tropo="off",
        code_sigma_m=0.3,
        use_cn0=False,
        elev_mask_deg=0.0,
        use_doppler=False,
        dual_frequency=False,
    )
    return b, eph, truth, cfg


def test_kalman_recovers_synthetic_code_and_phase(shared_data: Path) -> None:
    b, eph, truth, cfg = _kalman_synthetic(shared_data)
    sols = solve_spp_kalman(b, eph, cfg)
    for s in sols:
        assert s.status == "single" and s.excluded == ()
        assert np.linalg.norm(s.pos_ecef_m - truth) < 0.01


def test_kalman_rejects_a_faulty_code(shared_data: Path) -> None:
    b, eph, truth, cfg = _kalman_synthetic(shared_data, code_fault_m=60.0)
    bad = f"{b.tx_ids[3]}:P1"
    plain = solve_spp_kalman(b, eph, cfg.updated(robust="none"))
    sols = solve_spp_kalman(b, eph, cfg)
    assert max(np.linalg.norm(s.pos_ecef_m - truth) for s in plain[1:]) > 1.0
    for s in sols[1:]:
        assert bad in s.excluded
        assert np.linalg.norm(s.pos_ecef_m - truth) < 0.05


def test_kalman_restarts_an_arc_after_an_unflagged_slip(shared_data: Path) -> None:
    """Seven cycles added to one phase from epoch 5 with no loss-of-lock flag: rejected at
    epoch 5, accepted again (new arc) afterwards, position unharmed."""
    b, eph, truth, cfg = _kalman_synthetic(shared_data, slip_cyc=7.0)
    lab = f"{b.tx_ids[3]}:L1"
    sols = solve_spp_kalman(b, eph, cfg)
    assert [lab in s.excluded for s in sols] == [False] * 5 + [True] + [False] * 4
    assert max(np.linalg.norm(s.pos_ecef_m - truth) for s in sols) < 0.05
    held = solve_spp_kalman(b, eph, cfg.updated(robust="none"))
    assert np.linalg.norm(held[5].pos_ecef_m - truth) > 0.1


def test_signal_choice_on_the_phone_trace(pixel: tuple) -> None:
    """GPS only (the navigation file holds GPS only), L1 and L5 columns, zero phases absent."""
    b, eph, _ = pixel
    sig = spp_signals(b, eph.nav, True)
    assert sig.systems == ("G",)
    g06 = sig.ids.index("G06")
    assert sig.band[g06] == ("1", "5")
    assert not np.isfinite(sig.code_m[:, sig.ids.index("G02"), 1]).any()  # no L5 on a IIR-M satellite
    raw = b.phase_cyc[:, b.tx_ids.index("G06"), :]
    assert np.isfinite(sig.phase_cyc[:, g06, :]).sum() == (np.abs(raw) >= 1e-3).sum()
    assert np.isfinite(raw).sum() > np.isfinite(sig.phase_cyc[:, g06, :]).sum()


def _pixel_errors(shared: Path, sols: list) -> tuple[float, float]:
    """50th and 95th percentiles of the horizontal error against the SPAN truth (m).

    The truth's time tags are GPS milliseconds (equal to the SPAN UTC tags + 18 s); its
    heights are 65 m above the ellipsoid (geoid undulation added with the wrong sign), which
    does not change the horizontal error computed in the truth point's local frame.
    """
    gt = np.genfromtxt(
        shared / PIXEL / "ground_truth.csv", delimiter=",", skip_header=1, usecols=(2, 3, 4, 5)
    )
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
    return b, EphemerisSource(nav), preset("spp").updated(elev_mask_deg=10.0)


@pytest.fixture(scope="module")
def pixel_kalman(pixel: tuple) -> dict[str, list]:
    """Kalman SPP runs on the phone trace with the default settings (shared by tests)."""
    b, eph, _ = pixel
    return {
        "forward": solve_spp_kalman(b, eph),
        "smoothed": solve_spp_kalman(b, eph, preset("spp").updated(filter="ekf", smoother=True)),
    }


def test_pixel5_wls_horizontal_error(shared_data: Path, pixel: tuple) -> None:
    b, eph, cfg = pixel
    p50, p95 = _pixel_errors(shared_data, solve_spp(b, eph, cfg))
    print(f"\nPixel5 WLS+FDE: p50 {p50:.2f} m, p95 {p95:.2f} m, mean {(p50 + p95) / 2:.2f} m")
    assert p50 < 9.0 and p95 < 30.0


@pytest.mark.slow
def test_pixel5_robust_kalman_gsdc_score(shared_data: Path, pixel_kalman: dict) -> None:
    """Default robust Kalman SPP (forward only, causal): mean of the horizontal p50 and p95
    (the Google Smartphone Decimeter Challenge score).

    A regression bound, not the acceptance of issue 11 (1.8 m): measured 2.24 m (p50 1.47,
    p95 3.02; 2.35 m without the Doppler σ scale of algorithms.md §41, 2.46 m with the
    elevation law for the range rates). GPS L1+L5 only (the
    navigation file has no other system) and no base station.
    """
    p50, p95 = _pixel_errors(shared_data, pixel_kalman["forward"])
    print(
        f"\nPixel5 robust Kalman SPP (forward): p50 {p50:.2f} m, p95 {p95:.2f} m, "
        f"score {(p50 + p95) / 2:.2f} m"
    )
    assert (p50 + p95) / 2 <= 2.45


@pytest.mark.slow
def test_pixel5_rts_smoother_improves_the_score(shared_data: Path, pixel_kalman: dict) -> None:
    """RTS-smoothed score: a regression bound (measured 1.90 m; the acceptance is 1.5 m)."""
    f50, f95 = _pixel_errors(shared_data, pixel_kalman["forward"])
    p50, p95 = _pixel_errors(shared_data, pixel_kalman["smoothed"])
    print(
        f"\nPixel5 robust Kalman SPP + RTS: p50 {p50:.2f} m, p95 {p95:.2f} m, score {(p50 + p95) / 2:.2f} m"
    )
    assert (p50 + p95) / 2 <= 2.05
    assert p50 + p95 < f50 + f95


def _pixel_speed_errors(shared: Path, sols: list) -> np.ndarray:
    """|horizontal speed − SPAN speed| per epoch (m/s)."""
    truth = shared / PIXEL / "ground_truth.csv"
    gt = np.genfromtxt(truth, delimiter=",", skip_header=1, usecols=(2, 3, 4, 9))
    t = np.array([s.t_s for s in sols])
    speed = np.interp(t, gt[:, 0] / 1000.0, gt[:, 3])
    lat, lon = np.deg2rad(gt[0, 1]), np.deg2rad(gt[0, 2])
    rot = ecef2enu_rotation(lat, lon)
    v = np.array([rot @ s.vel_ecef_m_s for s in sols])
    return np.abs(np.hypot(v[:, 0], v[:, 1]) - speed)


@pytest.mark.slow
def test_pixel5_cn0_range_rate_law_sharpens_the_velocity(
    shared_data: Path, pixel: tuple, pixel_kalman: dict
) -> None:
    """The C/N0 law for the range-rate variance (docs/algorithms.md §19) against the
    elevation law: the speed error against SPAN is lower (measured 0.043 vs 0.059 m/s at the
    median, 95 % 0.49 vs 0.54 m/s; before the Doppler σ scale of algorithms.md §41, which
    also sets the elevation law's level from the data: 0.050 vs 0.096, 95 % 0.41 vs 0.52)."""
    b, eph, _ = pixel
    cn0 = _pixel_speed_errors(shared_data, pixel_kalman["forward"])
    cfg = preset("spp").updated(filter="ekf", doppler_weighting="elevation")
    elev = _pixel_speed_errors(shared_data, solve_spp_kalman(b, eph, cfg))
    print(f"\nPixel5 speed error median/95 %: cn0 {np.median(cn0):.3f}/{np.percentile(cn0, 95):.3f}, "
          f"elevation {np.median(elev):.3f}/{np.percentile(elev, 95):.3f} m/s")  # fmt: skip
    assert np.median(cn0) < 0.8 * np.median(elev)
    assert np.percentile(cn0, 95) < np.percentile(elev, 95)


def test_pixel5_robust_kalman_beats_wls(shared_data: Path, pixel: tuple, pixel_kalman: dict) -> None:
    b, eph, cfg = pixel
    p50, p95 = _pixel_errors(shared_data, pixel_kalman["forward"])
    w50, w95 = _pixel_errors(shared_data, solve_spp(b, eph, cfg))
    assert (p50 + p95) < 0.3 * (w50 + w95)


def test_pixel5_band1_code_only_is_worse(shared_data: Path, pixel: tuple, pixel_kalman: dict) -> None:
    """Without carrier phase and the L5 code the same filter is clearly worse: the two are
    what brings the phone under 4 m (not a tuning of the dynamics)."""
    b, eph, _ = pixel
    p50, p95 = _pixel_errors(shared_data, pixel_kalman["forward"])
    c50, c95 = _pixel_errors(
        shared_data,
        solve_spp_kalman(select_band1(b), eph, preset("spp").updated(filter="ekf", use_phase=False)),
    )
    print(f"\nPixel5 Kalman SPP, L1 code + Doppler only: p50 {c50:.2f} m, p95 {c95:.2f} m")
    assert (c50 + c95) / 2 > 4.0
    assert p50 + p95 < 0.6 * (c50 + c95)


def test_kalman_states_are_finite_and_used(pixel: tuple, pixel_kalman: dict) -> None:
    """Kalman clocks are finite, the code innovations are used (n_used >= 4) and the
    phone's L1 and L5 carrier phases enter the update."""
    sols = pixel_kalman["forward"][:50]
    assert all(s.n_used >= 4 for s in sols if s.status == "single")
    assert all(np.isfinite(s.clock_m["G"]) for s in sols)
    v = np.array([s.vel_ecef_m_s for s in sols])
    assert np.all(np.isfinite(v))
    assert np.all(np.linalg.norm(v[:20], axis=1) < 3.0)  # the car waits at the start
