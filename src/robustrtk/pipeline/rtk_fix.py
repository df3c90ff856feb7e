"""The fixed solution of the carrier-phase RTK stage: its residual test, its precision
gate's age-free share, its reported variance factor, fix-and-hold and the coordinate prior
of the ``prior`` AR scheme (``docs/algorithms.md`` §8, §20, §37, §38). Used by
:class:`robustrtk.pipeline.rtk.RtkStage`."""

from __future__ import annotations

from typing import cast

import numpy as np

from robustrtk.ambiguity.book import AmbKey
from robustrtk.core import FloatArray
from robustrtk.estimation.integrity import phase_variance_factor
from robustrtk.estimation.state import GaussianState
from robustrtk.measurement.base_propagation import age_dd_covariance_m2, age_free_fraction
from robustrtk.measurement.dd import DDRangeModel, DDSet


def fixed_phase_factor(
    model: DDRangeModel, fixed: GaussianState, factors: FloatArray, float_rows: np.ndarray
) -> float:
    """:func:`~robustrtk.estimation.integrity.phase_variance_factor` of a fixed solution's DD
    phase rows: rows the robust update rejected left out, down-weighted ones with their
    inflated variance (``R ← D R D``, ``D = diag √γ``); redundancy = rows used − 3 − rows
    whose ambiguity stays float (``float_rows``, row indices, −1 for none)."""
    g = np.asarray(factors, float)
    use = np.isfinite(g)
    if not use.any():
        return 1.0
    v = (model.z - model.h(fixed.x))[use]
    d = np.sqrt(g[use])
    k = np.flatnonzero(use)
    R = model.R[k[:, None], k] * (d[:, None] * d[None, :])  # R[ix_(use, use)] · outer(d, d)
    fl = np.asarray(float_rows, np.int64)
    n_float = int(np.count_nonzero(use[fl[(fl >= 0) & (fl < use.size)]]))
    return phase_variance_factor(v, R, int(use.sum()) - 3 - n_float)


def amb_keys_of(state: GaussianState) -> tuple[AmbKey, ...]:
    """The ambiguity keys of a state built by the engine (all :class:`AmbKey`)."""
    return cast(tuple[AmbKey, ...], state.layout.amb_keys)


def fixed_residuals_ok(
    state: GaussianState, model: DDRangeModel, idx: np.ndarray, values: FloatArray, k: float
) -> bool:
    r"""Residual test of a fixed solution: every DD phase row whose ambiguity is fixed has
    :math:`|v_i| \le k \sqrt{R_{ii}}`, :math:`v = z - h(\check x)`, with :math:`\check x`
    the state conditioned on ``x[idx] = values`` (§8) and :math:`R` the rows' nominal
    covariance (m², no robust weights). Rows whose ambiguity stays float absorb their
    residual and are not tested (``docs/algorithms.md`` §20).

    Parameters
    ----------
    state : GaussianState
        Float posterior.
    model : DDRangeModel
        The epoch's DD phase rows (m).
    idx : ndarray of int, shape (m,)
        State indices of the fixed ambiguities.
    values : ndarray, shape (m,)
        Their integers (cycles).
    k : float
        Threshold in σ.
    """
    fixed = state.conditional_update(idx, values)
    v = model.z - model.h(fixed.x)
    sig = np.sqrt(np.diag(model.R))
    rows = np.isin(model.amb_idx, idx)
    return bool(np.all(np.abs(v[rows]) <= k * sig[rows]))


def age_free_share(
    state: GaussianState, model: DDRangeModel, idx: np.ndarray, dd: DDSet, n_tx: int, base_age_var_m2: float
) -> float:
    """:func:`~robustrtk.measurement.base_propagation.age_free_fraction` of the fixed
    solution: the DD phase rows whose ambiguities are fixed (state indices ``idx``), their
    position Jacobian at ``state`` and their covariance with and without the base's age
    variance (``base_age_var_m2``, m², of the ``n_tx`` transmitters of the rover epoch)."""
    rows = np.flatnonzero(np.isin(model.amb_idx, idx))
    if rows.size < 3:
        return 1.0
    H = model.jacobian(state.x)[np.ix_(rows, np.arange(state.x.size)[model.pos_slice])]
    R_age = age_dd_covariance_m2(dd.D, n_tx, base_age_var_m2)
    sub = np.ix_(rows, rows)
    return age_free_fraction(H, model.R[sub], R_age[sub])


def coordinate_prior(state: GaussianState, sigma_m: float, covariance: str = "reset") -> GaussianState:
    r"""The state with its position taken as an a-priori coordinate of σ ``sigma_m``.

    ``covariance="reset"``: ``P_pp ← σ² I₃`` and ``P_pj = P_jp ← 0`` for every other state
    ``j`` (ambiguities, velocity). ``covariance="add"``: ``P_pp ← P_pp + σ² I₃`` with the
    cross-covariances kept (a random walk of σ per epoch). The means and the other blocks
    are kept in both (``docs/algorithms.md`` §20).

    Parameters
    ----------
    state : GaussianState
        Predicted state; its position is the previous epoch's coordinate (m, local frame).
    sigma_m : float
        σ of each coordinate of the prior (m).
    covariance : {"reset", "add"}
        How the prior's position covariance is formed.
    """
    p = state.layout.slice("pos")
    P = state.P.copy()
    if covariance == "add":
        P[p, p] += np.eye(3) * sigma_m**2
        return state.with_(P=P)
    if covariance != "reset":
        raise ValueError(f"covariance: expected reset or add, got {covariance!r}")
    P[p, :] = 0.0
    P[:, p] = 0.0
    P[p, p] = np.eye(3) * sigma_m**2
    return state.with_(P=P)


def hold(state: GaussianState, idx: np.ndarray, values: FloatArray, sigma_cyc: float) -> GaussianState:
    """Fix-and-hold: update the state with pseudo-observations ``x[idx] = values`` (σ in cycles)."""
    return state.constrain(idx, values, sigma_cyc)


__all__ = [
    "age_free_share",
    "amb_keys_of",
    "coordinate_prior",
    "fixed_phase_factor",
    "fixed_residuals_ok",
    "hold",
]
