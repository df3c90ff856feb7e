"""Carrier-phase RTK step of the DD engine.

Per epoch:

1. DD phase (cycles) against the same references as the code; slips from LLI (either
   receiver, either transmitter of the DD) and from the polynomial-fit detector on each
   DD phase series (integer jumps repaired, others reset — or, with a robust policy,
   deferred: a transient gross error is the robust filter's business, and only a jump
   that is still rejected ``slip_confirm`` epochs later resets the ambiguity).
2. Ambiguity states (cycles), one per (transmitter, group), added diffuse around
   ``(z − ρ(x̄))/λ`` when a DD appears, dropped when it disappears or its reference
   changes, reset on slips; all re-added every epoch in instantaneous (single-epoch) AR,
   where each epoch starts from the previous epoch's fixed solution (mean and covariance).
3. Filter update with DD phase (and optionally DD code) and the robust policy.
4. Integer resolution: full LAMBDA, PAR ranked by |Δv̄| (Li et al.), or PAR by success
   rate; the fixed solution is the conditional update of the state on the validated
   subset (algorithms.md §8). Fix-and-hold feeds the validated integers back to the
   filter as tight pseudo-observations.
"""

from __future__ import annotations

from collections.abc import Hashable
from typing import TYPE_CHECKING

import numpy as np

from robustrtk.ambiguity.par import (
    FixResult,
    conditional_update,
    resolve_full,
    resolve_par_ranked,
    resolve_par_success_rate,
)
from robustrtk.core import FloatArray, ObsEpoch, Solution
from robustrtk.cycleslip.polyfit import PolyFitDetector
from robustrtk.estimation.filters import EKF
from robustrtk.estimation.models import LinearMeasurement
from robustrtk.estimation.robust import NoRobust
from robustrtk.estimation.state import GaussianState
from robustrtk.measurement.dd import DDRangeModel, DDSet, StackedModel, form_dd

if TYPE_CHECKING:
    from robustrtk.pipeline.engine import DDEngine, DiagRow

#: Consecutive epochs a flagged, robustly rejected DD must stay rejected before its
#: ambiguity is reset as a real slip.
SLIP_CONFIRM = 3


def _wavelengths(epoch: ObsEpoch, k: int, dd: DDSet) -> FloatArray:
    return np.asarray(epoch.wavelength_m[dd.i_tx, k], float)


def _phase_dd(
    eng: DDEngine,
    rover: ObsEpoch,
    base: ObsEpoch,
    groups: list[str],
    avail: np.ndarray,
    refs: dict[str, str],
    pos_prior: FloatArray,
    tx_pos: FloatArray,
) -> DDSet:
    k = eng.signal
    lam = rover.wavelength_m[:, k]
    var_r = eng._variances(eng.cfg.measurement.phase_sigma_m, rover, pos_prior, tx_pos) / lam**2
    var_b = eng._variances(eng.cfg.measurement.phase_sigma_m, base, eng.base_pos_m, tx_pos) / lam**2
    return form_dd(
        rover.tx_ids,
        groups,
        np.where(avail, rover.phase_cyc[:, k], np.nan),
        np.where(avail, base.phase_cyc[:, k], np.nan),
        var_r,
        var_b,
        refs,
    )


