"""Tests of WGS84 frame conversions."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk.geometry.frames import (
    WGS84_A_M,
    WGS84_B_M,
    ecef2enu,
    ecef2enu_deg,
    ecef2enu_rotation,
    ecef2enu_vector,
    ecef2geodetic,
    ecef2geodetic_deg,
    enu2ecef,
    enu2ecef_vector,
    geodetic2ecef,
    geodetic2ecef_deg,
)


def _vectors(shared_data: Path) -> dict:
    return json.loads((shared_data / "testvectors" / "testvectors.json").read_text())


def test_ecef2geodetic_reference_vector(shared_data: Path) -> None:
    v = _vectors(shared_data)["coord_ecef2pos"]
    lat, lon, h = ecef2geodetic_deg(np.array(v["ecef"]))
    assert abs(lat - v["lat_deg"]) < v["tol_deg"]
    assert abs(lon - v["lon_deg"]) < v["tol_deg"]
    assert abs(h - v["h_m"]) < v["tol_h"]
    # and back
    r = geodetic2ecef_deg(v["lat_deg"], v["lon_deg"], v["h_m"])
    np.testing.assert_allclose(r, v["ecef"], atol=2e-3)


def test_ecef2enu_reference_vector(shared_data: Path) -> None:
    v = _vectors(shared_data)["coord_ecef2enu"]
    lat, lon = np.radians(v["pos_deg"][:2])
    enu = ecef2enu_vector(np.array(v["r"]), lat, lon)
    np.testing.assert_allclose(enu, v["enu"], atol=v["tol"])
    np.testing.assert_allclose(enu2ecef_vector(enu, lat, lon), v["r"], atol=1e-12)


def test_known_points() -> None:
    r = geodetic2ecef(0.0, 0.0, 0.0)
    np.testing.assert_allclose(r, [WGS84_A_M, 0, 0], atol=1e-9)
    r = geodetic2ecef(np.pi / 2, 0.3, 10.0)
    np.testing.assert_allclose(r, [0, 0, WGS84_B_M + 10.0], atol=1e-8)
    lat, lon, h = ecef2geodetic(np.array([0.0, 0.0, -WGS84_B_M + 5.0]))
    assert lat == pytest.approx(-np.pi / 2, abs=1e-15)
    assert h == pytest.approx(-5.0, abs=1e-8)
    lat, lon, h = ecef2geodetic(np.array([-WGS84_A_M - 3.0, 0.0, 0.0]))
    assert lat == pytest.approx(0.0, abs=1e-15)
    assert abs(lon) == pytest.approx(np.pi, abs=1e-15)
    assert h == pytest.approx(3.0, abs=1e-8)


def test_edge_cases_round_trip() -> None:
    lat = np.array([np.pi / 2, -np.pi / 2, 0.0, 0.0, 1e-10, np.pi / 2 - 1e-10, 0.7, -0.3])
    lon = np.array([0.0, 1.0, np.pi, -np.pi, 0.5, -2.0, np.pi, -np.pi])
    h = np.array([0.0, -50.0, -1000.0, 25.0, 3.0e7, -4000.0, -10.0, 2.0e4])
    r = geodetic2ecef(lat, lon, h)
    la, lo, hh = ecef2geodetic(r)
    np.testing.assert_allclose(la, lat, atol=1e-14)
    np.testing.assert_allclose(hh, h, atol=1e-8)
    # longitude: +pi and -pi are the same meridian; compare on the circle (not at poles)
    not_pole = np.abs(np.cos(lat)) > 1e-9
    dlon = np.angle(np.exp(1j * (lo - lon)))
    np.testing.assert_allclose(dlon[not_pole], 0.0, atol=1e-14)
    np.testing.assert_allclose(geodetic2ecef(la, lo, hh), r, atol=1e-8)


def test_vectorised_shapes() -> None:
    rng = np.random.default_rng(3)
    lat = rng.uniform(-1.5, 1.5, (4, 5))
    lon = rng.uniform(-3, 3, (4, 5))
    h = rng.uniform(-100, 1e4, (4, 5))
    r = geodetic2ecef(lat, lon, h)
    assert r.shape == (4, 5, 3)
    la, lo, hh = ecef2geodetic(r)
    assert la.shape == (4, 5)
    np.testing.assert_allclose(hh, h, atol=1e-8)
    enu = ecef2enu(r, 0.6, -2.1, 30.0)
    assert enu.shape == (4, 5, 3)
    np.testing.assert_allclose(enu2ecef(enu, 0.6, -2.1, 30.0), r, atol=1e-8)


def test_rotation_orthonormal_and_up_is_normal() -> None:
    lat, lon = 0.62, 2.44
    R = ecef2enu_rotation(lat, lon)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-15)
    assert np.linalg.det(R) == pytest.approx(1.0)
    # moving up along the ellipsoid normal changes only U
    d = geodetic2ecef(lat, lon, 100.0) - geodetic2ecef(lat, lon, 0.0)
    np.testing.assert_allclose(R @ d, [0, 0, 100.0], atol=1e-8)
    # moving north along the meridian by a tiny angle gives +N, no E
    d = geodetic2ecef(lat + 1e-7, lon, 0.0) - geodetic2ecef(lat, lon, 0.0)
    enu = R @ d
    assert enu[1] > 0 and abs(enu[0]) < 1e-9 and abs(enu[2]) < 1e-4
    # covariance rotation keeps the trace
    C = np.diag([1.0, 4.0, 9.0])
    assert np.trace(R @ C @ R.T) == pytest.approx(14.0)


def test_degree_helpers_match_radians() -> None:
    r = geodetic2ecef_deg(35.0, 139.0, 40.0)
    np.testing.assert_allclose(r, geodetic2ecef(np.radians(35.0), np.radians(139.0), 40.0))
    enu = ecef2enu_deg(r + 1.0, 35.0, 139.0, 40.0)
    np.testing.assert_allclose(enu, ecef2enu(r + 1.0, np.radians(35.0), np.radians(139.0), 40.0))


@settings(max_examples=300, deadline=None)
@given(
    lat=st.floats(-np.pi / 2, np.pi / 2),
    lon=st.floats(-np.pi, np.pi),
    h=st.floats(-1.0e4, 4.5e7),
)
def test_geodetic_round_trip(lat: float, lon: float, h: float) -> None:
    r = geodetic2ecef(lat, lon, h)
    la, lo, hh = ecef2geodetic(r)
    # float64 rounding of coordinates of size |r| bounds what is achievable (the height is
    # a difference of terms of size |r|: a few ulps of |r|)
    tol_m = 1e-9 + 2e-15 * float(np.linalg.norm(r))
    np.testing.assert_allclose(geodetic2ecef(la, lo, hh), r, atol=tol_m)
    assert abs(hh - h) < tol_m
    assert abs(la - lat) < 1e-14 + tol_m / WGS84_B_M


@settings(max_examples=200, deadline=None)
@given(
    lat=st.floats(-np.pi / 2, np.pi / 2),
    lon=st.floats(-np.pi, np.pi),
    h=st.floats(-500.0, 9000.0),
    e=st.floats(-1e5, 1e5),
    n=st.floats(-1e5, 1e5),
    u=st.floats(-1e5, 1e5),
)
def test_enu_round_trip(lat: float, lon: float, h: float, e: float, n: float, u: float) -> None:
    enu = np.array([e, n, u])
    r = enu2ecef(enu, lat, lon, h)
    np.testing.assert_allclose(ecef2enu(r, lat, lon, h), enu, atol=1e-7)
    # distances are preserved
    r0 = geodetic2ecef(lat, lon, h)
    assert np.linalg.norm(r - r0) == pytest.approx(np.linalg.norm(enu), abs=1e-7)
