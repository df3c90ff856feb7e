"""Vectorised ECEF -> ENU rotation, the Earth rotation constant of the orbits."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from robustrtk.geometry.frames import ecef2enu_rotation
from robustrtk.geometry.los import OMEGA_E_RAD_S
from robustrtk.geometry.orbits import CONSTANTS

lat_st = st.floats(min_value=-np.pi / 2, max_value=np.pi / 2)
lon_st = st.floats(min_value=-np.pi, max_value=2 * np.pi)


@given(st.lists(st.tuples(lat_st, lon_st), min_size=1, max_size=8))
def test_vectorised_equals_scalar_and_is_orthonormal(points: list[tuple[float, float]]) -> None:
    lat = np.array([p[0] for p in points])
    lon = np.array([p[1] for p in points])
    rot = ecef2enu_rotation(lat, lon)
    assert rot.shape == (len(points), 3, 3)
    for i, (a, b) in enumerate(points):
        np.testing.assert_array_equal(rot[i], ecef2enu_rotation(a, b))
    eye = np.einsum("nij,nkj->nik", rot, rot)
    np.testing.assert_allclose(eye, np.broadcast_to(np.eye(3), eye.shape), atol=1e-14)
    np.testing.assert_allclose(np.linalg.det(rot), 1.0, atol=1e-14)


def test_shapes_broadcast() -> None:
    assert ecef2enu_rotation(0.1, 0.2).shape == (3, 3)
    assert ecef2enu_rotation(np.zeros((2, 4)), 0.3).shape == (2, 4, 3, 3)
    up = ecef2enu_rotation(np.pi / 2, 0.0)[2]
    np.testing.assert_allclose(up, [0.0, 0.0, 1.0], atol=1e-16)


def test_gps_galileo_orbits_use_the_wgs84_rotation_rate() -> None:
    for s in "GJE":
        assert CONSTANTS[s].omega_e_rad_s == OMEGA_E_RAD_S == 7.2921151467e-5
    assert CONSTANTS["C"].omega_e_rad_s == CONSTANTS["R"].omega_e_rad_s == 7.292115e-5
