"""A base position taken from a RINEX header, tested against the base's own single-point solution.

A header's ``APPROX POSITION XYZ`` is what its name says: a receiver's or an operator's
approximate position, sometimes metres off (kamakura's GEONET header is 4.4 m from the
station's published coordinates). Relative positioning moves the rover by the base's
error, so a run on a header position should say how far the header is from what the base's
own observations give, and refuse a header they contradict.

The test (docs/algorithms.md §31): single-point solutions ``p_k`` of up to ``n`` base epochs
spread evenly over the file, their mean ``p̄``, and the difference ``d = h − p̄`` to the
header ``h``. Its covariance is that of the mean,

    C = C_spp + C_batch,

with ``C_spp`` the median single-epoch SPP covariance (the broadcast orbit, clock and
ionosphere errors that dominate a single-point solution change over hours, so averaging a
few minutes of epochs does not shrink them: the mean is treated as no better than one
epoch) and ``C_batch`` the scatter of the means of ``B`` consecutive batches of epochs
divided by ``B`` (the part that does average). ``d`` is refused when

    χ² = dᵀ C⁻¹ d > χ²₃(1 − α),

the 3-degree-of-freedom quantile at false-alarm probability ``α``.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from robustrtk.core import FloatArray, ObsBatch
from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.geometry.frames import ecef2enu_rotation, ecef2geodetic
from robustrtk.measurement.chi2 import chi2_ppf
from robustrtk.pipeline.config import preset
from robustrtk.pipeline.spp import select_band1, solve_spp

__all__ = ["BASE_CHECK_ALPHA", "BaseCheck", "check_header_position"]

#: False-alarm probability of the header test.
BASE_CHECK_ALPHA = 1e-3
#: Base epochs solved for the test (spread evenly over the file).
_N_EPOCHS = 60
#: Consecutive batches whose means give the averaging part of the covariance.
_N_BATCHES = 6


@dataclass(frozen=True)
class BaseCheck:
    """The header position against the base's mean single-point solution.

    Attributes
    ----------
    header_m : ndarray, shape (3,)
        Header position, ECEF (m).
    spp_m : ndarray, shape (3,)
        Mean of the base's single-point solutions, ECEF (m).
    cov_m2 : ndarray, shape (3, 3)
        Covariance of ``header_m − spp_m`` (m², ECEF): ``C_spp + C_batch``.
    n_epochs : int
        Base epochs solved.
    chi2 : float
        ``dᵀ C⁻¹ d``.
    bound : float
        ``χ²₃(1 − α)``.
    """

    header_m: FloatArray
    spp_m: FloatArray
    cov_m2: FloatArray
    n_epochs: int
    chi2: float
    bound: float

    @property
    def distance_m(self) -> float:
        """``|h − p̄|`` (m)."""
        return float(np.linalg.norm(self.header_m - self.spp_m))

    @property
    def consistent(self) -> bool:
        """The header passes the test (``χ² ≤ bound``)."""
        return self.chi2 <= self.bound

    def offset_enu_m(self) -> FloatArray:
        """``h − p̄`` east, north, up (m) at the header's position."""
        lat, lon, _ = ecef2geodetic(self.header_m)
        return np.asarray(ecef2enu_rotation(float(lat), float(lon)) @ (self.header_m - self.spp_m))

    def sigma_enu_m(self) -> FloatArray:
        """σ east, north, up (m) of the difference."""
        lat, lon, _ = ecef2geodetic(self.header_m)
        r = ecef2enu_rotation(float(lat), float(lon))
        return np.sqrt(np.diag(r @ self.cov_m2 @ r.T))

    def describe(self) -> str:
        """One line: both positions, the offset in ENU with its σ and the test."""
        e, n, u = self.offset_enu_m()
        se, sn, su = self.sigma_enu_m()
        h, s = self.header_m, self.spp_m
        return (
            f"header position ({h[0]:.2f},{h[1]:.2f},{h[2]:.2f}) is {self.distance_m:.2f} m from the "
            f"base's own mean single-point position ({s[0]:.2f},{s[1]:.2f},{s[2]:.2f}; {self.n_epochs} "
            f"epochs): E {e:+.2f} N {n:+.2f} U {u:+.2f} m against σ {se:.2f}/{sn:.2f}/{su:.2f} m, "
            f"χ² {self.chi2:.1f} (bound {self.bound:.1f})"
        )


def _subset(batch: ObsBatch, idx: np.ndarray) -> ObsBatch:
    return replace(
        batch,
        t_s=batch.t_s[idx],
        code_m=batch.code_m[idx],
        phase_cyc=batch.phase_cyc[idx],
        doppler_hz=batch.doppler_hz[idx],
        cn0_dbhz=batch.cn0_dbhz[idx],
        lli=batch.lli[idx],
    )


def check_header_position(
    base: ObsBatch,
    eph: EphemerisSource,
    header_m: FloatArray,
    elev_mask_deg: float,
    *,
    alpha: float = BASE_CHECK_ALPHA,
    n_epochs: int = _N_EPOCHS,
) -> BaseCheck | None:
    """Test a header base position against the base's own single-point solutions.

    Parameters
    ----------
    base, eph, elev_mask_deg
        As in :func:`robustrtk.pipeline.base_position.check_base_position`.
    header_m : array_like, shape (3,)
        The header position, ECEF (m).
    alpha : float
        False-alarm probability of the χ² test.
    n_epochs : int
        Largest number of base epochs solved (spread evenly over the file).

    Returns
    -------
    BaseCheck or None
        None when fewer than three base epochs are solved (no test possible).
    """
    band1 = select_band1(base)
    t = len(band1.t_s)
    if t == 0:
        return None
    idx = np.unique(np.linspace(0, t - 1, min(t, n_epochs)).round().astype(np.int64))
    sols = solve_spp(_subset(band1, idx), eph, preset("spp").updated(elev_mask_deg=elev_mask_deg))
    good = [
        s
        for s in sols
        if s.status == "single" and np.all(np.isfinite(s.pos_ecef_m)) and np.all(np.isfinite(s.cov_m2))
    ]
    if len(good) < 3:
        return None
    pos = np.array([s.pos_ecef_m for s in good], float)
    cov = np.array([s.cov_m2 for s in good], float)
    mean = pos.mean(axis=0)
    c_spp = np.median(cov, axis=0)
    n_b = min(_N_BATCHES, len(good))
    means = np.array([chunk.mean(axis=0) for chunk in np.array_split(pos, n_b)])
    c_batch = np.cov(means.T) / n_b if n_b > 1 else np.zeros((3, 3))
    c = c_spp + c_batch
    h = np.asarray(header_m, float).reshape(3)
    d = h - mean
    chi2 = float(d @ np.linalg.solve(c, d))
    return BaseCheck(h, mean, c, len(good), chi2, chi2_ppf(1.0 - alpha, 3))