def _slips(
    eng: DDEngine, rover: ObsEpoch, base: ObsEpoch, dd: DDSet, refs: dict[str, str], t: float
) -> tuple[FloatArray, np.ndarray, np.ndarray]:
    """Repaired DD phase (cycles), hard-slip mask and soft (deferred) slip mask per row."""
    k = eng.signal
    cfg = eng.cfg
    det = cfg.slip_detectors()
    z = dd.z.copy()
    hard = np.zeros(dd.m, dtype=bool)
    soft = np.zeros(dd.m, dtype=bool)
    robust = not isinstance(eng.robust, NoRobust)
    if "lli" in det:
        lli = (rover.lli[:, k] & 1) | (base.lli[:, k] & 1)
        hard |= (lli[dd.i_tx] | lli[dd.i_ref]).astype(bool)
    if eng.ext_slip is not None:
        # undifferenced detectors (geometry-free, Doppler) of either receiver, per row
        ext = np.asarray(eng.ext_slip, bool)
        flagged = ext[dd.i_tx] | ext[dd.i_ref]
        if robust:
            soft |= flagged & ~hard
        else:
            hard |= flagged
    if "poly" in det:
        if refs != eng._slip_refs or eng._poly is None:
            eng._poly = PolyFitDetector(
                window=10,
                degree=2,
                threshold_sigma=6.0,
                noise_cyc=max(
                    2.0 * cfg.measurement.phase_sigma_m / float(np.nanmean(rover.wavelength_m[:, k])), 1e-3
                ),
            )
            eng._slip_refs = dict(refs)
        series = np.full(rover.n_tx, np.nan)
        series[dd.i_tx] = dd.z
        series[dd.i_tx[hard]] = np.nan  # LLI slips restart their series
        mask, repaired, jump = eng._poly.step(t, series)
        rows_mask = mask[dd.i_tx]
        rows_jump = jump[dd.i_tx]
        repairable = rows_mask & np.isfinite(rows_jump) & (rows_jump != 0)
        z[repairable] = repaired[dd.i_tx][repairable]
        unrep = rows_mask & ~np.isfinite(rows_jump)
        if robust:
            soft |= unrep
        else:
            hard |= unrep
    return z, hard, soft


def _manage_ambiguities(
    eng: DDEngine,
    state: GaussianState,
    dd: DDSet,
    z_cyc: FloatArray,
    lam: FloatArray,
    hard: np.ndarray,
    tx_pos: FloatArray,
    base_range: FloatArray,
) -> GaussianState:
    cfg = eng.cfg
    keys: list[Hashable] = [(t, g) for t, g in zip(dd.tx, dd.group, strict=True)]
    ref_of = dict(zip(dd.group, dd.ref, strict=True))
    present = set(keys)
    drop: list[Hashable] = []
    for key in state.layout.amb_keys:
        group = str(key[1])  # type: ignore[index]
        if key not in present or eng._amb_ref.get(key) != ref_of.get(group):
            drop.append(key)
    if cfg.ar.instantaneous:
        drop = list(state.layout.amb_keys)
    for i, key in enumerate(keys):
        if hard[i] and key in state.layout.amb_keys and key not in drop:
            drop.append(key)
    state = state.drop_ambiguities(drop)
    for key in drop:
        eng.fixed.pop(key, None)
        eng._amb_ref.pop(key, None)
    new = [i for i, key in enumerate(keys) if key not in state.layout.amb_keys]
    for key in drop:
        eng._lock.pop(key, None)
    for i, key in enumerate(keys):
        eng._lock[key] = 1 if i in new else eng._lock.get(key, 0) + 1
    if new:
        geo = DDRangeModel(
            tx_pos,
            base_range,
            dd.i_tx,
            dd.i_ref,
            state.layout.slice("pos"),
            np.full(dd.m, -1, dtype=np.int64),
            np.zeros(dd.m),
            dd.z,
            dd.R,
            dd.labels,
            eng.sagnac,
            eng.tx_corr_m,
        ).h(state.x)
        vals = (z_cyc[new] * lam[new] - geo[new]) / lam[new]
        state = state.add_ambiguities([keys[i] for i in new], vals, cfg.ar.amb_init_sigma_cyc**2)
        for i in new:
            eng._amb_ref[keys[i]] = dd.ref[i]
    return state


