"""Atmospheric corrections: Saastamoinen troposphere and Klobuchar ionosphere.

Both return delays in metres to be subtracted from pseudoranges (and, for the troposphere,
from carrier phases in metres).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from robustrtk.core import CLIGHT, FloatArray

#: GPS L1 frequency (Hz), the Klobuchar reference.
F_L1_HZ = 1575.42e6

ArrayLike = npt.ArrayLike


def standard_atmosphere(h_m: ArrayLike, humidity: float = 0.7) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Standard atmosphere at orthometric height ``h_m``.

    ``P = 1013.25 (1 - 2.2557e-5 h)^5.2568`` hPa, ``T = 15 - 6.5e-3 h + 273.16`` K,
    water vapour pressure ``e = 6.108 rh exp((17.15 T - 4684) / (T - 38.45))`` hPa.

    Returns
    -------
    pressure_hpa, temperature_k, vapour_hpa : ndarray, shape of ``h_m``
    """
    h = np.maximum(np.asarray(h_m, dtype=float), -500.0)
    p = 1013.25 * (1.0 - 2.2557e-5 * h) ** 5.2568
    t = 15.0 - 6.5e-3 * h + 273.16
    e = 6.108 * humidity * np.exp((17.15 * t - 4684.0) / (t - 38.45))
    return p, t, e


def tropo_zenith_saastamoinen(
    lat_rad: ArrayLike,
    h_m: ArrayLike,
    humidity: float = 0.7,
    pressure_hpa: ArrayLike | None = None,
    temperature_k: ArrayLike | None = None,
) -> tuple[FloatArray, FloatArray]:
    """Saastamoinen zenith hydrostatic and wet delays (m).

    ``ZHD = 0.0022768 P / (1 - 0.00266 cos(2 lat) - 0.00028 h_km)``,
    ``ZWD = 0.002277 (1255 / T + 0.05) e``, with the standard atmosphere unless ``P``/``T``
    are given (``e`` always from the standard-atmosphere humidity formula at ``T``).

    Returns
    -------
    zhd_m, zwd_m : ndarray, broadcast shape
    """
    lat = np.asarray(lat_rad, dtype=float)
    h = np.asarray(h_m, dtype=float)
    p, t, _ = standard_atmosphere(h, humidity)
    if pressure_hpa is not None:
        p = np.asarray(pressure_hpa, dtype=float)
    if temperature_k is not None:
        t = np.asarray(temperature_k, dtype=float)
    e = 6.108 * humidity * np.exp((17.15 * t - 4684.0) / (t - 38.45))
    zhd = 0.0022768 * p / (1.0 - 0.00266 * np.cos(2.0 * lat) - 0.00028 * h * 1e-3)
    zwd = 0.002277 * (1255.0 / t + 0.05) * e
    return zhd, zwd


def tropo_saastamoinen(
    lat_rad: ArrayLike,
    h_m: ArrayLike,
    elev_rad: ArrayLike,
    humidity: float = 0.7,
    mapping: str = "saastamoinen",
) -> FloatArray:
    """Slant tropospheric delay (m), standard atmosphere.

    ``mapping``:

    * ``"saastamoinen"``: Saastamoinen's slant formula with ``z = pi/2 - el``::

        d = 0.002277 / cos z (P + (1255 / T + 0.05) e - tan^2 z)

      (its ``-tan^2 z`` term makes it unusable below ~5 deg; elevations are clipped there).
    * ``"sine"``: ``(ZHD + ZWD) / sin(el)``.
    * ``"zenith"``: ``ZHD + ZWD`` (no mapping).

    Heights outside [-500 m, 10 km] and negative elevations give 0 (no correction).

    Parameters
    ----------
    lat_rad, h_m, elev_rad : array_like, broadcastable

    Returns
    -------
    delay_m : ndarray, broadcast shape
    """
    lat = np.asarray(lat_rad, dtype=float)
    h = np.asarray(h_m, dtype=float)
    el = np.asarray(elev_rad, dtype=float)
    if mapping in ("zenith", "sine"):  # the zenith delays: the slant formula has its own
        zhd, zwd = tropo_zenith_saastamoinen(lat, h, humidity)
    if mapping == "zenith":
        out = zhd + zwd + 0.0 * el
    elif mapping == "sine":
        out = (zhd + zwd) / np.sin(np.maximum(el, np.radians(3.0)))
    elif mapping == "saastamoinen":
        p, t, e = standard_atmosphere(h, humidity)
        z = np.pi / 2.0 - np.maximum(el, np.radians(5.0))
        # hydrostatic part keeps Saastamoinen's gravity/latitude correction
        grav = 1.0 - 0.00266 * np.cos(2.0 * lat) - 0.00028 * h * 1e-3
        out = 0.002277 / np.cos(z) * (p / grav + (1255.0 / t + 0.05) * e - np.tan(z) ** 2)
    else:
        raise ValueError(f"unknown mapping {mapping!r} (expected saastamoinen, sine or zenith)")
    valid = (h >= -500.0) & (h <= 1.0e4) & (el > 0.0)
    return np.where(valid, out, 0.0)


