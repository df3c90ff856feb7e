"""Carrier-phase RTK stage of the DD engine.

Per epoch (the engine has predicted the state, chosen references and formed the DD code):

1. DD phase (cycles) against the same references as the code; slips from LLI (either
   receiver, either transmitter of the DD) and from the polynomial-fit detector on each
   DD phase series (integer jumps repaired, others reset — or, with a robust policy,
   deferred: a transient gross error is the robust filter's business, and only a jump
   that is still rejected ``SLIP_CONFIRM`` epochs later resets the ambiguity).
2. Ambiguity states (cycles), one per :class:`~robustrtk.ambiguity.book.AmbKey`, added
   diffuse around ``(z − ρ(x̄))/λ`` when a DD appears, dropped when it disappears or its
   reference changes, reset on slips; all re-added every epoch in instantaneous
   (single-epoch) AR, where each epoch starts from the previous epoch's fixed solution.
3. Filter update with DD phase (and optionally DD code) and the robust policy.
4. Integer resolution: full LAMBDA, PAR ranked by |Δv̄| (Li et al.), or PAR by success
   rate; the fixed solution is the conditional update of the state on the validated
   subset (``docs/algorithms.md`` §8). Fix-and-hold feeds the validated integers back to
   the filter as pseudo-observations.

Two AR schemes (``ar.scheme``). ``filter``: the filter's own covariance carries the
position from epoch to epoch (with fix-and-hold, continuous or single-epoch AR).
``prior`` (Li et al. 2019, Sec. 2.1; ``docs/algorithms.md`` §20): known-point
initialisation, then every epoch's float solution starts from the previous epoch's
reported coordinate (fixed when that epoch fixed) with the covariance
``σ_prior² I`` and no correlation with the other states, the ambiguities carried as
float estimates or re-estimated every epoch, AR at every epoch and no hold.

All bookkeeping lives in the engine's :class:`~robustrtk.ambiguity.book.AmbiguityBook`;
the stage's own memory is the polynomial detector and the run of consecutive fixes.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from robustrtk.ambiguity.book import AmbiguityBook, AmbKey, rereference_map
from robustrtk.ambiguity.par import (
    FixResult,
    resolve_full,
    resolve_par_ranked,
    resolve_par_success_rate,
)
from robustrtk.core import BoolArray, FloatArray, ObsEpoch, Solution, replaced
from robustrtk.cycleslip.polyfit import PolyFitDetector
from robustrtk.estimation.adaptive import AdaptiveFactor, adaptive_update
from robustrtk.estimation.filters import Filter
from robustrtk.estimation.robust import NoRobust, RobustPolicy
from robustrtk.estimation.state import GaussianState, UpdateResult
from robustrtk.measurement.dd import (
    DDRangeModel,
    DDRows,
    DDSet,
    RangeMemo,
    RowModel,
    StackedModel,
    dd_range_model,
    form_dd,
)
from robustrtk.measurement.glonass import SdAmbiguityMeans, fdma_phase_dd
from robustrtk.pipeline.config import Config
from robustrtk.pipeline.results import DiagRow, adaptive_row, diag_rows, solution_of
from robustrtk.pipeline.rtk_fix import (
    age_free_share,
    amb_keys_of,
    coordinate_prior,
    fixed_phase_factor,
    fixed_residuals_ok,
    hold,
)

#: Consecutive epochs a flagged, robustly rejected DD must stay rejected before its
#: ambiguity is reset as a real slip.
SLIP_CONFIRM = 3


@dataclass(frozen=True)
class DDEpoch:
    """What the engine computed for one epoch, handed to the RTK stage.

    Attributes
    ----------
    t_s : float
    rover, base : ObsEpoch
        The base reindexed to the rover's rows.
    groups : list of str
        DD group of each row.
    avail : ndarray of bool, shape (N,)
        Rows usable at both receivers.
    refs : dict str -> str
        Reference transmitter per group.
    code_dd : DDSet
        DD code (m).
    tx_pos_m : ndarray, shape (N, 3)
    base_range_m : ndarray, shape (N,)
        Base ranges (+ the base's delays).
    tx_corr_m : ndarray, shape (N,), optional
        Delays of the rover ranges at the prior position.
    elev_rad : ndarray, shape (N,)
        Elevation of each row at the prior position.
    var_phase_r_m2, var_phase_b_m2 : ndarray, shape (N,)
        Undifferenced phase variances (m²) at each receiver.
    slip, half_cycle : ndarray of bool, shape (N,), optional
        Per-epoch detector flags (see :class:`robustrtk.pipeline.results.EpochInputs`).
    dd_rows : DDRows, optional
        The DD rows of the epoch's available transmitters
        (:func:`robustrtk.measurement.dd.dd_rows`), reused by the DD phase when its rows
        are the same.
    base_age_var_m2 : float
        Age variance (m²) in each undifferenced base row's variance (a base epoch carried
        to the rover's tag, :func:`robustrtk.measurement.base_propagation.with_age`).
    range_memo : RangeMemo, optional
        The epoch's rover ranges (:class:`robustrtk.measurement.dd.RangeMemo`), shared with
        the engine's DD code model.
    """

    t_s: float
    rover: ObsEpoch
    base: ObsEpoch
    groups: list[str]
    avail: BoolArray
    refs: dict[str, str]
    code_dd: DDSet
    tx_pos_m: FloatArray
    base_range_m: FloatArray
    tx_corr_m: FloatArray | None
    elev_rad: FloatArray
    var_phase_r_m2: FloatArray
    var_phase_b_m2: FloatArray
    slip: BoolArray | None = None
    half_cycle: BoolArray | None = None
    dd_rows: DDRows | None = None
    base_age_var_m2: float = 0.0
    range_memo: RangeMemo | None = None


@dataclass(frozen=True)
class RtkOutcome:
    """One RTK epoch: the state the next epoch starts from, the solution, the update."""

    next_state: GaussianState
    solution: Solution
    diagnostics: list[DiagRow]
    update: UpdateResult | None


class RtkStage:
    """The carrier-phase part of one engine epoch (see the module docstring).

    Parameters
    ----------
    cfg : Config
    book : AmbiguityBook
        The engine's ambiguity bookkeeping (shared, mutated by the stage).
    filter : Filter
    robust : RobustPolicy
    sagnac : bool
    signal : int
        Signal column of the epochs.
    """

    def __init__(
        self,
        cfg: Config,
        book: AmbiguityBook,
        filter: Filter,
        robust: RobustPolicy,
        sagnac: bool,
        signal: int,
        adaptive: AdaptiveFactor | None = None,
    ) -> None:
        self.cfg = cfg
        self.book = book
        self.filter = filter
        self.robust = robust
        self.adaptive = adaptive
        self.sagnac = sagnac
        self.signal = signal
        self.poly: PolyFitDetector | None = None
        self.poly_refs: dict[str, str] = {}
        self.fix_streak = 0
        # the prior scheme resets the position prior from the second epoch on
        self.started = False
        # validated integers of the previous epoch and the run of epochs that agree with them
        self.prev_fix: dict[AmbKey, float] = {}
        self.agree_streak = 0
        self.last_refs: dict[str, str] = {}  # the latest reference of every group
        # single-difference ambiguities of GLONASS rows (FDMA DD phase)
        self.sd_amb = SdAmbiguityMeans()

    @property
    def single_epoch(self) -> bool:
        """Every epoch starts with new ambiguities (single-epoch AR, or the prior scheme
        with re-estimated ambiguities)."""
        ar = self.cfg.ar
        if ar.scheme == "prior":
            return ar.prior_ambiguities == "reestimate"
        return ar.instantaneous

    # ------------------------------------------------------------------ reference change
    def ref_change(self, old: dict[str, str], new: dict[str, str], state: GaussianState) -> GaussianState:
        """Re-express the ambiguities of groups whose reference changed (no reset). A group
        absent from ``old`` (an epoch without its phases) keeps its last reference."""
        last, self.last_refs = self.last_refs, {**self.last_refs, **new}
        if not state.layout.amb_keys:
            return state
        for g, new_ref in new.items():
            old_ref = old.get(g, last.get(g))
            if old_ref is None or old_ref == new_ref:
                continue
            mapped = rereference_map(amb_keys_of(state), state.layout.n_fixed, g, old_ref, new_ref)
            if mapped is None:
                continue
            T, keys = mapped
            self.prev_fix = {k: v for k, v in self.prev_fix.items() if k.signal != g}
            P = T @ state.P @ T.T
            state = state.with_(x=T @ state.x, P=0.5 * (P + P.T), layout=state.layout.__class__(
                blocks=state.layout.blocks, amb_keys=keys))  # fmt: skip
            self.book.rereference(g, old_ref, new_ref)
        return state

    # ------------------------------------------------------------------ pieces
    def _phase_dd(self, ep: DDEpoch) -> DDSet:
        k = self.signal
        lam = ep.rover.wavelength_m[:, k]
        ph_r = np.where(ep.avail, ep.rover.phase_cyc[:, k], np.nan)
        ph_b = np.where(ep.avail, ep.base.phase_cyc[:, k], np.nan)
        var_r, var_b = ep.var_phase_r_m2 / lam**2, ep.var_phase_b_m2 / lam**2
        dd = form_dd(ep.rover.tx_ids, ep.groups, ph_r, ph_b, var_r, var_b, ep.refs, ep.dd_rows)
        if "R" not in ep.rover.system:
            return dd
        # FDMA: rows of different wavelengths in metres, with the reference's SD ambiguity
        sd = ph_r - ph_b - (ep.rover.code_m[:, k] - ep.base.code_m[:, k]) / lam
        restart = ((ep.rover.lli[:, k] | ep.base.lli[:, k]) & 1).astype(bool)
        if ep.slip is not None:
            restart |= np.asarray(ep.slip, bool)
        var1 = 2.0 * self.cfg.measurement.code_sigma_m**2 / lam**2
        # only the GLONASS rows' means are used (a row of another system has the wavelength
        # of its reference, so fdma_phase_dd leaves it as it is): the running means of those
        # rows alone, NaN elsewhere
        glo = [i for i, s in enumerate(ep.rover.system) if s == "R"]
        ids = ep.rover.tx_ids
        n_g, var_g = self.sd_amb.update(ep.t_s, [ids[i] for i in glo], sd[glo], var1[glo], restart[glo])
        n_sd = np.full(len(ids), np.nan)
        var_n = np.full(len(ids), np.nan)
        n_sd[glo] = n_g
        var_n[glo] = var_g
        return fdma_phase_dd(dd, ph_r, ph_b, ep.var_phase_r_m2, ep.var_phase_b_m2, lam, n_sd, var_n)

    def _slips(self, ep: DDEpoch, dd: DDSet) -> tuple[FloatArray, BoolArray, BoolArray]:
        """Repaired DD phase (cycles), hard-slip mask and soft (deferred) slip mask per row."""
        k = self.signal
        cfg = self.cfg
        det = cfg.slip_detectors()
        z = dd.z.copy()
        hard = np.zeros(dd.m, dtype=bool)
        soft = np.zeros(dd.m, dtype=bool)
        robust = not isinstance(self.robust, NoRobust)
        if "lli" in det:
            lli = (ep.rover.lli[:, k] & 1) | (ep.base.lli[:, k] & 1)
            hard |= (lli[dd.i_tx] | lli[dd.i_ref]).astype(bool)
        if ep.slip is not None:
            # undifferenced detectors (geometry-free, Doppler) of either receiver, per row
            ext = np.asarray(ep.slip, bool)
            flagged = ext[dd.i_tx] | ext[dd.i_ref]
            if robust:
                soft |= flagged & ~hard
            else:
                hard |= flagged
        if "poly" in det:
            if ep.refs != self.poly_refs or self.poly is None:
                lam_mean = float(np.nanmean(ep.rover.wavelength_m[:, k]))
                self.poly = PolyFitDetector(
                    window=10, degree=2, threshold_sigma=6.0,
                    noise_cyc=max(2.0 * cfg.measurement.phase_sigma_m / lam_mean, 1e-3),
                )  # fmt: skip
                self.poly_refs = dict(ep.refs)
            series = np.full(ep.rover.n_tx, np.nan)
            series[dd.i_tx] = dd.z
            series[dd.i_tx[hard]] = np.nan  # LLI slips restart their series
            mask, repaired, jump = self.poly.step(ep.t_s, series)
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

    def _manage(
        self, state: GaussianState, ep: DDEpoch, dd: DDSet, keys: list[AmbKey], z_cyc: FloatArray,
        lam: FloatArray, hard: BoolArray,
    ) -> GaussianState:  # fmt: skip
        """Drop vanished, re-referenced and slipped ambiguities; add new ones."""
        book = self.book
        ref_of = dict(zip(dd.group, dd.ref, strict=True))
        present = set(keys)
        drop = book.stale(amb_keys_of(state), present, ref_of)
        if self.single_epoch:
            drop = list(amb_keys_of(state))
        for i, key in enumerate(keys):
            if hard[i] and key in state.layout.amb_keys and key not in drop:
                drop.append(key)
        state = state.drop_ambiguities(drop)
        book.forget(drop)
        for k in drop:  # a reset ambiguity's new integer is not a disagreement
            self.prev_fix.pop(k, None)
        have = set(state.layout.amb_keys)
        new = [i for i, key in enumerate(keys) if key not in have]
        book.tick(k for k in keys if k in have)
        if new:
            geo = dd_range_model(
                dd, ep.tx_pos_m, ep.base_range_m, state.layout.slice("pos"), sagnac=self.sagnac,
                tx_corr_m=ep.tx_corr_m, memo=ep.range_memo,
            ).h(state.x)  # fmt: skip
            vals = (z_cyc[new] * lam[new] - geo[new]) / lam[new]
            state = state.add_ambiguities([keys[i] for i in new], vals, self.cfg.ar.amb_init_sigma_cyc**2)
            for i in new:
                book.add(keys[i], dd.ref[i])
        return state

    def _candidates(
        self, amb_keys: tuple[AmbKey, ...], rows: np.ndarray, dd: DDSet, ep: DDEpoch
    ) -> BoolArray:
        """Mask over ``amb_keys`` of the ambiguities allowed into integer resolution: tracked
        for ``ar_lock_epochs``, above ``ar_elev_mask_deg`` and free of half-cycle flags."""
        ar = self.cfg.ar
        ok = rows >= 0
        if ar.ar_lock_epochs > 0 and not self.single_epoch:  # single-epoch AR: every epoch is new
            ok &= np.array(self.book.locked(amb_keys, ar.ar_lock_epochs), dtype=bool)
        if ar.ar_elev_mask_deg > 0:
            el = np.full(len(amb_keys), -np.inf)
            el[ok] = ep.elev_rad[dd.i_tx[rows[ok]]]
            ok &= el >= np.deg2rad(ar.ar_elev_mask_deg)
        if ep.half_cycle is not None:
            half = np.asarray(ep.half_cycle, bool)
            flag = np.zeros(len(amb_keys), dtype=bool)
            flag[ok] = half[dd.i_tx[rows[ok]]] | half[dd.i_ref[rows[ok]]]
            ok &= ~flag
        if self.cfg.gnss.glonass_ar != "on":  # float-only GLONASS (inter-channel biases)
            ok &= np.array([not k.tx.startswith("R") for k in amb_keys], dtype=bool)
        return ok

    def _resolve(
        self, state: GaussianState, amb_rows: np.ndarray, dv: FloatArray, cand: BoolArray,
        phase_model: tuple[DDRangeModel, float] | None = None, amb_idx: np.ndarray | None = None,
    ) -> tuple[FixResult, np.ndarray] | None:  # fmt: skip
        """Integer resolution over the candidates; the result and the candidates' state indices.

        With ``ar.fix_residual_k > 0`` a ratio-validated subset is accepted only when the
        fixed solution passes :func:`fixed_residuals_ok` on ``phase_model``'s rows.
        ``amb_idx``: ``state.layout.amb_indices()`` when the caller has it."""
        ar = self.cfg.ar
        idx = (state.layout.amb_indices() if amb_idx is None else amb_idx)[cand]
        amb_rows = amb_rows[cand]
        if ar.method == "off" or idx.size == 0:
            return None
        a = state.x[idx]
        Q = state.P[idx[:, None], idx]  # P[ix_(idx, idx)]
        Q = 0.5 * (Q + Q.T)
        accept: Callable[[np.ndarray, FloatArray], bool] | None = None
        if phase_model is not None and phase_model[1] > 0:
            pm, k = phase_model

            def accept_fn(sub: np.ndarray, values: FloatArray) -> bool:
                return fixed_residuals_ok(state, pm, idx[sub], values, k)

            accept = accept_fn

        try:
            if ar.method == "lambda" or idx.size < ar.par_min:
                return resolve_full(a, Q, ratio_threshold=ar.ratio, accept=accept), idx
            if ar.method in ("par-sr", "par-sr+par"):
                sr = resolve_par_success_rate(a, Q, ratio_threshold=ar.ratio, min_size=ar.par_min)
                if accept is not None and sr.validated and not accept(sr.subset, sr.fixed[sr.subset]):
                    sr = replace(sr, validated=False, status="float", subset=sr.subset[:0])
                if ar.method == "par-sr" or sr.validated:
                    return sr, idx
                # the best-determined subset failed: one biased ambiguity (a drifting or
                # half-cycle phase) can spoil it; rank by the rows' Δv̄ instead
            rank = np.full(idx.size, np.inf)
            # rank statistic |Δv̄| of each ambiguity's DD row; rows never tested rank last
            ok = amb_rows >= 0
            vals = np.abs(dv[amb_rows[ok]])
            rank[ok] = np.where(np.isfinite(vals), vals, 1e6)
            fix = resolve_par_ranked(a, Q, rank, min_size=ar.par_min, ratio_threshold=ar.ratio, accept=accept)
            return fix, idx
        except (ValueError, np.linalg.LinAlgError):
            return None

    def _confirm(self, fixed: dict[AmbKey, float]) -> bool:
        """Whether this epoch's validated integers may be reported (``fix_confirm_epochs``).

        A validated set counts toward confirmation when the previous epoch also validated
        and every ambiguity fixed at both epochs has the same integer; a set that changes
        an integer starts a new run. The fix is reported once the run reaches
        ``fix_confirm_epochs`` epochs (0 or 1: at once). A wrong set that passes the ratio
        test on one epoch rarely passes it again with the same integers on the next, when
        the float solution has moved by its own noise (algorithms.md § 24).
        """
        common = [k for k in fixed if k in self.prev_fix]
        agree = bool(common) and all(self.prev_fix[k] == fixed[k] for k in common)
        self.agree_streak = self.agree_streak + 1 if agree else 1
        self.prev_fix = fixed
        return self.agree_streak >= self.cfg.ar.fix_confirm_epochs

    # ------------------------------------------------------------------ the epoch
    def code_only(self, state: GaussianState, t: float, model: RowModel | None) -> RtkOutcome:
        """An epoch without DD phase: the filter updated with the DD code rows alone, reported
        as a code (DGNSS) solution; the ambiguity states ride along (a phase that comes back
        on the same arc finds them; a slip is the LLI's and detectors' business). Fewer than
        three rows give no solution (as DGNSS)."""
        if model is None or len(model.labels) < 3:
            return RtkOutcome(state, solution_of(state, t, "none", 0), [], None)
        res, adapt = adaptive_update(self.filter, state, model, self.robust, self.adaptive)
        diag = diag_rows(t, tuple(model.labels), ["code"] * len(model.labels), res)
        if adapt is not None:
            diag.append(adaptive_row(t, adapt))
        return RtkOutcome(res.state, solution_of(res.state, t, "code", res.n_used), diag, res)

    def step(
        self,
        state: GaussianState,
        ep: DDEpoch,
        code_model: RowModel | None,
        code_fallback: RowModel | None = None,
    ) -> RtkOutcome:
        """One RTK epoch from the predicted, re-referenced state (see the module docstring).

        ``code_model`` holds the DD code rows to add to the update (None: phase only). An
        epoch without a DD phase (no phase at either receiver) is solved from the DD code
        alone (``code_model``, else ``code_fallback``): status ``code`` (DGNSS), the
        ambiguities carried unchanged (:meth:`code_only`).
        """
        cfg = self.cfg
        book = self.book
        t = ep.t_s
        dd = self._phase_dd(ep)
        if dd.m < 1:
            return self.code_only(state, t, code_model if code_model is not None else code_fallback)
        prior_scheme = cfg.ar.scheme == "prior"
        if prior_scheme and self.started:
            state = coordinate_prior(state, cfg.ar.prior_sigma_m, cfg.ar.prior_covariance)
        self.started = True
        lam = np.asarray(ep.rover.wavelength_m[dd.i_tx, self.signal], float)
        z_cyc, hard, soft = self._slips(ep, dd)
        keys = book.keys(dd.tx, dd.group)
        # deferred slips: reset once a flagged row has stayed rejected for SLIP_CONFIRM epochs
        # (a flagged row becomes suspect; its rejections are counted after the update)
        for i in book.confirmed_slips(keys, soft.tolist(), SLIP_CONFIRM):
            hard[i] = True
        state = self._manage(state, ep, dd, keys, z_cyc, lam, hard)
        amb_idx = state.layout.amb_indices(keys).astype(np.int64, copy=False)
        phase_model = dd_range_model(
            dd, ep.tx_pos_m, ep.base_range_m, state.layout.slice("pos"), amb_idx=amb_idx, wavelength_m=lam,
            z_m=z_cyc * lam, R_m2=dd.R * (lam[:, None] * lam[None, :]),  # R · outer(λ, λ)
            sagnac=self.sagnac, tx_corr_m=ep.tx_corr_m, memo=ep.range_memo,
        )  # fmt: skip
        kinds = ["phase"] * dd.m
        model: RowModel = phase_model
        if code_model is not None and len(code_model.labels):
            model = StackedModel((phase_model, code_model))
            kinds += ["code"] * len(code_model.labels)
        res, adapt = adaptive_update(self.filter, state, model, self.robust, self.adaptive)
        post = res.state
        # a suspect row that the robust filter accepted again was a transient error
        # (an error that ends shows a second jump, back: only rejections count, so a row the
        # filter accepts again is cleared however many jumps it showed)
        book.judge_all(keys, res.situation[: len(keys)].tolist())
        diag = diag_rows(t, tuple(model.labels), kinds, res)
        if adapt is not None:
            diag.append(adaptive_row(t, adapt))

        # ambiguity resolution on the float state
        amb_keys = amb_keys_of(post)
        row_of = {k: i for i, k in enumerate(keys)}
        amb_rows = np.array([row_of.get(k, -1) for k in amb_keys], dtype=np.int64)
        cand = self._candidates(amb_keys, amb_rows, dd, ep)
        post_idx = post.layout.amb_indices()
        resolved = self._resolve(
            post, amb_rows, res.dv[: dd.m], cand, (phase_model, cfg.ar.fix_residual_k), post_idx
        )
        status = "float"
        out_state = post
        ratio = float("nan")
        n_fixed = 0
        fixed_ok = False
        if resolved is not None:
            fix, idx = resolved
            ratio = float(fix.ratio)
            # the ratio test alone accepts wrong sets when the float solution is weak: also
            # require the bootstrapped success rate of the accepted subset
            fixed_ok = bool(fix.validated and fix.subset.size and fix.success_rate >= cfg.ar.min_success_rate)
            if fixed_ok:
                sel = idx[fix.subset]
                vals = fix.fixed[fix.subset]
                key_of = dict(zip(post_idx.tolist(), amb_keys, strict=False))
                fixed_keys = [key_of[s] for s in sel.tolist()]
                book.set_fixed(fixed_keys, vals)
                confirmed = self._confirm(dict(zip(fixed_keys, vals.tolist(), strict=True)))
                if confirmed:
                    out_state = post.conditional_update(sel, vals)
                    n_fixed = int(fix.subset.size)
                    status = "fixed" if n_fixed == len(amb_keys) else "partial"
                if confirmed and cfg.ar.fix_max_sigma_m > 0:
                    sigma = float(np.sqrt(out_state.cov("pos").trace()))
                    if sigma > cfg.ar.fix_max_sigma_m and ep.base_age_var_m2 > 0.0:
                        # the geometry's precision, not the base's age (already in the weights)
                        sigma *= np.sqrt(
                            age_free_share(out_state, phase_model, sel, dd, ep.rover.n_tx, ep.base_age_var_m2)
                        )
                    if sigma > cfg.ar.fix_max_sigma_m:
                        status = "float"  # integers validated, geometry too weak for cm precision
                self.fix_streak += 1
                use_hold = cfg.ar.hold and not cfg.ar.instantaneous and not prior_scheme
                if confirmed and use_hold and self.fix_streak >= cfg.ar.hold_min_fix:
                    post = hold(post, sel, vals, cfg.ar.hold_sigma_cyc)
        if not fixed_ok:
            self.fix_streak = 0
            self.prev_fix = {}
            self.agree_streak = 0
        if prior_scheme:
            # the next epoch's prior is this epoch's reported coordinate (its covariance is
            # reset there); the ambiguities stay float estimates
            x = post.x.copy()
            p = post.layout.slice("pos")
            x[p] = out_state.x[p]
            post = post.with_(x=x)
        elif cfg.ar.instantaneous and status in ("fixed", "partial"):
            # single-epoch AR: the next epoch starts from this epoch's fixed solution, mean and
            # covariance. The float covariance must not be carried: with new ambiguities every
            # epoch the phase adds no position information to it, so it only grows.
            post = out_state
        sol = solution_of(out_state, t, status, res.n_used, ratio=ratio, n_fixed=n_fixed, n_amb=len(amb_keys))
        if status in ("fixed", "partial"):
            # the σ the phase residuals support (algorithms.md §38)
            fixed_idx = set(idx[fix.subset].tolist()) if resolved is not None else set()
            floating = amb_rows[[i not in fixed_idx for i in post_idx.tolist()]]
            f = fixed_phase_factor(phase_model, out_state, res.factors[: dd.m], floating)
            sol = replaced(sol, cov_m2=sol.cov_m2 * f)
        return RtkOutcome(post, sol, diag, res)


__all__ = [
    "SLIP_CONFIRM",
    "DDEpoch",
    "RtkOutcome",
    "RtkStage",
    "rereference_map",
]
