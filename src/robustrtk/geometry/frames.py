"""Coordinate frames on the WGS84 ellipsoid, vectorised over leading axes ``(..., 3)``.

Conventions: geodetic latitude/longitude in radians, ellipsoidal height in metres; ECEF in
metres; local East-North-Up (ENU) in metres. Degree helpers wrap the radian functions.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from robustrtk.core import FloatArray

#: WGS84 semi-major axis (m).
WGS84_A_M = 6_378_137.0
#: WGS84 flattening.
WGS84_F = 1.0 / 298.257223563
#: WGS84 semi-minor axis (m).
WGS84_B_M = WGS84_A_M * (1.0 - WGS84_F)
#: First eccentricity squared.
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)
#: Second eccentricity squared.
WGS84_EP2 = WGS84_E2 / (1.0 - WGS84_E2)

ArrayLike = npt.ArrayLike


def geodetic2ecef(lat_rad: ArrayLike, lon_rad: ArrayLike, h_m: ArrayLike) -> FloatArray:
    """Geodetic coordinates to ECEF.

    ``N = a / sqrt(1 - e^2 sin^2(lat))``;
    ``x = (N + h) cos(lat) cos(lon)``, ``y = (N + h) cos(lat) sin(lon)``,
    ``z = (N (1 - e^2) + h) sin(lat)``.

    Parameters
    ----------
    lat_rad, lon_rad, h_m : array_like, broadcastable shapes ``S``

    Returns
    -------
    pos_ecef_m : ndarray, shape ``S + (3,)``
    """
    lat = np.asarray(lat_rad, dtype=float)
    lon = np.asarray(lon_rad, dtype=float)
    h = np.asarray(h_m, dtype=float)
    lat, lon, h = np.broadcast_arrays(lat, lon, h)
    s, c = np.sin(lat), np.cos(lat)
    n = WGS84_A_M / np.sqrt(1.0 - WGS84_E2 * s * s)
    x = (n + h) * c * np.cos(lon)
    y = (n + h) * c * np.sin(lon)
    z = (n * (1.0 - WGS84_E2) + h) * s
    return np.stack([x, y, z], axis=-1)


def ecef2geodetic(pos_ecef_m: ArrayLike, n_iter: int = 4) -> tuple[FloatArray, FloatArray, FloatArray]:
    """ECEF to geodetic latitude, longitude (rad) and ellipsoidal height (m).

    Bowring's iteration on the parametric latitude ``beta`` written with ``atan2`` so that
    poles and the equator need no special case::

        beta_0 = atan2(z, (1 - f) p),   p = sqrt(x^2 + y^2)
        lat    = atan2(z + e'^2 b sin^3(beta), p - e^2 a cos^3(beta))
        beta   = atan2((1 - f) sin(lat), cos(lat))

    The error shrinks roughly cubically; four iterations reach well below 1e-9 m for points
    from the Earth's crust to GNSS orbits. Height uses the formula valid at all latitudes
    ``h = p cos(lat) + z sin(lat) - a sqrt(1 - e^2 sin^2(lat))``.

    Parameters
    ----------
    pos_ecef_m : array_like, shape (..., 3)

    Returns
    -------
    lat_rad, lon_rad, h_m : ndarray, shape (...)
    """
    r = np.asarray(pos_ecef_m, dtype=float)
    x, y, z = r[..., 0], r[..., 1], r[..., 2]
    p = np.hypot(x, y)
    lon = np.arctan2(y, x)
    beta = np.arctan2(z, (1.0 - WGS84_F) * p)
    lat = beta
    for _ in range(n_iter):
        sb, cb = np.sin(beta), np.cos(beta)
        lat = np.arctan2(z + WGS84_EP2 * WGS84_B_M * sb**3, p - WGS84_E2 * WGS84_A_M * cb**3)
        beta = np.arctan2((1.0 - WGS84_F) * np.sin(lat), np.cos(lat))
    s, c = np.sin(lat), np.cos(lat)
    h = p * c + z * s - WGS84_A_M * np.sqrt(1.0 - WGS84_E2 * s * s)
    return lat, lon, h


def ecef2enu_rotation(lat_rad: ArrayLike, lon_rad: ArrayLike) -> FloatArray:
    """Rotation ``R`` with ``enu = R @ d_ecef``; covariances rotate as ``R C R^T``.

    ``R = [[-sin(lon), cos(lon), 0],
           [-sin(lat) cos(lon), -sin(lat) sin(lon), cos(lat)],
           [cos(lat) cos(lon), cos(lat) sin(lon), sin(lat)]]``.

    Parameters
    ----------
    lat_rad, lon_rad : float or array_like, broadcastable shapes ``S``
        Geodetic latitude and longitude (rad).

    Returns
    -------
    rot : ndarray, shape ``S + (3, 3)``
        ``(3, 3)`` for scalars; one rotation per point otherwise (apply to ``(..., 3)``
        vectors with ``np.einsum("...ij,...j->...i", rot, d)``).
    """
    lat = np.asarray(lat_rad, dtype=float)
    lon = np.asarray(lon_rad, dtype=float)
    if lat.ndim == 0 and lon.ndim == 0:  # scalar fast path (per-epoch callers)
        sl, cl = np.sin(lat_rad), np.cos(lat_rad)
        so, co = np.sin(lon_rad), np.cos(lon_rad)
        return np.array(
            [
                [-so, co, 0.0],
                [-sl * co, -sl * so, cl],
                [cl * co, cl * so, sl],
            ],
            dtype=float,
        )
    lat, lon = np.broadcast_arrays(lat, lon)
    sl, cl = np.sin(lat), np.cos(lat)
    so, co = np.sin(lon), np.cos(lon)
    z = np.zeros_like(sl)
    return np.stack(
        [
            np.stack([-so, co, z], axis=-1),
            np.stack([-sl * co, -sl * so, cl], axis=-1),
            np.stack([cl * co, cl * so, sl], axis=-1),
        ],
        axis=-2,
    )


def ecef2enu(pos_ecef_m: ArrayLike, ref_lat_rad: float, ref_lon_rad: float, ref_h_m: float) -> FloatArray:
    """ECEF points to local ENU about a geodetic reference point.

    ``enu = R(lat0, lon0) (r - r0)`` with ``r0 = geodetic2ecef(lat0, lon0, h0)``.

    Parameters
    ----------
    pos_ecef_m : array_like, shape (..., 3)

    Returns
    -------
    enu_m : ndarray, shape (..., 3)
    """
    r = np.asarray(pos_ecef_m, dtype=float)
    r0 = geodetic2ecef(ref_lat_rad, ref_lon_rad, ref_h_m)
    rot = ecef2enu_rotation(ref_lat_rad, ref_lon_rad)
    return (r - r0) @ rot.T


def enu2ecef(enu_m: ArrayLike, ref_lat_rad: float, ref_lon_rad: float, ref_h_m: float) -> FloatArray:
    """Local ENU to ECEF: ``r = r0 + R^T enu`` (inverse of :func:`ecef2enu`).

    Parameters
    ----------
    enu_m : array_like, shape (..., 3)

    Returns
    -------
    pos_ecef_m : ndarray, shape (..., 3)
    """
    e = np.asarray(enu_m, dtype=float)
    r0 = geodetic2ecef(ref_lat_rad, ref_lon_rad, ref_h_m)
    rot = ecef2enu_rotation(ref_lat_rad, ref_lon_rad)
    return e @ rot + r0


def ecef2enu_vector(d_ecef_m: ArrayLike, ref_lat_rad: float, ref_lon_rad: float) -> FloatArray:
    """Rotate ECEF difference vectors ``(..., 3)`` into ENU (no translation)."""
    return np.asarray(d_ecef_m, dtype=float) @ ecef2enu_rotation(ref_lat_rad, ref_lon_rad).T


def enu2ecef_vector(d_enu_m: ArrayLike, ref_lat_rad: float, ref_lon_rad: float) -> FloatArray:
    """Rotate ENU vectors ``(..., 3)`` into ECEF differences (no translation)."""
    return np.asarray(d_enu_m, dtype=float) @ ecef2enu_rotation(ref_lat_rad, ref_lon_rad)


def geodetic2ecef_deg(lat_deg: ArrayLike, lon_deg: ArrayLike, h_m: ArrayLike) -> FloatArray:
    """:func:`geodetic2ecef` with latitude and longitude in degrees."""
    return geodetic2ecef(np.radians(lat_deg), np.radians(lon_deg), h_m)


def ecef2geodetic_deg(pos_ecef_m: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
    """:func:`ecef2geodetic` returning latitude and longitude in degrees."""
    lat, lon, h = ecef2geodetic(pos_ecef_m)
    return np.degrees(lat), np.degrees(lon), h


def ecef2enu_deg(pos_ecef_m: ArrayLike, ref_lat_deg: float, ref_lon_deg: float, ref_h_m: float) -> FloatArray:
    """:func:`ecef2enu` with the reference latitude and longitude in degrees."""
    return ecef2enu(pos_ecef_m, float(np.radians(ref_lat_deg)), float(np.radians(ref_lon_deg)), ref_h_m)


def enu2ecef_deg(enu_m: ArrayLike, ref_lat_deg: float, ref_lon_deg: float, ref_h_m: float) -> FloatArray:
    """:func:`enu2ecef` with the reference latitude and longitude in degrees."""
    return enu2ecef(enu_m, float(np.radians(ref_lat_deg)), float(np.radians(ref_lon_deg)), ref_h_m)
