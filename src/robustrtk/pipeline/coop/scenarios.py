"""Test scenarios of cooperative positioning on real receiver files (algorithms.md §21):
:func:`windowsill_mask` (one azimuth sector of the sky, a seeded centre, at most
``max_sats`` satellites) and :func:`inject_code_bias` (a seeded code error on some
satellites for a stretch of epochs)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from robustrtk.core import BoolArray, FloatArray, InputError, ObsBatch
from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.geometry.frames import ecef2enu_rotation, ecef2geodetic
from robustrtk.measurement.undifferenced import epoch_geometry
from robustrtk.pipeline.spp_common import select_band1


def _az_el(sat_pos_m: FloatArray, rx_m: FloatArray) -> tuple[FloatArray, FloatArray]:
    lat, lon, _ = ecef2geodetic(rx_m)
    rot = ecef2enu_rotation(float(lat), float(lon))
    enu = (sat_pos_m - rx_m) @ rot.T
    el = np.arcsin(np.clip(enu[:, 2] / np.linalg.norm(enu, axis=1), -1.0, 1.0))
    az = np.mod(np.arctan2(enu[:, 0], enu[:, 1]), 2 * np.pi)
    return az, el


def windowsill_mask(
    batch: ObsBatch,
    eph: EphemerisSource,
    pos_ecef_m: FloatArray,
    *,
    max_sats: int,
    seed: int = 0,
    width_deg: float = 180.0,
    center_az_deg: float | None = None,
    elev_mask_deg: float = 10.0,
    systems: str | None = None,
) -> tuple[BoolArray, float]:
    """A windowsill occlusion: only one azimuth sector of the sky is visible.

    The sector is ``width_deg`` wide (180°: the half-sky in front of a window, the wall
    hides the rest) centred on ``center_az_deg``, drawn uniformly in [0°, 360°) from
    ``numpy.random.default_rng(seed)`` when None. Per epoch the satellites of the sector
    above ``elev_mask_deg`` are visible, at most ``max_sats`` of them — the highest first
    (the window frame cuts the rest). Azimuths and elevations are seen from ``pos_ecef_m``.
    ``systems``: only satellites of these system letters count (those the nodes use).

    Returns
    -------
    visible : ndarray of bool, shape (T, N)
    center_az_deg : float
        The sector's centre (deg), drawn or given.
    """
    if center_az_deg is None:
        center_az_deg = float(np.random.default_rng(seed).uniform(0.0, 360.0))
    b1 = batch if len(batch.signals) == 1 else select_band1(batch)
    T, N = b1.code_m.shape[:2]
    vis = np.zeros((T, len(batch.tx_ids)), bool)
    col = {t: i for i, t in enumerate(batch.tx_ids)}
    half = np.deg2rad(width_deg) / 2
    c = np.deg2rad(center_az_deg)
    for k in range(T):
        g = epoch_geometry(b1, k, eph)
        if not g.ids:
            continue
        az, el = _az_el(g.sat_pos_m, np.asarray(pos_ecef_m, float))
        daz = np.abs((az - c + np.pi) % (2 * np.pi) - np.pi)
        ok = g.ok & (daz <= half) & (el >= np.deg2rad(elev_mask_deg))
        if systems is not None:
            ok &= np.array([sid[0] in systems for sid in g.ids], dtype=bool)
        cand = np.flatnonzero(ok)
        keep = cand[np.argsort(-el[cand], kind="stable")][:max_sats]
        for j in keep:
            vis[k, col[g.ids[j]]] = True
    return vis, float(center_az_deg)


def inject_code_bias(
    batch: ObsBatch,
    bias_m: float,
    n_sats: int,
    epochs: slice,
    seed: int = 0,
) -> tuple[ObsBatch, tuple[str, ...]]:
    """``bias_m`` added to every code of ``n_sats`` satellites over ``epochs``.

    The satellites are drawn (``numpy.random.default_rng(seed)``) among those with code in
    every epoch of the stretch. Returns the new batch and the satellites hit.
    """
    code = np.array(batch.code_m, copy=True)
    stretch = code[epochs]
    full = np.flatnonzero(np.all(np.isfinite(stretch).any(axis=2), axis=0))
    if full.size < n_sats:
        raise InputError(f"code bias: only {full.size} satellites have code over the stretch, {n_sats} asked")
    hit = np.sort(np.random.default_rng(seed).choice(full, n_sats, replace=False))
    rows = np.arange(len(batch))[epochs]
    code[np.ix_(rows, hit)] += bias_m
    return replace(batch, code_m=code), tuple(batch.tx_ids[i] for i in hit)


__all__ = ["inject_code_bias", "windowsill_mask"]