def _ar_candidates(eng: DDEngine, keys: list[Hashable], rows: np.ndarray, dd: DDSet) -> np.ndarray:
    """Mask over ``keys`` of the ambiguities allowed into integer resolution: tracked for
    ``ar_lock_epochs``, above ``ar_elev_mask_deg`` and free of half-cycle flags."""
    cfg = eng.cfg
    ok = rows >= 0
    if cfg.ar.ar_lock_epochs > 0 and not cfg.ar.instantaneous:  # single-epoch AR: every epoch is new
        ok &= np.array([eng._lock.get(k, 0) >= cfg.ar.ar_lock_epochs for k in keys], dtype=bool)
    if cfg.ar.ar_elev_mask_deg > 0 and eng.elev_rad is not None:
        el = np.full(len(keys), -np.inf)
        el[ok] = eng.elev_rad[dd.i_tx[rows[ok]]]
        ok &= el >= np.deg2rad(cfg.ar.ar_elev_mask_deg)
    if eng.half_cycle is not None:
        half = np.asarray(eng.half_cycle, bool)
        flag = np.zeros(len(keys), dtype=bool)
        flag[ok] = half[dd.i_tx[rows[ok]]] | half[dd.i_ref[rows[ok]]]
        ok &= ~flag
    return ok


def _resolve(
    eng: DDEngine, state: GaussianState, amb_rows: np.ndarray, dv: FloatArray, cand: np.ndarray
) -> tuple[FixResult, np.ndarray] | None:
    """Integer resolution over the candidate ambiguities; returns the result and the state
    indices of the candidates it was computed on."""
    cfg = eng.cfg
    idx = state.layout.amb_indices()[cand]
    amb_rows = amb_rows[cand]
    if cfg.ar.method == "off" or idx.size == 0:
        return None
    a = state.x[idx]
    Q = state.P[np.ix_(idx, idx)]
    Q = 0.5 * (Q + Q.T)
    try:
        if cfg.ar.method == "lambda" or idx.size < cfg.ar.par_min:
            return resolve_full(a, Q, ratio_threshold=cfg.ar.ratio), idx
        if cfg.ar.method == "par-sr":
            return resolve_par_success_rate(a, Q, ratio_threshold=cfg.ar.ratio, min_size=cfg.ar.par_min), idx
        rank = np.full(idx.size, np.inf)
        # rank statistic |Δv̄| of each ambiguity's DD row; rows never tested rank last
        ok = amb_rows >= 0
        vals = np.abs(dv[amb_rows[ok]])
        rank[ok] = np.where(np.isfinite(vals), vals, 1e6)
        return resolve_par_ranked(a, Q, rank, min_size=cfg.ar.par_min, ratio_threshold=cfg.ar.ratio), idx
    except (ValueError, np.linalg.LinAlgError):
        return None


