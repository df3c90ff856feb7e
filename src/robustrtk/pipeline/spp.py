"""Single point positioning (SPP) from code pseudoranges and broadcast ephemerides.

Two estimators, one :class:`robustrtk.pipeline.config.Config` (default :func:`preset`
``("spp")``); ``cfg.estimator.filter`` names the estimator (``lsq``, ``ekf``, ``ukf``):

* :func:`solve_spp` — per-epoch weighted least squares (Gauss–Newton) with one receiver
  clock per system, and RAIM-like fault detection and exclusion (FDE), on one L1/E1/B1
  code per satellite (:mod:`robustrtk.measurement.undifferenced`).
* :func:`solve_spp_kalman` — a robust Kalman filter (EKF or UKF) on code, Doppler and
  carrier phase of one or two bands, with an optional Rauch–Tung–Striebel smoother; model
  in :mod:`robustrtk.pipeline.spp_kalman`.

Both use the same corrections, variance model and least-squares core
(:mod:`robustrtk.measurement.undifferenced`). Settings read: ``elev_mask_deg``,
``code_sigma_m``, ``snr_mask_dbhz``, ``tropo``, ``iono``, ``robust`` (``none`` turns the
least-squares FDE off; the Kalman SPP's policy with ``k0``/``k1``) and the ``cfg.spp``
section; the Kalman SPP also ``filter``, ``ukf_*``, ``phase_sigma_m``, ``sigma_acc_m_s2``,
``reinit_epochs`` and ``smoother``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from robustrtk.core import FloatArray, ObsBatch
from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.geometry.frames import ecef2geodetic
from robustrtk.io.rinex_nav import NavData
from robustrtk.measurement.undifferenced import LsqSolution, epoch_geometry, lsq_fde
from robustrtk.pipeline.config import Config, preset
from robustrtk.pipeline.results import notify_progress
from robustrtk.pipeline.spp_common import (
    BAND1_PREFERENCE,
    SppEpoch,
    lsq_settings,
    nav_and_source,
    select_band1,
    unsolved_epoch,
)

#: Geodetic heights (m) a least-squares position may have: from a deep valley below the
#: ellipsoid to far above any aircraft. Outside, the epoch is ``none`` (a wrong minimum).
HEIGHT_RANGE_M = (-5_000.0, 100_000.0)
#: Largest 3-D position σ (m) reported as a ``single`` solution (RTKLIB's GDOP 30 at 30 m).
MAX_SIGMA_M = 1_000.0
#: Post-fit residuals larger than this many times their modelled σ (unit-weight σ̂ of an
#: epoch whose chi-square test failed after FDE) mean a wrong minimum, not a mis-set σ
#: (a σ set 10× too small gives σ̂ ≈ 14 on the Pixel 5 drive; a wild epoch σ̂ > 4000).
MAX_UNIT_SIGMA = 100.0
#: An exactly determined solution (no redundancy, so no residual test) farther than
#: ``MAX_SPEED_M_S · Δt + JUMP_SLACK_M`` from the last accepted one is refused.
MAX_SPEED_M_S = 1_000.0
JUMP_SLACK_M = 1_000.0


def sanity_reason(
    lsq: LsqSolution, chi2_ok: bool, prev_pos_m: FloatArray | None = None, dt_s: float = math.inf
) -> str:
    """Why a least-squares epoch cannot be reported (empty string when it can).

    The checks: the residuals agree with their variance model (when the chi-square test
    fails after FDE, the unit-weight σ̂ is at most :data:`MAX_UNIT_SIGMA`: residuals
    hundreds of σ long belong to a wrong minimum); the geodetic height lies in
    :data:`HEIGHT_RANGE_M`; the 3-D σ is at most :data:`MAX_SIGMA_M`; an exactly determined
    solution (as many rows as unknowns: nothing checks it) stays within
    ``MAX_SPEED_M_S · dt_s + JUMP_SLACK_M`` of the last accepted position ``prev_pos_m``.
    """
    dof = int(lsq.rows.size - lsq.n_unknowns)
    if not chi2_ok and dof > 0:
        s0 = math.sqrt(float(np.sum(lsq.v**2 / lsq.var)) / dof)
        if not s0 <= MAX_UNIT_SIGMA:
            return f"residuals {s0:.3g} times their sigma after exclusion"
    pos = np.asarray(lsq.pos, float)
    if not np.all(np.isfinite(pos)):
        return "non-finite position"
    h = float(ecef2geodetic(pos)[2])
    if not HEIGHT_RANGE_M[0] <= h <= HEIGHT_RANGE_M[1]:
        return f"height {h:.3g} m off the Earth's surface"
    var = float(np.trace(np.asarray(lsq.cov, float)[:3, :3]))
    if not (math.isfinite(var) and var <= MAX_SIGMA_M**2):
        return f"position sigma {math.sqrt(var) if var >= 0 else float('nan'):.3g} m over {MAX_SIGMA_M:.0f} m"
    if prev_pos_m is not None and dof <= 0:
        jump = float(np.linalg.norm(pos - prev_pos_m))
        if jump > MAX_SPEED_M_S * abs(dt_s) + JUMP_SLACK_M:
            return (
                f"jump of {jump / 1e3:.3g} km from the last solution, with no redundant satellite to check it"
            )
    return ""


def solve_spp(
    batch: ObsBatch,
    nav: NavData | EphemerisSource,
    cfg: Config | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> list[SppEpoch]:
    """Per-epoch weighted least-squares SPP with FDE.

    Parameters
    ----------
    batch : ObsBatch
        Observations; the L1/E1/B1 column per system is selected with
        :func:`select_band1` unless the batch already has a single signal.
    nav : NavData or EphemerisSource
    cfg : Config, optional
        Default ``preset("spp")``; read through
        :func:`robustrtk.pipeline.spp_common.lsq_settings` (the estimator choice is the
        caller's: this function is the least-squares one whatever ``cfg.estimator.filter``).
    progress : callable (done, total), optional

    Returns
    -------
    list of SppEpoch, one per epoch (status ``"none"`` with NaN position and a ``reason``
    when unsolved or when the solution fails :func:`sanity_reason`).

    Notes
    -----
    Each epoch starts from the previous epoch's accepted position; one that fails the
    sanity check from there is solved again from the Earth's centre before it is refused,
    so one wrong minimum never seeds the next epochs.
    """
    cfg = cfg or preset("spp")
    settings = lsq_settings(cfg)
    navd, eph = nav_and_source(nav)
    b1 = batch if len(batch.signals) == 1 else select_band1(batch)
    out: list[SppEpoch] = []
    prev: FloatArray | None = None
    prev_t = math.nan
    for i in range(len(b1)):
        t = float(b1.t_s[i])
        geom = epoch_geometry(b1, i, eph)
        lsq, excl, ok = lsq_fde(t, geom, navd, settings, prev)
        why = "no solution (too few usable satellites, or below the Earth's surface)"
        if lsq is not None:
            why = sanity_reason(lsq, ok, prev, t - prev_t)
            if why and prev is not None:
                lsq, excl, ok = lsq_fde(t, geom, navd, settings, None)
                why = "no solution" if lsq is None else sanity_reason(lsq, ok, prev, t - prev_t)
        if lsq is None or why:
            out.append(unsolved_epoch(t, why, tuple(excl)))
        else:
            prev, prev_t = lsq.pos, t
            out.append(
                SppEpoch(
                    t,
                    lsq.pos.copy(),
                    lsq.clk,
                    lsq.cov[:3, :3].copy(),
                    int(lsq.rows.size),
                    "single",
                    tuple(excl),
                    ok,
                )
            )
        notify_progress(progress, i + 1, len(b1), out[-1].status)
    return out


def solve_spp_kalman(*args: Any, **kwargs: Any) -> list[SppEpoch]:
    """The Kalman SPP, :func:`robustrtk.pipeline.spp_kalman.solve_spp_kalman` (same arguments);
    its module is imported on the first call, so the other modes do not load it."""
    from robustrtk.pipeline.spp_kalman import solve_spp_kalman as run

    return run(*args, **kwargs)


__all__ = [
    "BAND1_PREFERENCE",
    "SppEpoch",
    "select_band1",
    "solve_spp",
    "solve_spp_kalman",
]
