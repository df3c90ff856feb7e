"""Error statistics of cooperative solutions against a known position."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from robustrtk.core import FloatArray
from robustrtk.geometry.frames import ecef2enu_rotation, ecef2geodetic


def horizontal_errors(pos_ecef_m: npt.ArrayLike, truth_ecef_m: npt.ArrayLike) -> FloatArray:
    """Horizontal error (m) of each row of ``pos_ecef_m`` against ``truth_ecef_m`` (NaN kept)."""
    p = np.asarray(pos_ecef_m, float).reshape(-1, 3)
    tr = np.asarray(truth_ecef_m, float)
    lat, lon, _ = ecef2geodetic(tr)
    enu = (p - tr) @ ecef2enu_rotation(float(lat), float(lon)).T
    out: FloatArray = np.hypot(enu[:, 0], enu[:, 1])
    return out


__all__ = ["horizontal_errors"]
