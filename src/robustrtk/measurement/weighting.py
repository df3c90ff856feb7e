"""Variance models of undifferenced observations.

All models scale a base variance ``σ²`` (the zenith / nominal value):

* ``equal``: ``σ²``
* ``elevation``: ``σ² / sin²(max(el, el_min))`` (RTKLIB-like, el from the receiver)
* ``distance``: ``σ² (d / d0)²`` with ``d0`` a reference distance (m)
* ``snr``: ``σ² · 10^((snr0 − snr)/10)`` (variance ∝ 1/(C/N0) in linear units)
* ``reported``: ``σ_rep²``, the receiver's own σ of each measurement (Android
  ``ReceivedSvTimeUncertaintyNanos · c``, ``AccumulatedDeltaRangeUncertaintyMeters``),
  and the ``snr`` model where it reports none (docs/algorithms.md § 24)
"""

from __future__ import annotations

import numpy as np

from robustrtk.core import FloatArray, nan_to

WEIGHTINGS = ("equal", "elevation", "distance", "snr", "reported")


def elevation_sin2(elev_rad: FloatArray, elev_min_rad: float = np.deg2rad(5.0)) -> FloatArray:
    """``sin²(max(el, el_min))`` of the ``elevation`` model (NaN elevations: the zenith).

    Parameters
    ----------
    elev_rad : ndarray, shape (N,)
    elev_min_rad : float

    Returns
    -------
    ndarray, shape (N,)
        The divisor of ``σ²`` in :func:`variance`.
    """
    el = np.maximum(nan_to(elev_rad, np.pi / 2), elev_min_rad)
    return np.asarray(np.sin(el) ** 2, dtype=np.float64)


def variance(
    sigma_m: float,
    model: str = "equal",
    *,
    elev_rad: FloatArray | None = None,
    dist_m: FloatArray | None = None,
    snr_dbhz: FloatArray | None = None,
    n: int | None = None,
    elev_min_rad: float = np.deg2rad(5.0),
    dist_ref_m: float = 5.0,
    snr_ref_dbhz: float = 45.0,
    reported_sigma: FloatArray | None = None,
    elev_sin2: FloatArray | None = None,
) -> FloatArray:
    """Per-observation variance (m² or cycles², the unit of ``sigma_m``).

    Parameters
    ----------
    sigma_m : float
        Nominal standard deviation.
    model : {"equal", "elevation", "distance", "snr", "reported"}
    elev_rad, dist_m, snr_dbhz : ndarray, shape (N,)
        Inputs required by the chosen model; NaN inputs fall back to the nominal
        variance.
    reported_sigma : ndarray, shape (N,), optional
        ``reported``: the receiver's σ per observation (unit of ``sigma_m``); NaN or
        non-positive cells (and all when None) take the ``snr`` model.
    n : int
        Number of observations (needed for ``equal`` when no array is given).
    elev_sin2 : ndarray, shape (N,), optional
        ``elevation``: :func:`elevation_sin2` of the elevations, when already computed
        (``elev_rad`` is then not needed).

    Returns
    -------
    ndarray, shape (N,)
    """
    s2 = float(sigma_m) ** 2
    if model == "equal":
        size = n if n is not None else _size(elev_rad, dist_m, snr_dbhz)
        return np.full(size, s2)
    if model == "elevation":
        if elev_sin2 is None:
            if elev_rad is None:
                raise ValueError("elevation weighting needs elev_rad")
            elev_sin2 = elevation_sin2(elev_rad, elev_min_rad)
        return s2 / elev_sin2
    if model == "distance":
        if dist_m is None:
            raise ValueError("distance weighting needs dist_m")
        d = np.nan_to_num(np.asarray(dist_m, float), nan=dist_ref_m)
        return s2 * (d / dist_ref_m) ** 2
    if model == "reported":
        if snr_dbhz is None:
            raise ValueError("reported weighting needs snr_dbhz (its fallback)")
        var = variance(sigma_m, "snr", snr_dbhz=snr_dbhz, snr_ref_dbhz=snr_ref_dbhz)
        if reported_sigma is None:
            return var
        rep = np.asarray(reported_sigma, float)
        ok = np.isfinite(rep) & (rep > 0)
        return np.where(ok, np.where(ok, rep, 1.0) ** 2, var)
    if model == "snr":
        if snr_dbhz is None:
            raise ValueError("snr weighting needs snr_dbhz")
        snr = np.nan_to_num(np.asarray(snr_dbhz, float), nan=snr_ref_dbhz)
        return s2 * 10.0 ** ((snr_ref_dbhz - snr) / 10.0)
    raise ValueError(f"unknown weighting {model!r}; expected one of {', '.join(WEIGHTINGS)}")


def _size(*arrays: FloatArray | None) -> int:
    for a in arrays:
        if a is not None:
            return int(np.asarray(a).shape[0])
    raise ValueError("equal weighting needs n or an input array")


def local_elevation(pos_m: FloatArray, tx_pos_m: FloatArray) -> FloatArray:
    """Elevation (rad) of transmitters seen from ``pos_m`` in a local frame with z up.

    Parameters
    ----------
    pos_m : ndarray, shape (3,)
    tx_pos_m : ndarray, shape (N, 3)
    """
    d = tx_pos_m - pos_m
    return np.arcsin(np.clip(d[:, 2] / np.linalg.norm(d, axis=1), -1.0, 1.0))
