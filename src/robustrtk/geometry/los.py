"""Line of sight: geometric range with the Sagnac correction, azimuth/elevation, DOP."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from robustrtk.core import CLIGHT, FloatArray, row_norms
from robustrtk.geometry.frames import ecef2enu_rotation, ecef2geodetic

#: Earth rotation rate (WGS84, rad/s): Sagnac correction and GPS/QZSS/Galileo orbits.
OMEGA_E_RAD_S = 7.2921151467e-5


def geometric_range(sat_ecef_m: npt.ArrayLike, rx_ecef_m: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Receiver-satellite range including the Earth-rotation (Sagnac) correction.

    The satellite position is ECEF at transmission time; during the travel time the frame
    rotates by ``we tau``. To first order::

        rho = |r_s - r_r| + we (x_s y_r - y_s x_r) / c

    (the exact rotation differs by < 1 mm for GNSS ranges).

    Parameters
    ----------
    sat_ecef_m : array_like, shape (..., 3)
        Satellite positions (ECEF at transmission time).
    rx_ecef_m : array_like, shape (3,) or (..., 3)
        Receiver position (ECEF at reception time).

    Returns
    -------
    range_m : ndarray, shape (...)
    unit_los : ndarray, shape (..., 3)
        Unit vector from receiver to satellite (``(r_s - r_r) / |r_s - r_r|``).
    """
    rs = np.asarray(sat_ecef_m, dtype=float)
    rr = np.asarray(rx_ecef_m, dtype=float)
    d = rs - rr
    dist = row_norms(d)  # np.linalg.norm(d, axis=-1), the same numbers
    sagnac = OMEGA_E_RAD_S * (rs[..., 0] * rr[..., 1] - rs[..., 1] * rr[..., 0]) / CLIGHT
    unit = d / dist[..., None]
    return dist + sagnac, unit


def azimuth_elevation(sat_ecef_m: npt.ArrayLike, rx_ecef_m: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Azimuth (from north, clockwise, in [0, 2 pi)) and elevation of satellites.

    ``enu = R(lat, lon) (r_s - r_r)``, ``az = atan2(e, n)``, ``el = asin(u / |enu|)``.

    Parameters
    ----------
    sat_ecef_m : array_like, shape (..., 3)
    rx_ecef_m : array_like, shape (3,)

    Returns
    -------
    az_rad, elev_rad : ndarray, shape (...)
    """
    rr = np.asarray(rx_ecef_m, dtype=float)
    lat, lon, _ = ecef2geodetic(rr)
    return azimuth_elevation_rot(sat_ecef_m, rr, ecef2enu_rotation(float(lat), float(lon)))


def azimuth_elevation_rot(
    sat_ecef_m: npt.ArrayLike, rx_ecef_m: npt.ArrayLike, rot: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """:func:`azimuth_elevation` with the receiver's ECEF → ENU rotation given.

    Parameters
    ----------
    sat_ecef_m : array_like, shape (..., 3)
    rx_ecef_m : array_like, shape (3,)
    rot : ndarray, shape (3, 3)
        :func:`~robustrtk.geometry.frames.ecef2enu_rotation` at the receiver's geodetic
        latitude and longitude (kept by a caller that asks about the same receiver often).

    Returns
    -------
    az_rad, elev_rad : ndarray, shape (...)
        The numbers of :func:`azimuth_elevation`.
    """
    rr = np.asarray(rx_ecef_m, dtype=float)
    enu = (np.asarray(sat_ecef_m, dtype=float) - rr) @ rot.T
    rho = np.linalg.norm(enu, axis=-1)
    az = np.mod(np.arctan2(enu[..., 0], enu[..., 1]), 2.0 * np.pi)
    el = np.arcsin(np.clip(enu[..., 2] / rho, -1.0, 1.0))
    return az, el


def elevation_rot(sat_ecef_m: npt.ArrayLike, rx_ecef_m: npt.ArrayLike, rot: FloatArray) -> FloatArray:
    """The elevations of :func:`azimuth_elevation_rot` alone (the same numbers; no azimuth).

    Parameters
    ----------
    sat_ecef_m : array_like, shape (..., 3)
    rx_ecef_m : array_like, shape (3,)
    rot : ndarray, shape (3, 3)
        ECEF → ENU rotation at the receiver.

    Returns
    -------
    elev_rad : ndarray, shape (...)
    """
    rr = np.asarray(rx_ecef_m, dtype=float)
    enu = (np.asarray(sat_ecef_m, dtype=float) - rr) @ rot.T
    rho = row_norms(enu)
    # np.clip's numbers (NaN and signed zeros kept), without its generic dispatch
    return np.arcsin(np.minimum(np.maximum(enu[..., 2] / rho, -1.0), 1.0))


def dop(
    az_rad: npt.ArrayLike, elev_rad: npt.ArrayLike, systems: Sequence[str] | None = None
) -> dict[str, float]:
    """Dilution of precision from azimuths and elevations.

    Design rows in ENU ``g = [-cos(el) sin(az), -cos(el) cos(az), -sin(el), 1_sys]`` with one
    clock column per system (one in total when ``systems`` is None); ``Q = (G^T G)^-1``.

    Returns
    -------
    dict with ``gdop, pdop, hdop, vdop, tdop`` (``tdop`` from the first clock column); all
    NaN when fewer rows than unknowns or the geometry is singular.
    """
    az = np.asarray(az_rad, dtype=float).ravel()
    el = np.asarray(elev_rad, dtype=float).ravel()
    sys_list = ["_"] * az.size if systems is None else list(systems)
    labels = sorted(set(sys_list))
    g = np.zeros((az.size, 3 + len(labels)))
    g[:, 0] = -np.cos(el) * np.sin(az)
    g[:, 1] = -np.cos(el) * np.cos(az)
    g[:, 2] = -np.sin(el)
    for j, lab in enumerate(labels):
        g[:, 3 + j] = [1.0 if s == lab else 0.0 for s in sys_list]
    nan = {k: float("nan") for k in ("gdop", "pdop", "hdop", "vdop", "tdop")}
    if az.size < g.shape[1]:
        return nan
    n = g.T @ g
    if np.linalg.cond(n) > 1e12:
        return nan
    q = np.linalg.inv(n)
    d = np.diag(q)
    return {
        "gdop": float(np.sqrt(np.trace(q))),
        "pdop": float(np.sqrt(d[0] + d[1] + d[2])),
        "hdop": float(np.sqrt(d[0] + d[1])),
        "vdop": float(np.sqrt(d[2])),
        "tdop": float(np.sqrt(d[3])),
    }