def iono_klobuchar(
    t_s: ArrayLike,
    lat_rad: float,
    lon_rad: float,
    az_rad: ArrayLike,
    elev_rad: ArrayLike,
    alpha: ArrayLike,
    beta: ArrayLike,
    freq_hz: ArrayLike = F_L1_HZ,
) -> FloatArray:
    """Klobuchar ionospheric delay (m) on the signal at ``freq_hz`` (IS-GPS-200 20.3.3.5.2.5).

    In semicircles (``E = el / pi``, ``phi_u = lat / pi``, ``lambda_u = lon / pi``)::

        psi = 0.0137 / (E + 0.11) - 0.022
        phi_i = clip(phi_u + psi cos A, -0.416, 0.416)
        lambda_i = lambda_u + psi sin A / cos(pi phi_i)
        phi_m = phi_i + 0.064 cos(pi (lambda_i - 1.617))
        t = (43200 lambda_i + tow) mod 86400
        F = 1 + 16 (0.53 - E)^3
        AMP = max(sum alpha_n phi_m^n, 0), PER = max(sum beta_n phi_m^n, 72000)
        x = 2 pi (t - 50400) / PER
        T_iono = F (5e-9 + AMP (1 - x^2/2 + x^4/24))  if |x| < 1.57 else F 5e-9

    ``delay_m = c T_iono (f_L1 / f)^2``.

    Parameters
    ----------
    t_s : array_like
        GPST seconds (only the time of day matters).
    lat_rad, lon_rad : float
        Receiver geodetic latitude and longitude.
    az_rad, elev_rad : array_like, broadcastable with ``t_s``
    alpha, beta : array_like, shape (4,)
        Broadcast coefficients (``NavData.ion_gps_alpha`` / ``ion_gps_beta``).
    freq_hz : array_like
        Carrier frequency of the signal.

    Returns
    -------
    delay_m : ndarray, broadcast shape; 0 where ``el <= 0``.
    """
    a = np.asarray(alpha, dtype=float)
    b = np.asarray(beta, dtype=float)
    az = np.asarray(az_rad, dtype=float)
    el = np.asarray(elev_rad, dtype=float)
    t = np.asarray(t_s, dtype=float)
    e_sc = el / np.pi
    psi = 0.0137 / (e_sc + 0.11) - 0.022
    # np.clip(·, -0.416, 0.416), the same numbers (NaN stays NaN) without its wrapper
    phi_i = np.minimum(np.maximum(lat_rad / np.pi + psi * np.cos(az), -0.416), 0.416)
    lam_i = lon_rad / np.pi + psi * np.sin(az) / np.cos(phi_i * np.pi)
    phi_m = phi_i + 0.064 * np.cos((lam_i - 1.617) * np.pi)
    tod = np.mod(43200.0 * lam_i + np.mod(t, 86400.0), 86400.0)
    f = 1.0 + 16.0 * (0.53 - e_sc) ** 3
    # np.stack([1, phi_m, phi_m**2, phi_m**3], axis=-1), filled in place
    powers = np.empty(np.shape(phi_m) + (4,))
    powers[..., 0] = 1.0
    powers[..., 1] = phi_m
    powers[..., 2] = phi_m**2
    powers[..., 3] = phi_m**3
    amp = np.maximum(powers @ a, 0.0)
    per = np.maximum(powers @ b, 72000.0)
    x = 2.0 * np.pi * (tod - 50400.0) / per
    day = 5e-9 + amp * (1.0 - x * x / 2.0 + x**4 / 24.0)
    t_iono = f * np.where(np.abs(x) < 1.57, day, 5e-9)
    scale = (F_L1_HZ / np.asarray(freq_hz, dtype=float)) ** 2
    return np.where(el > 0.0, CLIGHT * t_iono * scale, 0.0)
