"""What both SPP estimators share: the output record, the band-1 signal choice, the
least-squares settings drawn from the :class:`robustrtk.pipeline.config.Config` tree, and
the navigation input."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from robustrtk.core import FloatArray, ObsBatch, Solution
from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.geometry.frames import ecef2geodetic
from robustrtk.io.rinex_nav import NavData
from robustrtk.measurement.undifferenced import LsqSettings
from robustrtk.pipeline.config import Config

#: Preferred code band digits per system for the single-frequency user (B1I is band 2).
BAND1_PREFERENCE: dict[str, tuple[str, ...]] = {
    "G": ("1",),
    "J": ("1",),
    "E": ("1",),
    "R": ("1",),
    "S": ("1",),
    "C": ("2", "1"),
    "I": ("5",),
}


#: Geodetic heights (m) a single-point position may have: from a deep valley below the
#: ellipsoid to far above any aircraft. Outside, the epoch is ``none`` (a wrong minimum).
HEIGHT_RANGE_M = (-5_000.0, 100_000.0)
#: Largest 3-D position σ (m) reported as a ``single`` solution (RTKLIB's GDOP 30 at 30 m).
MAX_SIGMA_M = 1_000.0


@dataclass(frozen=True)
class SppEpoch:
    """One epoch of SPP output.

    Attributes
    ----------
    t_s : float
        GPST seconds.
    pos_ecef_m : ndarray, shape (3,)
    clock_m : dict str -> float
        Receiver clock per system (m).
    cov_m2 : ndarray, shape (3, 3)
        Position covariance (m^2) under the variance model.
    n_used : int
    status : str
        ``"single"`` or ``"none"``.
    excluded : tuple of str
        Satellites excluded by FDE; for the Kalman SPP the rows its robust update
        rejected (``"G05:P1"`` code, ``"G05:L5"`` phase, ``"G05:D1"`` Doppler).
    chi2_ok : bool
        The final chi-square test passed (Kalman SPP: at least four code or phase rows used).
    vel_ecef_m_s : ndarray, shape (3,) or None
    adaptive_alpha : float
        Kalman SPP with an adaptive factor: the epoch's smallest αᵢ (1 = the prediction
        kept; algorithms.md §23). 1 otherwise.
    reason : str
        Why an epoch has status ``"none"`` (empty when solved), e.g. ``"height -3.1e+05 m
        off the Earth's surface"`` for a least-squares solution that failed its sanity check.
    """

    t_s: float
    pos_ecef_m: FloatArray
    clock_m: dict[str, float]
    cov_m2: FloatArray
    n_used: int
    status: str
    excluded: tuple[str, ...] = ()
    chi2_ok: bool = True
    vel_ecef_m_s: FloatArray | None = None
    adaptive_alpha: float = 1.0
    reason: str = ""

    def to_solution(self) -> Solution:
        """As a :class:`robustrtk.core.Solution`."""
        return Solution(
            t_s=self.t_s,
            pos_m=self.pos_ecef_m,
            cov_m2=self.cov_m2,
            status=self.status,
            n_used=self.n_used,
            vel_m_s=self.vel_ecef_m_s,
        )


# ---------------------------------------------------------------------- signal choice
def select_band1(batch: ObsBatch, systems: str | None = None) -> ObsBatch:
    """One-signal batch with the first L1/E1/B1 code column that has data, per system.

    For each system the candidate columns are the batch's signals of the preferred band
    (:data:`BAND1_PREFERENCE`, in batch order); the first with any finite code for that
    system is used for all its satellites. Satellites of systems not in ``systems`` (or
    with no candidate column) are dropped.

    Returns
    -------
    ObsBatch
        ``K = 1``; ``signals = ("1",)``; ``meta["signal_by_system"]`` records the choice.
    """
    sys_arr = np.array(batch.system)
    keep_rows: list[int] = []
    col_of_row: list[int] = []
    choice: dict[str, str] = {}
    for s in dict.fromkeys(batch.system):
        if systems is not None and s not in systems:
            continue
        rows = np.flatnonzero(sys_arr == s)
        col = -1
        for band in BAND1_PREFERENCE.get(s, ("1",)):
            for k, sig in enumerate(batch.signals):
                if sig[:1] == band and np.isfinite(batch.code_m[:, rows, k]).any():
                    col = k
                    break
            if col >= 0:
                break
        if col < 0:
            continue
        choice[s] = batch.signals[col]
        keep_rows.extend(rows.tolist())
        col_of_row.extend([col] * rows.size)
    order = np.argsort(keep_rows, kind="stable")
    r = np.asarray(keep_rows, dtype=np.int64)[order]
    c = np.asarray(col_of_row, dtype=np.int64)[order]
    meta = dict(batch.meta)
    meta["signal_by_system"] = choice
    if len(batch.signals) == 1 and r.size == len(batch.tx_ids):
        # every row kept from the one column: the same arrays, not a copy of them
        return replace(batch, signals=("1",), meta=meta)

    def take(a: np.ndarray) -> np.ndarray:
        return a[:, r, c][:, :, None]

    return replace(
        batch,
        tx_ids=tuple(batch.tx_ids[i] for i in r),
        system=tuple(batch.system[i] for i in r),
        signals=("1",),
        code_m=take(batch.code_m),
        phase_cyc=take(batch.phase_cyc),
        doppler_hz=take(batch.doppler_hz),
        cn0_dbhz=take(batch.cn0_dbhz),
        lli=take(batch.lli),
        wavelength_m=batch.wavelength_m[r, c][:, None],
        meta=meta,
    )


def unsolved_epoch(t_s: float, reason: str = "no solution", excluded: tuple[str, ...] = ()) -> SppEpoch:
    """An epoch without a solution (status ``"none"``, NaN position), with the reason."""
    return SppEpoch(
        t_s, np.full(3, np.nan), {}, np.full((3, 3), np.nan), 0, "none", excluded, False, reason=reason
    )


def lsq_settings(cfg: Config) -> LsqSettings:
    """The least-squares settings of ``cfg``: mask, code σ, C/N0 weighting and mask,
    atmosphere, and FDE (on when ``cfg.spp.raim`` and the robust policy is not ``none``)."""
    return LsqSettings(
        elev_mask_deg=cfg.gnss.elev_mask_deg,
        code_sigma_m=cfg.measurement.code_sigma_m,
        use_cn0=cfg.spp.use_cn0,
        cn0_ref_dbhz=cfg.spp.cn0_ref_dbhz,
        snr_mask_dbhz=cfg.measurement.snr_mask_dbhz,
        tropo=cfg.measurement.tropo,
        iono=cfg.measurement.iono,
        fde=cfg.spp.raim and cfg.robust.policy != "none",
        fde_alpha=cfg.spp.raim_alpha,
        max_exclusions=cfg.spp.max_exclusions,
        max_iter=cfg.spp.max_iter,
    )


def nav_and_source(nav: NavData | EphemerisSource) -> tuple[NavData, EphemerisSource]:
    """Navigation data and an ephemeris source over it."""
    if isinstance(nav, EphemerisSource):
        return nav.nav, nav
    return nav, EphemerisSource(nav)


def implausible_reason(pos_ecef_m: FloatArray, cov_m2: FloatArray) -> str:
    """Why a position cannot be reported (empty when it can): not finite, a geodetic height
    outside :data:`HEIGHT_RANGE_M`, or a 3-D σ over :data:`MAX_SIGMA_M`."""
    pos = np.asarray(pos_ecef_m, float)
    if not np.all(np.isfinite(pos)):
        return "non-finite position"
    h = float(ecef2geodetic(pos)[2])
    if not HEIGHT_RANGE_M[0] <= h <= HEIGHT_RANGE_M[1]:
        return f"height {h:.3g} m off the Earth's surface"
    var = float(np.trace(np.asarray(cov_m2, float)[:3, :3]))
    if not (math.isfinite(var) and var <= MAX_SIGMA_M**2):
        return f"position sigma {math.sqrt(var) if var >= 0 else float('nan'):.3g} m over {MAX_SIGMA_M:.0f} m"
    return ""


def reported(epochs: list[SppEpoch]) -> list[SppEpoch]:
    """``epochs`` with every solved one that fails :func:`implausible_reason` written as
    ``none`` with its reason (the Kalman SPP's output check; the run goes on)."""
    out = []
    for e in epochs:
        why = implausible_reason(e.pos_ecef_m, e.cov_m2) if e.status != "none" else ""
        out.append(replace(e, status="none", chi2_ok=False, reason=why) if why else e)
    return out


__all__ = [
    "BAND1_PREFERENCE", "HEIGHT_RANGE_M", "MAX_SIGMA_M", "SppEpoch", "implausible_reason", "lsq_settings",
    "nav_and_source", "reported", "select_band1", "unsolved_epoch",
]  # fmt: skip
