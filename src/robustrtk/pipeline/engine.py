"""The per-epoch step of double-differenced positioning (DPL, DGNSS and RTK).

:class:`DDEngine` owns the step (the loop is :mod:`robustrtk.pipeline.loop`; its parts are
:mod:`~robustrtk.pipeline.engine_setup`, :mod:`~robustrtk.pipeline.rows`,
:mod:`~robustrtk.pipeline.geometry_cache`): per epoch it predicts the state, picks
references, forms DD code (``measurement.dd``), runs the filter update with the robust
policy (``estimation``) — or hands the epoch to the carrier-phase stage
(:class:`robustrtk.pipeline.rtk.RtkStage`) — and returns an
:class:`~robustrtk.pipeline.results.EpochResult`. Everything an epoch needs arrives as
an :class:`~robustrtk.pipeline.results.EpochInputs` argument; the filter, process model,
robust policy and adaptive factor are instances passed in (built from the configuration
when not given); the ambiguity bookkeeping is one
:class:`~robustrtk.ambiguity.book.AmbiguityBook`; the base is a receiver whose position
comes from a :class:`~robustrtk.geometry.receivers.PositionSource` (it may move).
Transmitter positions come from a :class:`~robustrtk.core.TransmitterSource`; pseudolites
and satellites run through the same code (satellites add the Sagnac term and need
per-epoch positions).

Moving receivers: a wrong dynamic model (a car filtered as static) makes every DD
inconsistent with the prediction, and a robust filter would reject them all and lock up.
Two guards: the optional adaptive factor (``estimator.adaptive``) inflates the predicted
covariance when the predicted-state discrepancy (``state``, algorithms.md §23) or the median
standardized innovation (``innovation``) says the prediction is off
(:mod:`robustrtk.estimation.adaptive`; an ``adaptive`` diagnostics row per epoch), and
after ``estimator.reinit_epochs`` epochs in a row in which the robust update rejected most
rows, the filter restarts from a single-epoch least-squares solution (a ``reinit`` row in
the diagnostics).

DGNSS with the rover's Doppler: each epoch's velocity snapshot of its Doppler rows
(:mod:`robustrtk.measurement.doppler_velocity`, algorithms.md §44) is a measurement of the
velocity state, stacked with the DD code rows; with ``measurement.dgnss_doppler_jerk_m_s3``
a moving rover's prediction is the previous posterior carried by the Doppler velocities.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import numpy as np

from robustrtk.ambiguity.book import AmbiguityBook
from robustrtk.core import (
    FloatArray,
    ObsEpoch,
    TransmitterSource,
    replaced,
)
from robustrtk.estimation.adaptive import (
    AdaptiveFactor,
    MotionSelector,
    StationaryModel,
    adaptive_update,
)
from robustrtk.estimation.filters import Filter
from robustrtk.estimation.integrity import (
    IntegrityMonitor,
    IntegrityPolicy,
    Snapshot,
    covariance_floor,
    fixed_position_agrees,
    reinitialise,
    robust_snapshot,
)
from robustrtk.estimation.models import ProcessModel
from robustrtk.estimation.prior_scale import apply_prior_scale
from robustrtk.estimation.registry import make_robust_policy
from robustrtk.estimation.robust import RobustPolicy
from robustrtk.estimation.state import GaussianState, UpdateResult
from robustrtk.geometry.receivers import PositionSource, as_position_source
from robustrtk.measurement.base_propagation import with_age
from robustrtk.measurement.dd import (
    DDRangeModel,
    DDSet,
    RangeMemo,
    StackedModel,
    choose_references,
    dd_range_model,
    dd_rows,
    form_dd,
    ranges,
)
from robustrtk.measurement.doppler_velocity import VelocityModel, doppler_velocity_model
from robustrtk.measurement.tdcp_carry import Displacement, PhaseEpoch, TdcpTracker
from robustrtk.pipeline.config import Config
from robustrtk.pipeline.engine_setup import (
    carried_prediction,
    initial_state,
    innovations,
    least_squares_fix,
    make_adaptive,
    make_filter,
    make_imm,
    make_process,
    rereference,
    restart_state,
    row_variances,
    with_unmodelled_errors,
)
from robustrtk.pipeline.geometry_cache import GeometryCache
from robustrtk.pipeline.reference_check import check_references
from robustrtk.pipeline.reinit import Streak, gap_exceeded
from robustrtk.pipeline.results import (
    DiagRow,
    EpochInputs,
    EpochResult,
    RunResult,
    adaptive_row,
    diag_rows,
    event_row,
    imm_rows,
    solution_of,
)
from robustrtk.pipeline.rows import (
    align_epochs,
    has_dd,
    position_queries,
    reindex,
    row_groups_of,
    row_map,
    take_rows,
)  # fmt: skip
from robustrtk.pipeline.rtk import DDEpoch, RtkStage
from robustrtk.pipeline.satcount import with_satellites

if TYPE_CHECKING:  # the smoother and the IMM are imported where they run (off by default in RTK)
    from robustrtk.estimation.imm import ImmTracker
    from robustrtk.estimation.smoother import FilterStep

#: An epoch counts toward re-initialisation when the robust update rejected at least this
#: fraction of its rows.
REINIT_REJECTED_FRACTION = 0.5


class DDEngine:
    """The epoch loop around immutable filter states (see the module docstring).

    Parameters
    ----------
    cfg : Config
    source : TransmitterSource
        Transmitter positions (local frame for pseudolites).
    base_pos_m : ndarray, shape (3,), or PositionSource
        The base position: a surveyed constant or a source per epoch (moving base);
        :attr:`EpochInputs.base_pos_m` overrides it for one epoch.
    rover_pos0_m : ndarray, shape (3,)
        Initial rover position.
    signal : int
        Signal column used (0 for single-frequency pseudolites and signal rows).
    sagnac : bool
        Satellite ranges in ECEF need the Earth-rotation term.
    reference : str or None
        Preferred reference transmitter.
    frame : {"local", "ecef"}
        ``"local"``: z-up local frame (pseudolites), elevations from the z axis;
        ``"ecef"``: satellites, elevations from the ellipsoid normal at the receiver and
        transmitters below ``elev_mask_deg`` left out.
    elev_mask_deg : float
        Elevation mask (deg), used only when ``frame == "ecef"``.
    row_groups : bool
        Rows are (transmitter, signal) pairs named ``"<tx>:<slot>"`` (multi-frequency GNSS,
        :func:`robustrtk.measurement.signals.signal_rows`): the DD group of a row is
        ``"<system>:<slot>"``. Otherwise the group is ``"<system>:<signal>"``.
    filter, process, robust : optional
        Estimator instances; built from ``cfg`` when None.
    adaptive : InnovationAdaptiveFactor, StateDiscrepancyFactor or None, optional
        Adaptive factor of the code and RTK updates
        (:func:`robustrtk.estimation.adaptive.adaptive_update`); from
        ``cfg.estimator.adaptive`` when not given.
    receivers : tuple of str
        ``(rover, base)`` names carried by the ambiguity keys.

    Notes
    -----
    In the ``"ecef"`` frame each receiver's satellite positions are computed at its own
    transmission times (its time tag minus its pseudorange over c), so base and rover
    time tags may differ by milliseconds (receiver clocks) without biasing the DDs.
    """

    def __init__(
        self,
        cfg: Config,
        source: TransmitterSource,
        base_pos_m: FloatArray | PositionSource,
        rover_pos0_m: FloatArray,
        signal: int = 0,
        sagnac: bool = False,
        reference: str | None = None,
        frame: str = "local",
        elev_mask_deg: float = 15.0,
        row_groups: bool = False,
        *,
        filter: Filter | None = None,
        process: ProcessModel | None = None,
        robust: RobustPolicy | None = None,
        adaptive: AdaptiveFactor | None | str = "config",
        receivers: tuple[str, str] = ("rover", "base"),
        integrity: IntegrityPolicy | None = None,
    ) -> None:
        if frame not in ("local", "ecef"):
            raise ValueError(f"frame: expected local or ecef, got {frame!r}")
        self.frame = frame
        self.geo = GeometryCache(frame)  # one epoch asks for the same geometry several times
        self.elev_mask_rad = float(np.deg2rad(elev_mask_deg))
        self.cfg = cfg
        self.source = source
        self.base = as_position_source(base_pos_m)
        self.rover_pos0_m = np.asarray(rover_pos0_m, float)
        self.signal = signal
        self.sagnac = sagnac
        self.filter = filter if filter is not None else make_filter(cfg)
        self.process = process if process is not None else make_process(cfg)
        # dynamics "auto": code modes mix stationary, cruising and manoeuvring models (IMM,
        # algorithms.md §32); RTK tries a stationary hypothesis first each epoch (MotionSelector)
        self.selector: MotionSelector | None = None
        self.stationary: StationaryModel | None = None
        self.imm: ImmTracker | None = make_imm(cfg) if process is None else None
        if cfg.estimator.dynamics == "auto" and self.imm is None:
            self.selector = MotionSelector()
            self.stationary = StationaryModel(q_m2_s=cfg.estimator.q_static_m2_s)
        self.moving = False
        if robust is None:
            rb = cfg.robust
            robust = make_robust_policy(
                rb.policy, k0=rb.k0, k1=rb.k1, prefit_k0=rb.prefit_k0, prefit_k1=rb.prefit_k1
            )
        self.robust = robust
        self.adaptive = make_adaptive(cfg) if isinstance(adaptive, str) else adaptive
        self.preferred_ref = reference
        self.refs: dict[str, str] = {}
        self.state: GaussianState | None = None
        self.row_groups = row_groups
        self.book = AmbiguityBook(receivers)
        self.rtk = (
            RtkStage(cfg, self.book, self.filter, self.robust, sagnac, signal, self.adaptive)
            if cfg.mode == "rtk"
            else None
        )
        self.bad_epochs = Streak(cfg.estimator.reinit_epochs)  # epochs in a row mostly rejected
        # the rover carried by its own phase between epochs (§45)
        tdcp = self.rtk is None and frame == "ecef" and cfg.measurement.dgnss_tdcp_carry
        self.tdcp = TdcpTracker() if tdcp else None
        self.reinits: list[float] = []
        # the prediction confronted with each epoch's own snapshot (algorithms.md §30)
        self.integrity = IntegrityMonitor(integrity or IntegrityPolicy())
        self.snapshot: Snapshot | None = None
        self.started = False  # an integrity test has run (the first one tests the starting guess)
        self.last_model: ProcessModel | None = None
        # forward records for the RTS smoother (code modes with estimator.smoother)
        self.steps: list[FilterStep] | None = [] if cfg.estimator.smoother and self.rtk is None else None
        self.floors: list[FloatArray | None] = []  # each step's snapshot covariance (the floor)

    # ------------------------------------------------------------------ helpers
    def groups(self, epoch: ObsEpoch) -> list[str]:
        """DD group of each row of ``epoch``."""
        if self.row_groups:
            return list(row_groups_of(tuple(epoch.system), tuple(epoch.tx_ids)))
        sig = epoch.signals[self.signal] if epoch.signals else "L1"
        return [f"{s}:{sig}" for s in epoch.system]

    def variances(
        self, sigma: float, epoch: ObsEpoch, pos_m: FloatArray, tx_pos: FloatArray, kind: str = "code"
    ) -> FloatArray:
        """:func:`~robustrtk.pipeline.engine_setup.row_variances`, plus the age variance of
        a base epoch carried to a later tag
        (:class:`~robustrtk.measurement.base_propagation.PropagatedEpoch`)."""
        var = row_variances(self.cfg, self.geo, self.signal, sigma, epoch, pos_m, tx_pos, kind)
        age_var = with_age(epoch)[1]
        return var + age_var if age_var > 0.0 else var

    def prefetch(self, inputs: Sequence[EpochInputs]) -> None:
        """Hand the satellite-position queries :meth:`step` will make for these epochs to the
        source's ``prefetch`` (when it has one), to be evaluated in a few vectorised calls
        instead of one or two per epoch. Results are unchanged."""
        pre = getattr(self.source, "prefetch", None)
        if pre is None:
            return
        pre(position_queries(inputs, self.signal, self.frame == "ecef", self.wants_doppler()))

    def wants_doppler(self) -> bool:
        """The DGNSS velocity rows of the rover's Doppler are on (§44): a code solution of
        satellites with ``measurement.dgnss_doppler``."""
        return self.rtk is None and self.frame == "ecef" and self.cfg.measurement.dgnss_doppler

    def step(self, inputs: EpochInputs) -> EpochResult:
        """Process one matched epoch pair; the engine's state moves to this epoch. The
        solution's ``n_sat`` counts the satellites of the rows used (:mod:`.satcount`)."""
        return with_satellites(self._solve_epoch(inputs), inputs.rover.tx_ids)

    def _solve_epoch(self, inputs: EpochInputs) -> EpochResult:
        cfg = self.cfg
        rover = inputs.rover
        base = reindex(inputs.base, rover.tx_ids)
        t = rover.t_s
        if self.state is None:
            self.state = initial_state(cfg, self.rover_pos0_m, t, self.process)
        prev = self.state
        if self.imm is not None:
            pos = prev.get("pos")
            up = pos / np.linalg.norm(pos) if self.frame == "ecef" and np.linalg.norm(pos) > 0 else None
            state = self.imm.predict(self.filter, prev, t, up)
            self.last_model = self.imm.dominant()
        else:
            state = self.filter.predict(prev, self.stationary or self.process, t)
            self.last_model = self.stationary or self.process
        base_pos = np.asarray(
            inputs.base_pos_m if inputs.base_pos_m is not None else self.base.position(t), float
        )
        if not np.isfinite(base_pos).all():
            self.state = state
            return EpochResult(solution_of(state, t, "none", 0), [], ("no base position",))
        pos_prior = state.get("pos")
        k = self.signal
        code_r, code_b = rover.code_m[:, k], base.code_m[:, k]
        tx_pos, tx_clk = self.source.positions(t, rover.tx_ids, code_r)
        if self.frame == "ecef":
            # the base's own transmission times (its tag and pseudoranges)
            tx_pos_b, _ = self.source.positions(base.t_s, rover.tx_ids, code_b)
        else:
            tx_pos_b = tx_pos
        tx_ok = np.logical_and.reduce(np.isfinite(tx_pos), axis=1) & np.logical_and.reduce(
            np.isfinite(tx_pos_b), axis=1
        )
        groups = self.groups(rover)
        avail = tx_ok & np.isfinite(code_r) & np.isfinite(code_b)
        phase_ok = None
        if cfg.mode == "rtk":
            phase_ok = np.isfinite(rover.phase_cyc[:, k]) & np.isfinite(base.phase_cyc[:, k])
        snr_mask = cfg.measurement.snr_mask_dbhz
        if snr_mask > 0:
            with np.errstate(invalid="ignore"):
                low = (rover.cn0_dbhz[:, k] < snr_mask) | (base.cn0_dbhz[:, k] < snr_mask)
            avail &= ~low
        tx_pos_safe = np.where(tx_ok[:, None], tx_pos, 0.0)
        tx_pos_b_safe = np.where(tx_ok[:, None], tx_pos_b, 0.0)
        elev = self.geo.elevation(pos_prior, tx_pos_safe)
        if self.frame == "ecef":
            avail &= elev >= self.elev_mask_rad
        phase_avail = avail
        if phase_ok is not None:
            phase_avail = avail & phase_ok
            if has_dd(groups, phase_avail) or not has_dd(groups, avail):
                avail = phase_avail
            # else: no DD phase at all this epoch (a receiver without phases): the DD code of
            # every row with code serves a code solution (RtkStage.code_only)
        preferred = {g: self.preferred_ref for g in set(groups)} if self.preferred_ref else None
        refs = choose_references(rover.tx_ids, groups, avail, elev, preferred, self.refs)
        base_range = ranges(base_pos, tx_pos_b_safe, self.sagnac)
        tx_corr = None
        if self.frame == "ecef" and cfg.measurement.tropo == "saastamoinen":
            base_range = base_range + self.geo.tropo(base_pos, tx_pos_b_safe)
            tx_corr = self.geo.tropo(pos_prior, tx_pos_safe)
        sigma_code = cfg.measurement.code_sigma_m
        var_code_r = self.variances(sigma_code, rover, pos_prior, tx_pos_safe)
        var_code_b = self.variances(sigma_code, base, base_pos, tx_pos_safe)
        # the rows of every DD set of the epoch (code, phase): observed and available
        rows = dd_rows(rover.tx_ids, groups, avail, refs)
        code_dd = form_dd(
            rover.tx_ids, groups, np.where(avail, code_r, np.nan), np.where(avail, code_b, np.nan),
            var_code_r, var_code_b, refs, rows,
        )  # fmt: skip
        pos_slice = state.layout.slice("pos")
        memo = RangeMemo()  # the epoch's rover ranges, shared by its code and phase models

        def code_model(dd: DDSet) -> DDRangeModel:
            return dd_range_model(
                dd, tx_pos_safe, base_range, pos_slice, sagnac=self.sagnac, tx_corr_m=tx_corr, memo=memo
            )

        check = self.rtk is None and code_dd.m >= 3 and self.frame == "ecef" and self.preferred_ref is None
        raw_dd = code_dd
        if check:
            # before the motion test: a faulty reference shifts every DD of its group
            code_dd = check_references(state, raw_dd, code_model(raw_dd), elev)
        if self.selector is not None:
            moving_state = self.filter.predict(prev, self.process, t)
            if code_dd.m > 0:
                model = code_model(code_dd)
                self.moving = self.selector.moving(
                    innovations(model, state), innovations(model, moving_state)
                )
            else:
                self.moving = False
            if self.moving:
                state = moving_state
                self.last_model = self.process
                if check:
                    code_dd = check_references(state, raw_dd, code_model(raw_dd), elev)
        # the DD code rows' model: the integrity snapshot's and the RTK update's rows
        dd_code_model = code_model(code_dd) if code_dd.m > 0 else None
        state, integ = self.check_integrity(prev, state, t, dd_code_model)
        if self.rtk is not None:
            state = self.rtk.ref_change(self.refs, refs, state)
        self.refs = refs
        if self.rtk is None:
            vel, disp = None, None
            with np.errstate(invalid="ignore"):  # the rover's own rows above the masks
                use = tx_ok & (elev >= self.elev_mask_rad) & ~(rover.cn0_dbhz[:, k] < snr_mask)
            if self.tdcp is not None:  # its TDCP displacement from the last epoch (§45)
                var_ph = self.variances(cfg.measurement.phase_sigma_m, rover, pos_prior, tx_pos_safe, "phase")
                disp = self.tdcp.step(PhaseEpoch(
                    t, rover.tx_ids, rover.phase_cyc, rover.lli, rover.doppler_hz, rover.cn0_dbhz,
                    rover.wavelength_m, np.where(use[:, None], tx_pos, np.nan), tx_clk, var_ph,
                ), prev.get("pos"), k)  # fmt: skip
            if self.wants_doppler() and state.layout.has("vel"):
                # the rover's own Doppler velocity (algorithms.md §44)
                vel = doppler_velocity_model(
                    self.source, t, rover.tx_ids, code_r, rover.doppler_hz[:, k], rover.wavelength_m[:, k],
                    rover.cn0_dbhz[:, k], pos_prior, tx_pos_safe, elev, use, state.layout.slice("vel"),
                    cfg.measurement.dgnss_doppler_sigma_m_s,
                )  # fmt: skip
            return self.with_integrity(self._step_code(state, t, code_dd, code_model, vel, disp), integ)
        sigma_ph = cfg.measurement.phase_sigma_m
        ep = DDEpoch(
            t_s=t, rover=rover, base=base, groups=groups, avail=phase_avail, refs=refs, code_dd=code_dd,
            tx_pos_m=tx_pos_safe, base_range_m=base_range, tx_corr_m=tx_corr, elev_rad=elev,
            var_phase_r_m2=self.variances(sigma_ph, rover, pos_prior, tx_pos_safe, "phase"),
            var_phase_b_m2=self.variances(sigma_ph, base, base_pos, tx_pos_safe, "phase"),
            slip=inputs.slip, half_cycle=inputs.half_cycle, dd_rows=rows if phase_avail is avail else None,
            base_age_var_m2=with_age(base)[1], range_memo=memo,
        )  # fmt: skip
        use_code = (cfg.measurement.rtk_use_code or not cfg.estimator.known_point) and code_dd.m > 0
        # the DD code also serves an epoch without phase (a code solution)
        out = self.rtk.step(state, ep, dd_code_model if use_code else None, dd_code_model)
        res = self.with_integrity(EpochResult(out.solution, out.diagnostics), integ, out.update)
        if (
            out.update is not None
            and out.solution.status in ("fixed", "partial")
            and res.solution.status == "float"
        ):
            # a fix the integrity test refused is not held either: the next epoch starts from
            # the float posterior, and the stage's run of fixes starts again
            self.state = out.update.state
            self.rtk.fix_streak = 0
            self.rtk.prev_fix = {}
            self.rtk.agree_streak = 0
        else:
            self.state = out.next_state
        return res

    # ------------------------------------------------------------------ integrity
    def check_integrity(
        self, prev: GaussianState, state: GaussianState, t: float, model: DDRangeModel | None
    ) -> tuple[GaussianState, list[DiagRow]]:
        """The predicted ``state`` tested against the epoch's robust snapshot of its DD code
        rows (:mod:`robustrtk.estimation.integrity`): widened when inconsistent,
        re-initialised from the snapshot (ambiguities dropped) when that persists or after
        a time gap. Returns the state and the epoch's ``integrity`` rows."""
        mon = self.integrity
        pol = mon.policy
        snap = None
        if model is not None:
            # the fit moves the position alone: a model of it without the other states' columns
            pm = model.on_position()
            snap = robust_snapshot(
                pm.h, pm.jacobian, pm.z, pm.R, state.x[model.pos_slice], pm.pos_slice,
                min_redundancy=pol.min_redundancy,
            )  # fmt: skip
        self.snapshot = snap if pol.enabled else None
        self.started, first = True, not self.started
        if self.snapshot is None or snap is None:
            return state, []
        if gap_exceeded(t, prev.t_s, pol.max_gap_s):
            mon.reinit_now()
            event = ("reinit", float("nan"), 1.0)
        else:
            state, ev = mon.check(state, snap, first=first)
            if ev is None or ev.kind == "ok":
                return state, []
            event = (ev.kind, ev.test, ev.scale)
        if event[0] == "reinit":
            state = state.drop_ambiguities(list(state.layout.amb_keys))
            self.book.forget(list(self.book))
            state = reinitialise(state, snap, max(self.cfg.estimator.init_sigma_vel_m_s, 10.0))
            self.reinits.append(t)
        nan = float("nan")
        return state, [DiagRow(t, f"integrity:{event[0]}", "integrity", nan, event[2], event[1], nan, nan, 0)]

    def with_integrity(
        self, res: EpochResult, rows: list[DiagRow], update: UpdateResult | None = None
    ) -> EpochResult:
        """The epoch's result with its integrity rows; a fix that disagrees with the float
        solution (``update``'s state) or the snapshot reported as float; a code solution's
        covariance bounded below by the snapshot's (time-correlated code errors do not
        average out)."""
        sol = res.solution
        snap = self.snapshot
        diag = res.diagnostics + rows if rows else res.diagnostics
        nan = float("nan")
        if sol.status in ("fixed", "partial") and update is not None:
            pol = self.integrity.policy
            why = fixed_position_agrees(sol.pos_m, sol.cov_m2, snap, pol.alpha, require=pol.enabled)
            if why:
                self.integrity.counts["fix_rejected"] += 1
                fl = update.state
                sol = solution_of(fl, sol.t_s, "float", sol.n_used, ratio=sol.ratio, n_amb=sol.n_amb)
                diag = diag + [
                    DiagRow(sol.t_s, "integrity:fix_rejected", "integrity", nan, nan, nan, nan, nan, 0)
                ]
                res = replaced(res, events=res.events + (why,))
        # a code solution, or a float one (integers not validated: its position rests on
        # averaged code, algorithms.md §38), is no better than the epoch's snapshot
        if sol.status in ("code", "float") and snap is not None and self.integrity.policy.floor_covariance:
            sol = replaced(sol, cov_m2=covariance_floor(sol.cov_m2, snap.cov_m2))
        if sol.status in ("fixed", "partial", "float") and self.frame == "ecef":
            sol = with_unmodelled_errors(sol, np.asarray(self.base.position(sol.t_s), float))
        if sol is res.solution and diag is res.diagnostics:
            return res
        return replaced(res, solution=sol, diagnostics=diag)

    # ------------------------------------------------------------------ code (DPL / DGNSS)
    def _step_code(
        self,
        state: GaussianState,
        t: float,
        dd: DDSet,
        code_model: Callable[[DDSet], DDRangeModel],
        vel: VelocityModel | None = None,
        disp: Displacement | None = None,
    ) -> EpochResult:
        prev = self.state
        if dd.m < 3:
            self.state = state
            self.record(prev, state, state, restarted=False)
            return EpochResult(solution_of(state, t, "none", 0))
        model = code_model(dd)
        events: list[str] = []
        if self.bad_epochs.due:
            restarted = self.restart(state, model)
            if restarted is not None:
                state = restarted
                events.append("reinit")
        F_carry = None
        if not events and prev is not None and self.reinits[-1:] != [t]:
            # a moving receiver carried by its TDCP displacement or Doppler velocities, not by
            # the dynamics; a standing one is left to them (the stationary model averages, §44/45)
            jerk = self.cfg.measurement.dgnss_doppler_jerk_m_s3
            state, vel, F_carry = carried_prediction(prev, state, disp, vel, jerk)
        rows: DDRangeModel | StackedModel = model if vel is None else StackedModel((model, vel))
        kinds = ["code"] * dd.m + ["doppler"] * (len(rows.labels) - dd.m)
        if self.imm is not None:
            res, adapt = self.imm.update(self.filter, state, rows, self.robust, self.adaptive)
        else:
            res, adapt = adaptive_update(self.filter, state, rows, self.robust, self.adaptive)
        self.count_bad(res, len(rows.labels), bool(events))
        self.state = res.state
        if res.prior_scale is not None:
            state = state.with_(P=apply_prior_scale(state.P, res.prior_scale))
        self.record(prev, state, res.state, restarted=bool(events) or self.reinits[-1:] == [t], F=F_carry)
        diag = diag_rows(t, rows.labels, kinds, res)
        if len(diag) > dd.m:  # the velocity rows: no DD situation (as other non-DD rows)
            diag[dd.m :] = [r._replace(dv=float("nan"), situation=0) for r in diag[dd.m :]]
        if adapt is not None:
            diag.append(adaptive_row(t, adapt))
        if self.imm is not None:
            diag += imm_rows(t, self.imm.spec.names, self.imm.probabilities)
        if events:
            self.reinits.append(t)
            diag.append(event_row(t, "reinit"))
        return EpochResult(solution_of(res.state, t, "code", res.n_used), diag, tuple(events))

    def record(
        self,
        prev: GaussianState | None,
        prior: GaussianState,
        post: GaussianState,
        restarted: bool,
        F: FloatArray | None = None,
    ) -> None:
        """Keep the epoch's prior, posterior and transition for the RTS smoother (when on);
        ``F`` the transition when it is not the last model's (the Doppler carry)."""
        if self.steps is None:
            return
        if F is None and prev is not None and not restarted and self.last_model is not None:
            F = self.last_model.transition(prev.layout, prior.t_s - prev.t_s)[0]
        from robustrtk.estimation.smoother import FilterStep

        self.steps.append(FilterStep(F, prior.x, prior.P, post.x, post.P, post.layout))
        snap, floor = self.snapshot, self.integrity.policy.floor_covariance
        self.floors.append(snap.cov_m2 if snap is not None and floor else None)

    def count_bad(self, res: UpdateResult, m: int, restarted: bool) -> None:
        """Count epochs in a row whose robust update rejected most rows."""
        rejected = int(np.count_nonzero(res.situation == 3))
        self.bad_epochs.update(not restarted and m >= 4 and rejected >= REINIT_REJECTED_FRACTION * m)

    def restart(self, state: GaussianState, model: DDRangeModel) -> GaussianState | None:
        """The state re-initialised on the single-epoch least-squares position
        (:func:`~robustrtk.pipeline.engine_setup.restart_state`); the ambiguity book forgets."""
        new = restart_state(state, model, self.cfg)
        if new is not None:
            self.book.forget(list(self.book))
        return new


__all__ = [
    "DDEngine", "DiagRow", "EpochInputs", "EpochResult", "RunResult", "align_epochs", "has_dd",
    "initial_state", "least_squares_fix", "make_adaptive", "make_filter", "make_process", "reindex",
    "rereference", "row_groups_of", "row_map", "take_rows",
]  # fmt: skip
