"""The batch smoother's ionosphere field (robustrtk.pipeline.spp_fgo_iono): used where the two
bands can tell it, kept where it is there."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.geometry.frames import ecef2enu_rotation, ecef2geodetic
from robustrtk.io.readers import read_navigation
from robustrtk.io.rinex_obs import read_rinex_obs
from robustrtk.pipeline.config import preset
from robustrtk.pipeline.spp_fgo import solve_spp_fgo
from robustrtk.pipeline.spp_fgo_iono import MIN_CALIBRATED_PER_EPOCH, field_observable, shell_geometry
from robustrtk.sim.drive import grid_track, simulate_drive
from robustrtk.sim.phone import phone_profile

START_M = np.array([-3961904.939, 3348993.763, 3698211.764])  # Kamakura


def test_field_observable_needs_calibrated_two_band_satellites() -> None:
    T, N = 100, 10
    two = np.zeros((T, N), bool)
    cal = np.array([True] * 5 + [False] * 5)
    two[:, 5:] = True  # five uncalibrated (GPS L5) satellites: not enough
    assert not field_observable(two, cal)
    two[:60, :MIN_CALIBRATED_PER_EPOCH] = True  # in 60 % of the epochs four Galileo E5a
    assert field_observable(two, cal)
    two[:40] = False
    two[:, 5:] = True  # now only 20 % of the epochs
    assert not field_observable(two, cal)
    assert not field_observable(np.zeros((0, N), bool), cal)


def test_shell_geometry_at_zenith_and_horizon() -> None:
    m, dn, de = shell_geometry(np.array([np.pi / 2, np.radians(10.0)]), np.array([0.0, np.pi / 2]))
    assert m[0] == pytest.approx(1.0) and dn[0] == pytest.approx(0.0, abs=1e-9)
    assert 2.5 < m[1] < 3.5  # thin-shell mapping at 10° (the broadcast model's obliquity is ~3)
    assert de[1] > 1.0 and abs(dn[1]) < 1e-9  # east: the pierce point over 1000 km away


def _drive(shared_data: Path, iono_scale: float) -> tuple[object, EphemerisSource, np.ndarray]:
    d = shared_data / "kamakura_kinematic_5km"
    if not (d / "SEPT265G.21O").is_file():
        pytest.skip(f"kamakura_kinematic_5km not found in {shared_data}")
    layout = read_rinex_obs(d / "SEPT265G.21O")
    eph = EphemerisSource(read_navigation([d / "SEPT2650.21P"]))
    t = float(layout.t_s[0]) + np.arange(600.0)
    truth = grid_track(t, START_M, seed=2)
    clean = simulate_drive(layout, eph, t, truth, seed=2, iono_scale=iono_scale)
    return phone_profile(clean, seed=0).batch, eph, truth


def _score(sols: list, truth: np.ndarray) -> float:  # type: ignore[type-arg]
    pos = np.array([s.pos_ecef_m for s in sols])
    lat, lon, _ = ecef2geodetic(truth[0])
    e = (pos - truth) @ ecef2enu_rotation(float(lat), float(lon)).T
    h = np.hypot(e[:, 0], e[:, 1])
    return float(np.percentile(h, 50) + np.percentile(h, 95)) / 2.0


@pytest.mark.parametrize("iono_scale", [1.0, 1.6])
def test_field_kept_only_where_the_model_is_wrong(shared_data: Path, iono_scale: float) -> None:
    """Ten minutes of a simulated drive (GPS/Galileo/QZSS on two bands), phone-profiled. Where
    the broadcast model is the truth (scale 1) the field is not significant and the smoother
    is the one without it, to the bit; where the true delay is 1.6 × the model's, the field
    takes a quarter of the error away (0.20 → 0.15 m measured; 0.56 → 0.33 m on half an hour)."""
    phone, eph, truth = _drive(shared_data, iono_scale)
    cfg = preset("spp").updated(filter="ekf")
    diag: list = []  # type: ignore[type-arg]
    with_field = solve_spp_fgo(phone, eph, cfg, diagnostics=diag)
    without = solve_spp_fgo(phone, eph, cfg.updated(fgo_iono=False))
    a, b = _score(with_field, truth), _score(without, truth)
    print(f"\niono x{iono_scale}: smoother with the field {a:.3f} m, without {b:.3f} m")
    said = diag[0].ionosphere  # what the summary's "ionosphere" line says
    if iono_scale == 1.0:
        assert [s.pos_ecef_m.tolist() for s in with_field] == [s.pos_ecef_m.tolist() for s in without]
        assert "not significant" in said
    else:
        assert a < 0.8 * b
        assert "estimated error" in said
