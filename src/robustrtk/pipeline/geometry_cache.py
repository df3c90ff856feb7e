"""Geometry an epoch asks for several times, computed once (:class:`GeometryCache`).

One epoch of the DD engine asks for the same receiver-to-transmitter geometry for the
elevation mask, the weights, the troposphere, rover and base; the base (a constant) is
asked about every epoch. The cache keeps the last few answers by the bytes of the
positions asked about; results are those of the functions it wraps.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TypeVar

import numpy as np

from robustrtk.core import FloatArray
from robustrtk.geometry.frames import ecef2enu_rotation, ecef2geodetic
from robustrtk.geometry.los import azimuth_elevation_rot, elevation_rot
from robustrtk.measurement.corrections import tropo_saastamoinen
from robustrtk.measurement.weighting import elevation_sin2, local_elevation

_K = TypeVar("_K")
_V = TypeVar("_V")


def _remembered(memo: dict[_K, _V], key: _K, compute: Callable[[], _V], size: int = 8) -> _V:
    """``memo[key]``, computed by ``compute()`` and stored when absent; the memo is emptied
    once it holds ``size`` entries (one epoch asks for the same few geometries)."""
    hit = memo.get(key)
    if hit is None:
        if len(memo) >= size:
            memo.clear()
        hit = compute()
        memo[key] = hit
    return hit


class GeometryCache:
    """Geodetic coordinates, azimuths, elevations and tropospheric delays, remembered.

    Parameters
    ----------
    frame : {"local", "ecef"}
        ``"local"``: z-up local frame (pseudolites), elevations from the z axis; ``"ecef"``:
        elevations from the ellipsoid normal at the receiver.
    """

    def __init__(self, frame: str) -> None:
        self.frame = frame
        # (position, transmitters) bytes -> (azimuth, elevation)
        self._az_el_memo: dict[tuple[bytes, bytes], tuple[FloatArray, FloatArray]] = {}
        # the same for the elevations alone, and for their elevation-weighting divisors
        self._el_memo: dict[tuple[bytes, bytes], FloatArray] = {}
        self._sin2_memo: dict[tuple[bytes, bytes], FloatArray] = {}
        # position bytes -> (lat, lon, h, ECEF->ENU rotation), least recently used dropped
        # first: the base (a constant) is asked about every epoch, the rover a few times
        self._geo_memo: dict[bytes, tuple[FloatArray, FloatArray, FloatArray, FloatArray]] = {}

    def geodetic(self, pos_m: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """:func:`~robustrtk.geometry.frames.ecef2geodetic` of an ECEF position (3,) and the
        :func:`~robustrtk.geometry.frames.ecef2enu_rotation` there, remembered for the few
        positions asked about last (the base's every epoch)."""
        p = np.asarray(pos_m, dtype=float)
        key = p.tobytes()
        memo = self._geo_memo
        hit = memo.pop(key, None)
        if hit is None:
            if len(memo) >= 8:
                del memo[next(iter(memo))]
            lat, lon, h = ecef2geodetic(p)
            hit = (lat, lon, h, ecef2enu_rotation(float(lat), float(lon)))
        memo[key] = hit  # (re)inserted last: the most recently used
        return hit

    def az_el(self, tx_pos: FloatArray, pos_m: FloatArray) -> tuple[FloatArray, FloatArray]:
        """:func:`~robustrtk.geometry.los.azimuth_elevation` (rad), remembered for the last few
        ``(pos_m, tx_pos)`` of the epoch (copies are returned)."""
        p = np.asarray(pos_m, dtype=float)
        t = np.asarray(tx_pos, dtype=float)
        hit = _remembered(
            self._az_el_memo,
            (p.tobytes(), t.tobytes()),
            lambda: azimuth_elevation_rot(t, p, self.geodetic(p)[3]),
        )
        return hit[0].copy(), hit[1].copy()

    def elevation(self, pos_m: FloatArray, tx_pos: FloatArray) -> FloatArray:
        """Elevation (rad) of each transmitter seen from ``pos_m`` in the cache's frame
        (``"ecef"``: the elevations of :meth:`az_el`, remembered the same way)."""
        if self.frame != "ecef":
            return local_elevation(pos_m, tx_pos)
        p = np.asarray(pos_m, dtype=float)
        t = np.asarray(tx_pos, dtype=float)
        hit = _remembered(
            self._el_memo, (p.tobytes(), t.tobytes()), lambda: elevation_rot(t, p, self.geodetic(p)[3])
        )
        return hit.copy()

    def elevation_sin2(self, pos_m: FloatArray, tx_pos: FloatArray) -> FloatArray:
        """:func:`~robustrtk.measurement.weighting.elevation_sin2` of :meth:`elevation`,
        remembered for the last few ``(pos_m, tx_pos)`` (code and phase share it)."""

        def divisor() -> FloatArray:
            out = elevation_sin2(self.elevation(pos_m, tx_pos))
            out.flags.writeable = False  # shared by the calls that hit the memo: read-only
            return out

        key = (np.asarray(pos_m, dtype=float).tobytes(), np.asarray(tx_pos, dtype=float).tobytes())
        return _remembered(self._sin2_memo, key, divisor)

    def tropo(self, pos_m: FloatArray, tx_pos: FloatArray) -> FloatArray:
        """Saastamoinen slant delays (m) from ``pos_m`` to each transmitter."""
        lat, _, h, _ = self.geodetic(pos_m)
        el = self.elevation(pos_m, tx_pos)
        return np.asarray(tropo_saastamoinen(lat, h, el), float)


__all__ = ["GeometryCache"]
