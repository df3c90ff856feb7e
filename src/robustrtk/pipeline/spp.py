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

from collections.abc import Callable
from typing import Any

from robustrtk.core import FloatArray, ObsBatch
from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.io.rinex_nav import NavData
from robustrtk.measurement.undifferenced import epoch_geometry, lsq_fde
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
    list of SppEpoch, one per epoch (status ``"none"`` with NaN position when unsolved).
    """
    cfg = cfg or preset("spp")
    settings = lsq_settings(cfg)
    navd, eph = nav_and_source(nav)
    b1 = batch if len(batch.signals) == 1 else select_band1(batch)
    out: list[SppEpoch] = []
    prev: FloatArray | None = None
    for i in range(len(b1)):
        t = float(b1.t_s[i])
        lsq, excl, ok = lsq_fde(t, epoch_geometry(b1, i, eph), navd, settings, prev)
        if lsq is None:
            out.append(unsolved_epoch(t))
        else:
            prev = lsq.pos
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
