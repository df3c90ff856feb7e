"""The software receiver of robustrtk.sim.drive against the solver's own models, and the
phone-profiled drive the batch smoother is judged on (issue 32: a simulator's drive degraded
by the phone profile)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.geometry.frames import ecef2enu_rotation, ecef2geodetic
from robustrtk.io.readers import read_navigation
from robustrtk.io.rinex_obs import read_rinex_obs
from robustrtk.pipeline.config import preset
from robustrtk.pipeline.spp import solve_spp
from robustrtk.sim.drive import grid_track, simulate_drive

START_M = np.array([-3961904.939, 3348993.763, 3698211.764])  # Kamakura


def _layout(shared_data: Path) -> tuple[object, EphemerisSource]:
    d = shared_data / "kamakura_kinematic_5km"
    if not (d / "SEPT265G.21O").is_file():
        pytest.skip(f"kamakura_kinematic_5km not found in {shared_data}")
    return read_rinex_obs(d / "SEPT265G.21O"), EphemerisSource(read_navigation([d / "SEPT2650.21P"]))


def _horizontal(pos: np.ndarray, truth: np.ndarray) -> np.ndarray:
    lat, lon, _ = ecef2geodetic(truth[0])
    e = (pos - truth) @ ecef2enu_rotation(float(lat), float(lon)).T
    return np.hypot(e[:, 0], e[:, 1])


def test_grid_track_is_a_car() -> None:
    """Speeds within the legs' limits, accelerations bounded, and it stops."""
    t = np.arange(1200.0)
    p = grid_track(t, START_M, seed=3)
    v = np.linalg.norm(np.diff(p, axis=0), axis=1)
    assert v.max() <= 14.0 + 1e-6
    assert np.percentile(np.abs(np.diff(v)), 99) <= 3.0
    assert (v < 1e-6).sum() > 20  # stops at corners
    assert np.linalg.norm(p[-1] - p[0]) > 200.0


def test_noise_free_drive_is_explained_by_the_solver_models(shared_data: Path) -> None:
    """Without noise the least-squares SPP of the simulated code returns the track to the
    millimetre: ranges, Earth rotation, satellite clocks and group delays of both bands,
    troposphere and broadcast ionosphere are the solver's own. An inconsistency in any (a
    band's group delay, the ionosphere's frequency scaling, the transmission time) moves it by
    decimetres to metres."""
    layout, eph = _layout(shared_data)
    t = float(layout.t_s[0]) + np.arange(120.0)
    truth = grid_track(t, START_M, seed=1)
    b = simulate_drive(layout, eph, t, truth, code_sigma_m=0.0, phase_sigma_m=0.0, doppler_sigma_m_s=0.0)
    assert np.isfinite(b.code_m).any(axis=(0, 1)).sum() >= 4  # L1, L2, L5 ... simulated
    sols = solve_spp(b, eph.nav, preset("spp"))
    pos = np.array([s.pos_ecef_m for s in sols])
    err = np.linalg.norm(pos - truth, axis=1)
    assert np.all(np.isfinite(err))
    assert float(np.max(err)) < 0.005, float(np.max(err))
    # the model's ionosphere doubled: metres (the check above is not blind to it)
    b2 = simulate_drive(layout, eph, t[:20], truth[:20], code_sigma_m=0.0, phase_sigma_m=0.0,
                        doppler_sigma_m_s=0.0, iono_scale=2.0)  # fmt: skip
    pos2 = np.array([s.pos_ecef_m for s in solve_spp(b2, eph.nav, preset("spp"))])
    assert float(np.median(np.linalg.norm(pos2 - truth[:20], axis=1))) > 1.0


def _gsdc_score(sols: list, truth: np.ndarray) -> float:  # type: ignore[type-arg]
    pos = np.array([s.pos_ecef_m for s in sols])
    assert all(s.status == "single" for s in sols)
    h = _horizontal(pos, truth)
    return float(np.percentile(h, 50) + np.percentile(h, 95)) / 2.0


@pytest.mark.slow
@pytest.mark.parametrize(("seed", "canyon_deg"), [(0, 0.0), (1, 30.0)])
def test_smoother_beats_the_kalman_on_a_phone_profiled_simulated_drive(
    shared_data: Path, seed: int, canyon_deg: float
) -> None:
    """Issue 32's held-out line on its own kind of data: a simulator's drive (here the software
    receiver, 15 minutes of a car on a street grid, open sky or a 30° street canyon) degraded
    by the phone profile; the batch smoother's GSDC score is at most 0.75 × the forward
    Kalman SPP's (measured 0.24–0.38 × on 20-minute drives) and not worse than the RTS."""
    from robustrtk.pipeline.spp_fgo import solve_spp_fgo
    from robustrtk.pipeline.spp_kalman import solve_spp_kalman
    from robustrtk.sim.phone import phone_profile

    layout, eph = _layout(shared_data)
    t = float(layout.t_s[0]) + np.arange(900.0)
    truth = grid_track(t, START_M, seed=seed + 1)
    clean = simulate_drive(layout, eph, t, truth, seed=seed, canyon_deg=canyon_deg)
    phone = phone_profile(clean, seed=seed).batch
    cfg = preset("spp").updated(filter="ekf")
    kalman = _gsdc_score(solve_spp_kalman(phone, eph, cfg), truth)
    rts = _gsdc_score(solve_spp_kalman(phone, eph, cfg.updated(smoother=True)), truth)
    smoother = _gsdc_score(solve_spp_fgo(phone, eph, cfg), truth)
    print(f"\nseed {seed} canyon {canyon_deg}: Kalman {kalman:.3f} RTS {rts:.3f} smoother {smoother:.3f}")
    assert smoother <= 0.75 * kalman
    assert smoother <= rts
