"""Kalman-filter SPP on code, Doppler and carrier phase, on one or two bands, with RTS smoothing.

The signals and satellite states are in :mod:`robustrtk.pipeline.spp_signals`, the process
model in :mod:`robustrtk.pipeline.spp_dynamics`, the observation rows in
:mod:`robustrtk.pipeline.spp_rows`; this module is the filter loop and its smoothing.

State (ECEF, metres; ``n_s`` systems, ``n_b`` systems with a second band)::

    x = [pos(3), vel(3), clk(n_s), drift(1), pclk(n_s), ifb(n_b), N_1 .. N_m]

``clk_s`` is the receiver clock seen by the code of system ``s``; ``pclk_s`` the clock seen
by its carrier phase (a separate state because phones re-estimate the clock bias they apply
to pseudoranges every epoch while the accumulated carrier phase runs on the hardware clock,
so the two differ by tens of metres epoch to epoch); both follow one clock drift ``d``
(m/s). ``ifb_s`` is the receiver's code bias of the second band (L5/E5a, else L2/E5b/B3)
relative to the first; ``N_j`` (m) is the float carrier-phase bias of one continuous arc of
one satellite and band (phase hardware delays, the initial integer and the code–carrier
ionospheric divergence, hence a small random walk).

Observation rows of satellite ``i`` on band ``b`` (frequency ``f_b``, wavelength
``lambda_b``)::

    code    P + c (dt_i − T_GD,b) − I_b − T        = rho_i + clk_s + [b = 2] ifb_s
    phase   lambda_b phi + c dt_i + I_b − T        = rho_i + pclk_s + N_(i,b,arc)
    Doppler −lambda_b D + c ddt_i                   = u_i · (v_i − v) − Sagnac rate + d

with ``rho_i`` the range with the Sagnac term, ``I_b`` Klobuchar scaled by ``(f_1/f_b)^2``
and ``T`` Saastamoinen (:func:`robustrtk.measurement.undifferenced.atmosphere`). Variances
``sigma^2 / sin^2(el)``, times the C/N0 factor when ``kalman_use_cn0``
(:func:`robustrtk.measurement.undifferenced.elevation_cn0_variance`); Doppler rows with
``doppler_weighting = "cn0"`` follow the tracking-loop law ``sigma_ref^2 10^((cn0_ref − cn0)/10)``
(:func:`robustrtk.measurement.undifferenced.cn0_variance`, docs/algorithms.md §19), their σ
multiplied by the running robust scale of the filter's own Doppler residuals
(:class:`RunningScale`, §41). With
``zupt``, an epoch whose Doppler rows alone give a speed below ``zupt_speed_m_s``
(:func:`doppler_standing`) also gets three zero-velocity rows.

Dynamics (:class:`SppProcessModel`): white acceleration, with separate horizontal and
vertical spectral densities (a road vehicle accelerates far less vertically); clocks driven
by the common drift plus their own white noise; ``ifb`` and ``N`` random walks. A
carrier-phase arc ends (its ``N`` is dropped and a new one starts from the phase minus the
predicted range) when the phase was absent at the previous epoch, when the robust update
rejected it at the previous epoch, or — with ``lli_reset`` — when the loss-of-lock bit is
set; without ``lli_reset`` a loss-of-lock flag only adds ``slip_var_m2`` to ``N`` (phones
set it far more often than the phase actually slips). These layout changes, and the
restart of a clock that jumped, are a :class:`Relayout` around the process model; the
time update is :func:`predict_relayout`. All rows go through one update of the filter
named by ``cfg.estimator.filter`` with the robust policy ``cfg.robust``
(:func:`robustrtk.estimation.registry.make_robust_policy`).

The forward filter records its transitions, so a Rauch–Tung–Striebel pass
(:mod:`robustrtk.estimation.smoother`) can smooth the whole track when
``cfg.estimator.smoother``.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from robustrtk.core import FloatArray, ObsBatch, median_of, vector_norm
from robustrtk.estimation.adaptive import adaptive_update, make_adaptive_factor
from robustrtk.estimation.integrity import (
    IntegrityEvent,
    IntegrityMonitor,
    IntegrityPolicy,
    Snapshot,
    covariance_floor,
    widen,
)
from robustrtk.estimation.models import LinearMeasurement
from robustrtk.estimation.registry import make_robust_policy
from robustrtk.estimation.smoother import FilterStep
from robustrtk.estimation.state import GaussianState, StateLayout
from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.io.rinex_nav import NavData
from robustrtk.measurement.undifferenced import lsq_fde
from robustrtk.pipeline.config import Config, preset
from robustrtk.pipeline.loop import EpochLoop
from robustrtk.pipeline.reinit import Streak, gap_exceeded, smooth_steps
from robustrtk.pipeline.results import notify_progress
from robustrtk.pipeline.spp_codebias import CodeErrorStates
from robustrtk.pipeline.spp_common import (
    SppEpoch,
    lsq_settings,
    nav_and_source,
    reported,
    unsolved_epoch,
)
from robustrtk.pipeline.spp_dynamics import (
    Relayout,
    SppProcessModel,
    TransitionModel,
    kalman_filter,
    predict_relayout,
    spp_layout,
)
from robustrtk.pipeline.spp_rows import KalmanSppRun, design_rows, doppler_standing
from robustrtk.pipeline.spp_signals import (
    BAND2_PREFERENCE,
    SatStates,
    SatStatesTable,
    Signals,
    lsq_geometry,
    spp_signals,
)


def solve_spp_kalman(
    batch: ObsBatch,
    nav: NavData | EphemerisSource,
    cfg: Config | None = None,
    progress: Callable[[int, int], None] | None = None,
    systems: str | None = None,
    integrity: IntegrityPolicy | None = None,
    events: list[tuple[float, IntegrityEvent]] | None = None,
) -> list[SppEpoch]:
    """Robust Kalman-filter SPP on code, Doppler and carrier phase (one or two bands).

    State: position, velocity, a code clock and a carrier-phase clock per system sharing
    one drift, an inter-frequency code bias per system with a second band, and one float
    bias per carrier-phase arc (model in the module docstring). Initialised from the first
    least-squares (FDE) solution; each epoch: predict (:class:`SppProcessModel` inside a
    :class:`Relayout` for the arcs), restart a clock whose per-system median innovation
    exceeds ``clock_reset_m``, then one robust update (``cfg.robust``) of every row of the
    satellites above the mask at the predicted position. The filter is re-initialised from
    the FDE solution when the two disagree by more than ``reinit_m`` for
    ``cfg.estimator.reinit_epochs`` consecutive epochs (0 = never). With
    ``cfg.estimator.smoother`` the forward estimates are replaced by Rauch–Tung–Striebel
    smoothed ones.

    Integrity (:mod:`robustrtk.estimation.integrity`, algorithms.md §30): each epoch the
    predicted position is tested against the epoch's least-squares (FDE) solution; an
    inconsistent prediction is widened, and re-initialised from that solution when the
    test fails ``integrity.patience`` epochs in a row or after a gap longer than
    ``integrity.max_gap_s``. An epoch is solved only when at least four rows that carry
    position information were used (code, or the phase of an arc that continues: a new
    arc's bias absorbs its phase); its reported covariance is bounded below by the
    least-squares one (time-correlated code errors do not average out).

    Parameters
    ----------
    batch : ObsBatch
        Observations with any signals: per system the first band-1 column with code and
        (``cfg.spp.dual_frequency``) a second-band column are used; a batch reduced by
        :func:`robustrtk.pipeline.spp_common.select_band1` gives band 1 only.
    nav : NavData or EphemerisSource
    cfg : Config, optional
        Default ``preset("spp").updated(filter="ekf")``; ``cfg.estimator.filter`` must be
        ``ekf`` or ``ukf``.
    progress : callable (done, total), optional
    systems : str, optional
        System letters to use (all with ephemerides when None).
    integrity : IntegrityPolicy, optional
        The monitor's policy (default :class:`IntegrityPolicy`).
    events : list, optional
        Receives ``(t_s, IntegrityEvent)`` of every widening and re-initialisation.

    Returns
    -------
    list of SppEpoch, one per epoch: status ``"single"`` when at least four code or phase
    position rows were used, ``"none"`` otherwise (before the first fix: NaN position); ``n_used``
    counts code rows; ``excluded`` lists rows the policy rejected (``"G05:P1"`` code,
    ``"G05:L5"`` phase, ``"G05:D1"`` Doppler, ``"ZUPT:vx"`` a zero-velocity row).
    """
    cfg = cfg or preset("spp").updated(filter="ekf")
    stage = KalmanSppStage(batch, nav, cfg, systems, integrity, events)
    loop = EpochLoop(stage)
    T = len(batch)
    out: list[SppEpoch] = []
    for i in range(T):
        out.append(loop.step(i))
        notify_progress(progress, i + 1, T, out[-1].status)
    if cfg.estimator.smoother:
        out = _smoothed(out, stage.steps, stage.run, stage.floors)
    return reported(out)


class RunningScale:
    """Causal robust scale of one kind of row: ``1.4826 · median |u|`` over the last
    ``window`` standardised post-fit residuals ``u`` (standardised by the configured σ and
    the update's redundancy, ``Cvv = R − H P⁺ Hᵀ``), 1 until ``min_rows`` were seen
    (docs/algorithms.md §41).

    Parameters
    ----------
    window : int
        Residuals kept (rows; a phone's 8–10 Doppler rows per epoch: about 30–40 s).
    min_rows : int
        Residuals needed before the scale departs from 1.
    """

    def __init__(self, window: int = 300, min_rows: int = 50) -> None:
        self.u: deque[float] = deque(maxlen=window)
        self.min_rows = min_rows
        self.value = 1.0

    def add(self, u: FloatArray) -> None:
        """Append the standardised residuals ``u`` (dimensionless, shape (m,)) of one
        epoch and update :attr:`value` (the factor on σ the next epoch's rows get)."""
        self.u.extend(np.abs(np.asarray(u, float)).tolist())
        if len(self.u) >= self.min_rows:
            self.value = 1.4826 * median_of(np.fromiter(self.u, float))


class KalmanSppFilter:
    """The Kalman SPP of one epoch after another (module notes): :meth:`solve_epoch` takes
    an epoch's signals and satellite states and returns its solution, the filter's state
    carried from epoch to epoch. A file's run (:class:`KalmanSppStage`) and a stream's
    (:mod:`robustrtk.pipeline.spp_kalman_stream`) are its clients.

    Parameters
    ----------
    run : KalmanSppRun
        The state's layout and the arcs' bookkeeping.
    cfg : Config
    integrity, events
        As :func:`solve_spp_kalman`.
    record : bool
        Keep each epoch's filter step and covariance floor (``steps``, ``floors``: the
        smoother's input; a stream keeps none).
    """

    def __init__(
        self,
        run: KalmanSppRun,
        cfg: Config,
        integrity: IntegrityPolicy | None = None,
        events: list[tuple[float, IntegrityEvent]] | None = None,
        record: bool = True,
    ) -> None:
        self.cfg = cfg
        self.run = run
        self.kf = kalman_filter(cfg)
        rb = cfg.robust
        self.policy = make_robust_policy(
            rb.policy, k0=rb.k0, k1=rb.k1, prefit_k0=rb.prefit_k0, prefit_k1=rb.prefit_k1
        )
        est = cfg.estimator
        self.adaptive = make_adaptive_factor(
            est.adaptive, est.adaptive_c0, est.adaptive_c1, est.adaptive_max_iter
        )
        self.settings = lsq_settings(cfg)
        self.dynamics = SppProcessModel.of(cfg)
        self.reinit_m = cfg.spp.reinit_m
        self.record = record
        self.steps: list[FilterStep | None] = []
        self.state: GaussianState | None = None
        # epochs in a row in which the filter and the least-squares solution disagree
        self.disagree = Streak(cfg.estimator.reinit_epochs)
        self.monitor = IntegrityMonitor(integrity or IntegrityPolicy())
        self.events = events
        self.floors: list[FloatArray | None] = []
        # the Doppler rows' σ scale, measured on their own residuals (algorithms.md §41)
        self.scales = {"D": RunningScale()}
        # Gauss–Markov code-error states (algorithms.md §43), set up at the first fix
        self.code_states: CodeErrorStates | None = None
        self._code_states_due = cfg.spp.code_bias or cfg.spp.code_elevation_delay

    def restart(self) -> None:
        """No filter any more: the next epoch starts one from its least squares."""
        self.state = None
        self.disagree.reset()

    def code_error_states(self, sig: Signals, pos_m: FloatArray) -> CodeErrorStates | None:
        """The code-error states set up at the first fix from ``pos_m`` (ECEF m); a client
        that knows the whole record gives them their σ and τ from its data."""
        return None

    def solve_epoch(self, t: float, sig: Signals, i: int, seq: int, sats: SatStates) -> SppEpoch:
        """Epoch ``i`` of ``sig`` at ``t`` (GPST s), the run's epoch number ``seq``, with
        its satellite states: predict and update the filter (or start it), module notes."""
        cfg, run, monitor, state = self.cfg, self.run, self.monitor, self.state
        nf = run.fixed.n_fixed
        max_gap_s = monitor.policy.max_gap_s
        x0 = None if state is None or gap_exceeded(t, state.t_s, max_gap_s) else state.x[:3]
        lsq, _, _ = lsq_fde(t, lsq_geometry(sig, i, sats), run.nav, self.settings, x0)
        snap = (
            None if lsq is None else Snapshot(np.asarray(lsq.pos, float), np.asarray(lsq.cov, float)[:3, :3])
        )
        floor = snap.cov_m2 if snap is not None and monitor.policy.floor_covariance else None
        if self.record:
            self.floors.append(floor)
        if self.state is not None and lsq is not None:
            self.disagree.update(vector_norm(lsq.pos - self.state.x[:3]) > self.reinit_m)
            if self.disagree.due:
                self.restart()
        scale = 1.0
        if self.state is not None and snap is None and gap_exceeded(t, self.state.t_s, max_gap_s):
            self.restart()  # no prediction across the gap, no snapshot to restart from
        if self.state is not None and snap is not None and monitor.policy.enabled:
            ev = _integrity_test(self.state, snap, t, self.dynamics, run.fixed, monitor)
            if ev.kind != "ok" and self.events is not None:
                self.events.append((t, ev))
            if ev.kind == "reinit":
                self.restart()
            scale = ev.scale
        state = self.state
        first = state is None
        if state is None:
            if lsq is None:
                if self.record:
                    self.steps.append(None)
                return unsolved_epoch(t)
            state = run.initial_state(t, lsq.pos, lsq.cov[:3, :3], lsq.clk)
            run.last_seen.clear()
            run.restart.clear()
            if self._code_states_due:
                self._code_states_due = False
                self.code_states = self.code_error_states(sig, np.asarray(lsq.pos, float))
        model = self.dynamics.at(state.x[:3])
        F_fixed, _ = model.transition(run.fixed, t - state.t_s)
        x_lin = F_fixed @ state.x[:nf]
        rows, new_amb, suspect = run.build_rows(sig, i, seq, t, sats, x_lin, nf)
        if cfg.spp.zupt:
            run.zupt_rows(rows, x_lin, nf)
        cs = self.code_states
        ext = None
        if cs is not None:
            H_pos = [h[:3] for h in rows.H]
            ext = cs.prepare(rows.kind, rows.labels, H_pos, rows.var, x_lin[:3], state.layout.amb_keys)
        in_rows = set(rows.amb) | (set() if ext is None else ext.present)
        kept = tuple(k for k in state.layout.amb_keys if k in in_rows)
        new_ext = [] if ext is None else ext.new
        change = Relayout(
            model if cs is None else cs.process(model),
            replace(run.fixed, amb_keys=kept + tuple(new_amb) + tuple(new_ext)),
            start={**new_amb, **dict.fromkeys(new_ext, 0.0)},
            start_var=cfg.spp.amb_var0_m2,
            extra_var={k: cfg.spp.slip_var_m2 for k in suspect},
            start_var_of={} if ext is None else ext.start_var,
        )
        prior, F = predict_relayout(state, change, t)
        if scale > 1.0:
            prior = widen(prior, scale)
        m = len(rows.d)
        if m:
            H, d = design_rows(rows, prior.layout, prior.x, x_lin)
            if ext is not None:
                ext.columns(H, d, prior.layout, prior.x)
            resets = run.clock_restarts(rows, d, prior.x, new_amb)
            if resets:
                change = replace(change, restart=resets)
                prior, F = predict_relayout(state, change, t)
                prior = widen(prior, scale) if scale > 1.0 else prior
                H, d = design_rows(rows, prior.layout, prior.x, x_lin)
                if ext is not None:
                    ext.columns(H, d, prior.layout, prior.x)
            kinds = np.array(rows.kind)
            cont = np.array([a is None or a not in new_amb for a in rows.amb], bool)
            s_row = np.ones(m)
            for k, sc in self.scales.items():
                s_row[kinds == k] = sc.value
            var = np.asarray(rows.var) * s_row**2
            meas = LinearMeasurement(H=H, z=d + H @ prior.x, R=np.diag(var), labels=tuple(rows.labels))
            res, adapt = adaptive_update(self.kf, prior, meas, self.policy, self.adaptive)
            # residuals standardised by the configured σ (the scale in use taken out)
            u_cfg = res.std_residual * s_row
            for k, sc in self.scales.items():
                sc.add(u_cfg[(kinds == k) & np.isfinite(res.factors) & np.isfinite(u_cfg)])
            alpha = 1.0 if adapt is None else adapt.alpha_min
            post = res.state
            used = np.isfinite(res.factors)
            rejected = tuple(lab for lab, ok in zip(rows.labels, used, strict=True) if not ok)
            for r, key in enumerate(rows.amb):
                if key is not None and not used[r]:
                    run.restart.add((key[0], key[1]))
            n_code = int(np.sum(used & (kinds == "P")))
            # a new arc's bias absorbs its phase: that row tells nothing of the position
            n_pos = int(np.sum(used & cont & (kinds != "D") & (kinds != "Z")))
        else:
            post, rejected, n_code, n_pos, alpha = prior, (), 0, 0, 1.0
        if self.record:
            self.steps.append(FilterStep(None if first else F, prior.x, prior.P, post.x, post.P))
        self.state = post
        return _epoch(post.x, post.P, run, t, n_code, rejected, n_pos >= 4, alpha, floor)


class KalmanSppStage(KalmanSppFilter):
    """The per-epoch work of :func:`solve_spp_kalman` on a whole batch (a
    :class:`~robustrtk.pipeline.loop.Stage`): the signals chosen over the file, the
    satellite states computed a block of epochs at a time; ``step(i)`` solves epoch ``i``,
    keeping the filter's forward records (``steps``, ``floors``) for the smoother.

    Parameters as :func:`solve_spp_kalman` (``cfg`` given).
    """

    def __init__(
        self,
        batch: ObsBatch,
        nav: NavData | EphemerisSource,
        cfg: Config,
        systems: str | None = None,
        integrity: IntegrityPolicy | None = None,
        events: list[tuple[float, IntegrityEvent]] | None = None,
    ) -> None:
        self.batch = batch
        _, self.eph = nav_and_source(nav)
        self.sig = spp_signals(batch, self.eph.nav, cfg.spp.dual_frequency, systems)
        super().__init__(KalmanSppRun.of(self.sig, self.eph, cfg), cfg, integrity, events)
        self.sats = SatStatesTable(self.sig, batch.t_s, self.eph)

    def code_error_states(self, sig: Signals, pos_m: FloatArray) -> CodeErrorStates | None:
        """The code-error states, their σ and τ from the whole file when not configured."""
        return CodeErrorStates.of(self.cfg, self.batch, sig, self.eph, pos_m)

    def step(self, i: int) -> SppEpoch:
        """Epoch ``i`` of the batch (:meth:`KalmanSppFilter.solve_epoch`)."""
        return self.solve_epoch(float(self.batch.t_s[i]), self.sig, i, i, self.sats.of(i))


def _integrity_test(
    state: GaussianState,
    snap: Snapshot,
    t: float,
    dynamics: SppProcessModel,
    fixed: StateLayout,
    monitor: IntegrityMonitor,
) -> IntegrityEvent:
    """The monitor's test of the position predicted from ``state`` to ``t`` (the fixed
    part's time update: the arc biases do not enter the position) against the snapshot; a
    gap beyond ``max_gap_s`` is a re-initialisation without test."""
    if gap_exceeded(t, state.t_s, monitor.policy.max_gap_s):
        monitor.reinit_now()
        return IntegrityEvent("reinit", float("nan"))
    nf = fixed.n_fixed
    F, Q = dynamics.at(state.x[:3]).transition(fixed, t - state.t_s)
    x = F @ state.x[:nf]
    P = F @ state.P[:nf, :nf] @ F.T + Q
    pred = GaussianState(x=x, P=0.5 * (P + P.T), t_s=t, layout=fixed)
    widened, ev = monitor.check(pred, snap)
    return ev if ev is not None else IntegrityEvent("ok", float("nan"))


def _epoch(
    x: FloatArray,
    P: FloatArray,
    run: KalmanSppRun,
    t: float,
    n_used: int,
    rejected: tuple[str, ...],
    ok: bool,
    alpha: float = 1.0,
    floor: FloatArray | None = None,
) -> SppEpoch:
    clk_at = run.clk_indices()
    clk = {s: float(x[clk_at[s]]) for s in run.systems}
    cov = P[0:3, 0:3].copy() if floor is None else covariance_floor(P[0:3, 0:3], floor)
    return SppEpoch(
        t,
        x[0:3].copy(),
        clk,
        cov,
        n_used,
        "single" if ok else "none",
        rejected,
        ok,
        x[3:6].copy(),
        alpha,
    )


def _smoothed(
    out: list[SppEpoch],
    steps: list[FilterStep | None],
    run: KalmanSppRun,
    floors: list[FloatArray | None] | None = None,
) -> list[SppEpoch]:
    """Replace positions, velocities, clocks and covariances by their RTS estimates, one
    segment (a run of epochs the filter carried across) at a time."""
    res = list(out)
    for k, xp in enumerate(smooth_steps(steps)):
        if xp is None:
            continue
        e = out[k]
        fl = None if floors is None else floors[k]
        res[k] = _epoch(xp[0], xp[1], run, e.t_s, e.n_used, e.excluded, e.chi2_ok, e.adaptive_alpha, fl)
    return res


__all__ = [
    "BAND2_PREFERENCE",
    "KalmanSppFilter",
    "KalmanSppStage",
    "Relayout",
    "RunningScale",
    "Signals",
    "SppProcessModel",
    "doppler_standing",
    "TransitionModel",
    "spp_signals",
    "kalman_filter",
    "predict_relayout",
    "solve_spp_kalman",
    "spp_layout",
]