def rtk_step(
    eng: DDEngine,
    state: GaussianState,
    t: float,
    rover: ObsEpoch,
    base: ObsEpoch,
    groups: list[str],
    avail: np.ndarray,
    refs: dict[str, str],
    code_dd: DDSet,
    tx_pos: FloatArray,
    base_range: FloatArray,
    pos_prior: FloatArray,
) -> tuple[Solution, list[DiagRow]]:
    """One RTK epoch (see module docstring)."""
    cfg = eng.cfg
    dd = _phase_dd(eng, rover, base, groups, avail, refs, pos_prior, tx_pos)
    if dd.m < 1:
        eng.state = state
        return eng._solution(state, t, "none", 0), []
    lam = _wavelengths(rover, eng.signal, dd)
    z_cyc, hard, soft = _slips(eng, rover, base, dd, refs, t)
    # deferred slips: reset once a flagged row has stayed rejected for SLIP_CONFIRM epochs
    keys: list[Hashable] = [(tx, g) for tx, g in zip(dd.tx, dd.group, strict=True)]
    for i, key in enumerate(keys):
        if soft[i] and key not in eng._suspect:
            eng._suspect[key] = 0  # suspicion starts; rejections are counted after updates
        if eng._suspect.get(key, 0) >= SLIP_CONFIRM:
            hard[i] = True
            eng._suspect.pop(key, None)
    state = _manage_ambiguities(eng, state, dd, z_cyc, lam, hard, tx_pos, base_range)
    amb_idx = np.array([state.layout.amb_index(k) for k in keys], dtype=np.int64)
    phase_model = DDRangeModel(
        tx_pos_m=tx_pos,
        base_range_m=base_range,
        i_tx=dd.i_tx,
        i_ref=dd.i_ref,
        pos_slice=state.layout.slice("pos"),
        amb_idx=amb_idx,
        wavelength_m=lam,
        z=z_cyc * lam,
        R=dd.R * np.outer(lam, lam),
        labels=dd.labels,
        sagnac=eng.sagnac,
        tx_corr_m=eng.tx_corr_m,
    )
    parts = [phase_model]
    kinds = ["phase"] * dd.m
    if (cfg.measurement.rtk_use_code or not cfg.estimator.known_point) and code_dd.m:
        parts.append(eng._model(code_dd, tx_pos, base_range, state, None, None))
        kinds += ["code"] * code_dd.m
    model = StackedModel(tuple(parts)) if len(parts) > 1 else phase_model
    res = eng.filter.update(state, model, eng.robust)
    post = res.state
    # a suspect row that the robust filter accepted again was a transient error
    # (an error that ends shows a second jump, back: only rejections count, so a row the
    # filter accepts again is cleared however many jumps it showed)
    for i, key in enumerate(keys):
        if key in eng._suspect and res.situation[i] == 1:
            eng._suspect.pop(key, None)
        elif key in eng._suspect and res.situation[i] == 3:
            eng._suspect[key] += 1
    labels = tuple(model.labels)
    diag = eng._diag(t, labels, kinds, res)

    # ambiguity resolution on the float state
    amb_keys = post.layout.amb_keys
    row_of: dict[Hashable, int] = {k: i for i, k in enumerate(keys)}
    amb_rows = np.array([row_of.get(k, -1) for k in amb_keys], dtype=np.int64)
    cand = _ar_candidates(eng, list(amb_keys), amb_rows, dd)
    resolved = _resolve(eng, post, amb_rows, res.dv[: dd.m], cand)
    status = "float"
    out_state = post
    ratio = float("nan")
    n_fixed = 0
    if resolved is not None:
        fix, idx = resolved
        ratio = float(fix.ratio)
        # the ratio test alone accepts wrong sets when the float solution is weak: also
        # require the bootstrapped success rate of the accepted subset
        if fix.validated and fix.subset.size and fix.success_rate >= cfg.ar.min_success_rate:
            xf, Pf = conditional_update(post.x, post.P, idx[fix.subset], fix.fixed[fix.subset])
            out_state = post.with_(x=xf, P=Pf)
            n_fixed = int(fix.subset.size)
            status = "fixed" if n_fixed == len(amb_keys) else "partial"
            if cfg.ar.fix_max_sigma_m > 0:
                sigma = float(np.sqrt(np.trace(out_state.cov("pos"))))
                if sigma > cfg.ar.fix_max_sigma_m:
                    status = "float"  # integers validated, geometry too weak for cm precision
            eng._fix_streak += 1
            if cfg.ar.hold and not cfg.ar.instantaneous and eng._fix_streak >= cfg.ar.hold_min_fix:
                post = _hold(post, idx[fix.subset], fix.fixed[fix.subset], cfg.ar.hold_sigma_cyc)
        else:
            eng._fix_streak = 0
    else:
        eng._fix_streak = 0
    if cfg.ar.instantaneous and status in ("fixed", "partial"):
        # single-epoch AR: the next epoch starts from this epoch's fixed solution, mean and
        # covariance. The float covariance must not be carried: with new ambiguities every
        # epoch the phase adds no position information to it, so it only grows.
        post = out_state
    eng.state = post
    sol = eng._solution(out_state, t, status, res.n_used, ratio=ratio, n_fixed=n_fixed, n_amb=len(amb_keys))
    return sol, diag


def _hold(state: GaussianState, idx: np.ndarray, values: FloatArray, sigma_cyc: float) -> GaussianState:
    """Fix-and-hold: update the filter with pseudo-observations ``x[idx] = values``."""
    H = np.zeros((idx.size, state.n))
    H[np.arange(idx.size), idx] = 1.0
    meas = LinearMeasurement(H, np.asarray(values, float), np.eye(idx.size) * sigma_cyc**2)
    return EKF().update(state, meas).state
