"""Line-of-sight geometry: ranges with Sagnac, azimuth/elevation, DOP."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk.core import CLIGHT
from robustrtk.geometry.frames import ecef2enu_rotation, ecef2geodetic, geodetic2ecef
from robustrtk.geometry.los import (
    OMEGA_E_RAD_S,
    azimuth_elevation,
    azimuth_elevation_rot,
    dop,
    elevation_rot,
    geometric_range,
)


def test_az_el_match_vendor(shared_data: Path) -> None:
    path = shared_data / "android_parser_fixtures/google_decimeter_2022/device_gnss.csv"
    with open(path, newline="") as fh:
        rows = [r for r in csv.DictReader(fh) if r["SvPositionXEcefMeters"]]
    sat = np.array([[float(r[f"SvPosition{a}EcefMeters"]) for a in "XYZ"] for r in rows])
    rx = np.array([float(rows[0][f"WlsPosition{a}EcefMeters"]) for a in "XYZ"])
    az, el = azimuth_elevation(sat, rx)
    ref_el = np.array([float(r["SvElevationDegrees"]) for r in rows])
    ref_az = np.array([float(r["SvAzimuthDegrees"]) for r in rows])
    assert np.abs(np.degrees(el) - ref_el).max() < 1e-3
    daz = np.angle(np.exp(1j * (az - np.radians(ref_az))))
    assert np.degrees(np.abs(daz)).max() < 1e-2


def test_sagnac_matches_exact_rotation() -> None:
    rng = np.random.default_rng(7)
    rx = geodetic2ecef(0.6, -2.0, 30.0)
    sat = rng.normal(size=(50, 3))
    sat = sat / np.linalg.norm(sat, axis=1)[:, None] * 26.56e6
    rho, unit = geometric_range(sat, rx)
    # exact: rotate the satellite by we * tau into the frame at reception, iterate tau
    tau = np.linalg.norm(sat - rx, axis=1) / CLIGHT
    for _ in range(5):
        a = OMEGA_E_RAD_S * tau
        rot = np.stack(
            [
                sat[:, 0] * np.cos(a) + sat[:, 1] * np.sin(a),
                -sat[:, 0] * np.sin(a) + sat[:, 1] * np.cos(a),
                sat[:, 2],
            ],
            axis=1,
        )
        tau = np.linalg.norm(rot - rx, axis=1) / CLIGHT
    exact = tau * CLIGHT
    np.testing.assert_allclose(rho, exact, atol=1e-3)
    # the correction itself is tens of metres at most, non-zero in general
    plain = np.linalg.norm(sat - rx, axis=1)
    assert 1.0 < np.abs(rho - plain).max() < 50.0
    np.testing.assert_allclose(np.linalg.norm(unit, axis=1), 1.0)


def test_az_el_cardinal_directions() -> None:
    lat, lon = 0.5, 1.0
    rx = geodetic2ecef(lat, lon, 0.0)
    up = geodetic2ecef(lat, lon, 2.0e7)
    north = geodetic2ecef(lat + 1e-3, lon, 0.0)
    east = geodetic2ecef(lat, lon + 1e-3, 0.0)
    az, el = azimuth_elevation(np.stack([up, north, east]), rx)
    assert el[0] == pytest.approx(np.pi / 2, abs=1e-9)
    assert az[1] == pytest.approx(0.0, abs=1e-6) or az[1] == pytest.approx(2 * np.pi, abs=1e-6)
    assert az[2] == pytest.approx(np.pi / 2, abs=1e-3)
    assert abs(el[1]) < 1e-3 and abs(el[2]) < 1e-3


def _ecef_gdop(unit_enu: np.ndarray) -> float:
    g = np.hstack([-unit_enu, np.ones((len(unit_enu), 1))])
    return float(np.sqrt(np.trace(np.linalg.inv(g.T @ g))))


@settings(max_examples=100, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(5, 15))
def test_dop_properties(seed: int, n: int) -> None:
    rng = np.random.default_rng(seed)
    az = rng.uniform(0, 2 * np.pi, n)
    el = rng.uniform(np.radians(10), np.radians(85), n)
    d = dop(az, el)
    unit = np.stack([np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)], axis=1)
    assert d["gdop"] == pytest.approx(_ecef_gdop(unit), rel=1e-9)
    assert d["pdop"] ** 2 == pytest.approx(d["hdop"] ** 2 + d["vdop"] ** 2, rel=1e-9)
    assert d["gdop"] ** 2 == pytest.approx(d["pdop"] ** 2 + d["tdop"] ** 2, rel=1e-9)
    # one more satellite never degrades the geometry
    d2 = dop(np.r_[az, 1.0], np.r_[el, 0.7])
    assert d2["gdop"] <= d["gdop"] + 1e-12
    # a second clock (system) never improves it
    sys = ["G"] * (n - 2) + ["E"] * 2
    assert dop(az, el, sys)["pdop"] >= d["pdop"] - 1e-12


def test_dop_degenerate() -> None:
    assert np.isnan(dop([0.0, 1.0, 2.0], [0.5, 0.6, 0.7])["gdop"])
    # all satellites in the same direction: singular
    assert np.isnan(dop([1.0] * 6, [0.5] * 6)["pdop"])


@settings(max_examples=40, deadline=None)
@given(lat=st.floats(-89.0, 89.0), lon=st.floats(-180.0, 180.0), seed=st.integers(0, 2**32 - 1))
def test_rotation_given_variants_give_the_same_numbers(lat: float, lon: float, seed: int) -> None:
    rx = geodetic2ecef(np.deg2rad(lat), np.deg2rad(lon), 100.0)
    sat = np.random.default_rng(seed).normal(0.0, 2.6e7, (12, 3))
    la, lo, _ = ecef2geodetic(rx)
    rot = ecef2enu_rotation(float(la), float(lo))
    az, el = azimuth_elevation(sat, rx)
    az2, el2 = azimuth_elevation_rot(sat, rx, rot)
    np.testing.assert_array_equal(az2, az)
    np.testing.assert_array_equal(el2, el)
    np.testing.assert_array_equal(elevation_rot(sat, rx, rot), el)
    assert np.all(np.abs(el) <= np.pi / 2)
