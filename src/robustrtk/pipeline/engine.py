"""The per-epoch loop for double-differenced positioning (DPL, DGNSS and RTK).

:class:`DDEngine` owns the loop and nothing else: per epoch it predicts the state, picks
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
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import replace
from functools import lru_cache
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np

from robustrtk.ambiguity.book import AmbiguityBook
from robustrtk.ambiguity.lambda_ import backend as lambda_backend
from robustrtk.core import (
    BoolArray,
    FloatArray,
    InputError,
    IntArray,
    ObsBatch,
    ObsEpoch,
    Solution,
    TransmitterSource,
)
from robustrtk.estimation.adaptive import (
    AdaptiveFactor,
    MotionSelector,
    StationaryModel,
    adaptive_update,
    make_adaptive_factor,
)
from robustrtk.estimation.filters import Filter
from robustrtk.estimation.imm import ImmTracker, make_imm_models
from robustrtk.estimation.integrity import (
    IntegrityMonitor,
    IntegrityPolicy,
    Snapshot,
    covariance_floor,
    fix_agrees,
    reinitialise,
    robust_snapshot,
    unmodelled_covariance,
)
from robustrtk.estimation.models import ProcessModel
from robustrtk.estimation.prior_scale import apply_prior_scale
from robustrtk.estimation.registry import make_filter as make_filter_named
from robustrtk.estimation.registry import make_process_model, make_robust_policy
from robustrtk.estimation.robust import RobustPolicy
from robustrtk.estimation.state import GaussianState, StateLayout, UpdateResult
from robustrtk.geometry.frames import ecef2enu_rotation, ecef2geodetic
from robustrtk.geometry.los import azimuth_elevation_rot, elevation_rot
from robustrtk.geometry.receivers import PositionSource, as_position_source
from robustrtk.measurement.base_propagation import with_age
from robustrtk.measurement.corrections import tropo_saastamoinen
from robustrtk.measurement.dd import (
    DDRangeModel,
    DDSet,
    choose_references,
    dd_range_model,
    dd_rows,
    form_dd,
    ranges,
)
from robustrtk.measurement.weighting import elevation_sin2, local_elevation, variance
from robustrtk.pipeline.base_buffer import (
    BaseEvents,
    BasePair,
    aged_inputs,
    base_lli_events,
    pair_base_epochs,
    with_base_events,
)
from robustrtk.pipeline.config import Config
from robustrtk.pipeline.results import (
    DiagRow,
    EpochInputs,
    EpochResult,
    RowTally,
    RunResult,
    adaptive_row,
    diag_rows,
    event_row,
    notify_progress,
    solution_of,
)
from robustrtk.pipeline.rtk import DDEpoch, RtkStage
from robustrtk.pipeline.satcount import with_satellites

if TYPE_CHECKING:  # the smoother is imported where it runs (smoothing is off by default)
    from robustrtk.estimation.smoother import FilterStep

#: Faulty-reference test threshold on the reference's discriminant (satellite space).
REF_CHECK_K = 3.0
#: An epoch counts toward re-initialisation when the robust update rejected at least this
#: fraction of its rows.
REINIT_REJECTED_FRACTION = 0.5


def rereference(dd: DDSet, rows: np.ndarray, j: int) -> DDSet:
    """The DDs ``rows`` of one group re-expressed against the transmitter of row ``j``.

    Rows ``i − r`` become ``(i − r) − (j − r) = i − j`` and row ``j − r`` becomes ``r − j``:
    a linear map ``T`` (``z ← T z``, ``R ← T R Tᵀ``, ``D ← T D``) that keeps all the
    information, so a DPL update with all rows is unchanged.
    """
    m = dd.m
    T = np.eye(m)
    T[rows, j] -= 1.0
    T[j, :] = 0.0
    T[j, j] = -1.0
    tx, ref = list(dd.tx), list(dd.ref)
    i_tx, i_ref = dd.i_tx.copy(), dd.i_ref.copy()
    new, old, i_new, i_old = dd.tx[j], dd.ref[j], int(dd.i_tx[j]), int(dd.i_ref[j])
    for k in rows:
        ref[k], i_ref[k] = new, i_new
    tx[j], i_tx[j] = old, i_old
    R = T @ dd.R @ T.T
    return replace(
        dd, labels=tuple(f"{a}-{b}" for a, b in zip(tx, ref, strict=True)), tx=tuple(tx),
        ref=tuple(ref), i_tx=i_tx, i_ref=i_ref, D=T @ dd.D, z=T @ dd.z, R=0.5 * (R + R.T),
    )  # fmt: skip


def make_filter(cfg: Config) -> Filter:
    """EKF or UKF from the configuration."""
    est = cfg.estimator
    if est.filter == "ekf":
        return make_filter_named("ekf")
    if est.filter == "ukf":
        return make_filter_named("ukf", alpha=est.ukf_alpha, beta=est.ukf_beta, kappa=est.ukf_kappa)
    raise InputError(f"filter: {est.filter!r} is not a Kalman filter; the DD engine takes ukf or ekf")


def make_process(cfg: Config) -> ProcessModel:
    """Dynamics from the configuration (ambiguities: constant)."""
    est = cfg.estimator
    if est.dynamics == "static":
        return make_process_model("static", q_m2_s=est.q_static_m2_s)
    cv = est.kinematic_model == "constant-velocity" or (est.kinematic_model == "auto" and cfg.mode == "rtk")
    cv |= est.dynamics == "auto"  # the moving hypothesis needs a velocity
    if cv:
        return make_process_model("constant-velocity", sigma_m_s2=est.sigma_acc_m_s2)
    return make_process_model("random-walk", sigma_m_s=est.sigma_vel_m_s)


def make_adaptive(cfg: Config) -> AdaptiveFactor | None:
    """The adaptive factor of the configuration (None when off)."""
    est = cfg.estimator
    return make_adaptive_factor(est.adaptive, est.adaptive_c0, est.adaptive_c1, est.adaptive_max_iter)


def initial_state(cfg: Config, pos0_m: FloatArray, t_s: float, process: ProcessModel) -> GaussianState:
    """Known-point initialization: position at ``pos0_m`` with ``init_sigma_m``.

    With ``known_point = False`` the position is only an approximation (σ ≥ 1 m) and RTK
    converges from DD code (see :mod:`robustrtk.pipeline.rtk`)."""
    est = cfg.estimator
    layout = StateLayout(blocks=process.blocks())
    n = layout.size
    x = np.zeros(n)
    P = np.zeros((n, n))
    p = layout.slice("pos")
    x[p] = pos0_m
    # without known-point initialization the initial position is only approximate
    sigma0 = est.init_sigma_m if est.known_point else max(est.init_sigma_m, 1.0)
    P[p, p] = np.eye(3) * sigma0**2
    if layout.has("vel"):
        v = layout.slice("vel")
        P[v, v] = np.eye(3) * est.init_sigma_vel_m_s**2
    return GaussianState(x=x, P=P, t_s=t_s, layout=layout)


def align_epochs(rover: ObsBatch, base: ObsBatch, tol_s: float = 0.005) -> Iterator[tuple[int, int]]:
    """Pairs ``(i_rover, i_base)`` of epochs whose times agree within ``tol_s``."""
    tb = base.t_s
    if tb.size == 0:
        return
    j = np.searchsorted(tb, rover.t_s)
    for i, jj in enumerate(j):
        best = None
        for c in (jj - 1, jj):
            if 0 <= c < tb.size and abs(tb[c] - rover.t_s[i]) <= tol_s:
                if best is None or abs(tb[c] - rover.t_s[i]) < abs(tb[best] - rover.t_s[i]):
                    best = c
        if best is not None:
            yield i, int(best)


@lru_cache(maxsize=16)
def row_map(
    src_ids: tuple[str, ...], dst_ids: tuple[str, ...]
) -> tuple[tuple[int, ...], BoolArray, IntArray]:
    """Where the rows ``dst_ids`` are in ``src_ids`` (the first row of each name).

    Returns
    -------
    idx : tuple of int, length len(dst_ids)
        Source row of each destination row, −1 when absent.
    have : ndarray of bool, shape (len(dst_ids),)
        ``idx >= 0``.
    src_rows : ndarray of int, shape (have.sum(),)
        ``idx[have]``.

    Remembered for the last few pairs (a batch's epochs share their transmitter tuples).
    """
    first: dict[str, int] = {}
    for i, t in enumerate(src_ids):
        first.setdefault(t, i)
    idx = tuple(first.get(t, -1) for t in dst_ids)
    idx_a = np.array(idx, dtype=np.int64)
    have = idx_a >= 0
    src_rows = idx_a[have]
    have.flags.writeable = False
    src_rows.flags.writeable = False
    return idx, have, src_rows


@lru_cache(maxsize=16)
def row_groups_of(system: tuple[str, ...], tx_ids: tuple[str, ...]) -> tuple[str, ...]:
    """DD group ``"<system>:<slot>"`` of each signal row ``"<tx>:<slot>"`` (remembered for
    the last few row tuples: a batch's epochs share theirs)."""
    return tuple(f"{s}:{t.split(':', 1)[1]}" for s, t in zip(system, tx_ids, strict=True))


def take_rows(a: np.ndarray, have: BoolArray, src_rows: IntArray, fill: float) -> np.ndarray:
    """``a``'s rows ``src_rows`` placed at the rows ``have`` of a new array, ``fill`` elsewhere
    (see :func:`row_map`)."""
    out = np.full((have.shape[0],) + a.shape[1:], fill, dtype=a.dtype)
    out[have] = a[src_rows]
    return out


def reindex(epoch: ObsEpoch, tx_ids: tuple[str, ...]) -> ObsEpoch:
    """The epoch's rows reordered to ``tx_ids`` (NaN rows for transmitters it lacks)."""
    if epoch.tx_ids == tx_ids:
        return epoch
    idx, have, rows = row_map(tuple(epoch.tx_ids), tuple(tx_ids))

    def take(a: np.ndarray | None, fill: float) -> np.ndarray | None:
        return None if a is None else take_rows(a, have, rows, fill)

    system = epoch.system
    kw: dict[str, Any] = dict(
        tx_ids=tx_ids,
        system=tuple(system[i] if i >= 0 else "P" for i in idx),
        code_m=take(epoch.code_m, np.nan),
        phase_cyc=take(epoch.phase_cyc, np.nan),
        doppler_hz=take(epoch.doppler_hz, np.nan),
        cn0_dbhz=take(epoch.cn0_dbhz, np.nan),
        lli=take(epoch.lli, 0),
        wavelength_m=take(epoch.wavelength_m, np.nan),
        code_sigma_m=take(epoch.code_sigma_m, np.nan),
        phase_sigma_cyc=take(epoch.phase_sigma_cyc, np.nan),
    )
    if type(epoch) is ObsEpoch:  # the constructor directly: replace() costs more than the copies
        return ObsEpoch(t_s=epoch.t_s, signals=epoch.signals, **kw)
    return replace(epoch, **kw)


def innovations(model: DDRangeModel, state: GaussianState) -> tuple[FloatArray, FloatArray]:
    """Innovations ``d = z − h(x̄)`` and their covariance ``S = H P̄ Hᵀ + R`` (linearised)."""
    H = model.jacobian(state.x)
    return model.z - model.h(state.x), H @ state.P @ H.T + model.R


def least_squares_fix(
    model: DDRangeModel, state: GaussianState, iterations: int = 6
) -> tuple[FloatArray, FloatArray] | None:
    """Single-epoch weighted least squares of the position from DD code rows.

    Gauss–Newton from the state's position: ``δx = (Hᵀ R⁻¹ H)⁻¹ Hᵀ R⁻¹ (z − h(x))`` on the
    position block, iterated. Returns the position (3,) and its covariance (3, 3), or None
    when the geometry is singular or the rows are too few.
    """
    p = model.pos_slice
    if len(model.labels) < 4:
        return None
    x = state.x.copy()
    try:
        W = np.linalg.inv(model.R)
        for _ in range(iterations):
            H = model.jacobian(x)[:, p]
            N = H.T @ W @ H
            dx = np.linalg.solve(N, H.T @ W @ (model.z - model.h(x)))
            x[p] = x[p] + dx
            if float(np.linalg.norm(dx)) < 1e-4:
                break
        H = model.jacobian(x)[:, p]
        C = np.linalg.inv(H.T @ W @ H)
    except np.linalg.LinAlgError:
        return None
    if not (np.all(np.isfinite(x[p])) and np.all(np.isfinite(C))):
        return None
    return x[p].copy(), 0.5 * (C + C.T)


_K = TypeVar("_K")
_V = TypeVar("_V")


def _remembered(memo: dict[_K, _V], key: _K, compute: Callable[[], _V], size: int = 8) -> _V:
    """``memo[key]``, computed by ``compute()`` and stored when absent; the memo is emptied
    once it holds ``size`` entries (one epoch asks for the same few geometries)."""
    hit = memo.get(key)
    if hit is None:
        if len(memo) >= size:
            memo.clear()
        hit = compute()
        memo[key] = hit
    return hit


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
        self.imm: ImmTracker | None = None
        if cfg.estimator.dynamics == "auto" and cfg.mode != "rtk" and process is None:
            self.imm = ImmTracker(make_imm_models(cfg.estimator.sigma_acc_m_s2, cfg.estimator.q_static_m2_s))
        elif cfg.estimator.dynamics == "auto":
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
        self.bad_epochs = 0
        self.reinits: list[float] = []
        # the prediction confronted with each epoch's own snapshot (algorithms.md §30)
        self.integrity = IntegrityMonitor(integrity or IntegrityPolicy())
        self.snapshot: Snapshot | None = None
        self.started = False  # an integrity test has run (the first one tests the starting guess)
        # (position, transmitters) bytes -> (azimuth, elevation): one epoch asks for the same
        # geometry several times (mask, weights, troposphere, rover and base)
        self._az_el_memo: dict[tuple[bytes, bytes], tuple[FloatArray, FloatArray]] = {}
        # the same for the elevations alone, and for their elevation-weighting divisors
        self._el_memo: dict[tuple[bytes, bytes], FloatArray] = {}
        self._sin2_memo: dict[tuple[bytes, bytes], FloatArray] = {}
        # position bytes -> (lat, lon, h, ECEF->ENU rotation), least recently used dropped
        # first: the base (a constant) is asked about every epoch, the rover a few times
        self._geo_memo: dict[bytes, tuple[FloatArray, FloatArray, FloatArray, FloatArray]] = {}
        self.last_model: ProcessModel | None = None
        # forward records for the RTS smoother (code modes with estimator.smoother)
        self.steps: list[FilterStep] | None = [] if cfg.estimator.smoother and self.rtk is None else None

    # ------------------------------------------------------------------ helpers
    def groups(self, epoch: ObsEpoch) -> list[str]:
        """DD group of each row of ``epoch``."""
        if self.row_groups:
            return list(row_groups_of(tuple(epoch.system), tuple(epoch.tx_ids)))
        sig = epoch.signals[self.signal] if epoch.signals else "L1"
        return [f"{s}:{sig}" for s in epoch.system]

    def geodetic(self, pos_m: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """:func:`~robustrtk.geometry.frames.ecef2geodetic` of an ECEF position (3,) and the
        :func:`~robustrtk.geometry.frames.ecef2enu_rotation` there, remembered for the few
        positions asked about last (the base's every epoch)."""
        p = np.asarray(pos_m, dtype=float)
        key = p.tobytes()
        memo = self._geo_memo
        hit = memo.pop(key, None)
        if hit is None:
            if len(memo) >= 8:
                del memo[next(iter(memo))]
            lat, lon, h = ecef2geodetic(p)
            hit = (lat, lon, h, ecef2enu_rotation(float(lat), float(lon)))
        memo[key] = hit  # (re)inserted last: the most recently used
        return hit

    def az_el(self, tx_pos: FloatArray, pos_m: FloatArray) -> tuple[FloatArray, FloatArray]:
        """:func:`~robustrtk.geometry.los.azimuth_elevation` (rad), remembered for the last few
        ``(pos_m, tx_pos)`` of the epoch (copies are returned)."""
        p = np.asarray(pos_m, dtype=float)
        t = np.asarray(tx_pos, dtype=float)
        hit = _remembered(
            self._az_el_memo,
            (p.tobytes(), t.tobytes()),
            lambda: azimuth_elevation_rot(t, p, self.geodetic(p)[3]),
        )
        return hit[0].copy(), hit[1].copy()

    def elevation(self, pos_m: FloatArray, tx_pos: FloatArray) -> FloatArray:
        """Elevation (rad) of each transmitter seen from ``pos_m`` in the engine's frame
        (``"ecef"``: the elevations of :meth:`az_el`, remembered the same way)."""
        if self.frame != "ecef":
            return local_elevation(pos_m, tx_pos)
        p = np.asarray(pos_m, dtype=float)
        t = np.asarray(tx_pos, dtype=float)
        hit = _remembered(
            self._el_memo, (p.tobytes(), t.tobytes()), lambda: elevation_rot(t, p, self.geodetic(p)[3])
        )
        return hit.copy()

    def elevation_sin2(self, pos_m: FloatArray, tx_pos: FloatArray) -> FloatArray:
        """:func:`~robustrtk.measurement.weighting.elevation_sin2` of :meth:`elevation`,
        remembered for the last few ``(pos_m, tx_pos)`` (code and phase share it)."""

        def divisor() -> FloatArray:
            out = elevation_sin2(self.elevation(pos_m, tx_pos))
            out.flags.writeable = False  # shared by the calls that hit the memo: read-only
            return out

        key = (np.asarray(pos_m, dtype=float).tobytes(), np.asarray(tx_pos, dtype=float).tobytes())
        return _remembered(self._sin2_memo, key, divisor)

    def variances(
        self, sigma: float, epoch: ObsEpoch, pos_m: FloatArray, tx_pos: FloatArray, kind: str = "code"
    ) -> FloatArray:
        """:meth:`weighted_variances`, plus the age variance of a base epoch carried to a
        later tag (:class:`~robustrtk.measurement.base_propagation.PropagatedEpoch`)."""
        var = self.weighted_variances(sigma, epoch, pos_m, tx_pos, kind)
        age_var = with_age(epoch)[1]
        return var + age_var if age_var > 0.0 else var

    def weighted_variances(
        self, sigma: float, epoch: ObsEpoch, pos_m: FloatArray, tx_pos: FloatArray, kind: str = "code"
    ) -> FloatArray:
        """Undifferenced variances (m²) of each row under the configured weighting.

        ``reported``: the receiver's own σ of each measurement (``kind`` ``"code"``:
        ``code_sigma_m``; ``"phase"``: ``phase_sigma_cyc · λ``), and the ``snr`` model
        where it reports none (algorithms.md § 24).
        """
        w = self.cfg.measurement.weighting
        if w == "reported":
            k = self.signal
            rep = epoch.code_sigma_m if kind == "code" else epoch.phase_sigma_cyc
            rep_k = None
            if rep is not None:
                rep_k = rep[:, k] if kind == "code" else rep[:, k] * epoch.wavelength_m[:, k]
            return variance(sigma, "reported", snr_dbhz=epoch.cn0_dbhz[:, k], reported_sigma=rep_k)
        if w == "equal":
            return variance(sigma, "equal", n=epoch.n_tx)
        if w == "elevation":
            return variance(sigma, "elevation", elev_sin2=self.elevation_sin2(pos_m, tx_pos))
        if w == "distance":
            return variance(sigma, "distance", dist_m=np.linalg.norm(tx_pos - pos_m, axis=1))
        return variance(sigma, "snr", snr_dbhz=epoch.cn0_dbhz[:, self.signal])

    def tropo(self, pos_m: FloatArray, tx_pos: FloatArray) -> FloatArray:
        """Saastamoinen slant delays (m) from ``pos_m`` to each transmitter."""
        lat, _, h, _ = self.geodetic(pos_m)
        el = self.elevation(pos_m, tx_pos)
        return np.asarray(tropo_saastamoinen(lat, h, el), float)

    # ------------------------------------------------------------------ main step
    def prefetch(self, inputs: Sequence[EpochInputs]) -> None:
        """Hand the satellite-position queries :meth:`step` will make for these epochs to the
        source's ``prefetch`` (when it has one), to be evaluated in a few vectorised calls
        instead of one or two per epoch. Results are unchanged."""
        pre = getattr(self.source, "prefetch", None)
        if pre is None:
            return
        k = self.signal
        queries: list[tuple[float, tuple[str, ...], FloatArray]] = []
        for inp in inputs:
            rover = inp.rover
            queries.append((rover.t_s, rover.tx_ids, rover.code_m[:, k]))
            if self.frame == "ecef":
                # the base's column of pseudoranges reindexed as in step (reindex's numbers)
                base = inp.base
                code_b = base.code_m[:, k]
                if base.tx_ids != rover.tx_ids:
                    _, have, rows = row_map(tuple(base.tx_ids), tuple(rover.tx_ids))
                    code_b = take_rows(code_b, have, rows, np.nan)
                queries.append((base.t_s, rover.tx_ids, code_b))
        pre(queries)

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
        if not np.all(np.isfinite(base_pos)):
            self.state = state
            return EpochResult(solution_of(state, t, "none", 0), [], ("no base position",))
        pos_prior = state.get("pos")
        k = self.signal
        code_r, code_b = rover.code_m[:, k], base.code_m[:, k]
        tx_pos, _ = self.source.positions(t, rover.tx_ids, code_r)
        if self.frame == "ecef":
            # the base's own transmission times (its tag and pseudoranges)
            tx_pos_b, _ = self.source.positions(base.t_s, rover.tx_ids, code_b)
        else:
            tx_pos_b = tx_pos
        tx_ok = np.all(np.isfinite(tx_pos), axis=1) & np.all(np.isfinite(tx_pos_b), axis=1)
        groups = self.groups(rover)
        avail = tx_ok & np.isfinite(code_r) & np.isfinite(code_b)
        if cfg.mode == "rtk":
            avail &= np.isfinite(rover.phase_cyc[:, k]) & np.isfinite(base.phase_cyc[:, k])
        snr_mask = cfg.measurement.snr_mask_dbhz
        if snr_mask > 0:
            with np.errstate(invalid="ignore"):
                low = (rover.cn0_dbhz[:, k] < snr_mask) | (base.cn0_dbhz[:, k] < snr_mask)
            avail &= ~low
        tx_pos_safe = np.where(tx_ok[:, None], tx_pos, 0.0)
        tx_pos_b_safe = np.where(tx_ok[:, None], tx_pos_b, 0.0)
        elev = self.elevation(pos_prior, tx_pos_safe)
        if self.frame == "ecef":
            avail &= elev >= self.elev_mask_rad
        preferred = {g: self.preferred_ref for g in set(groups)} if self.preferred_ref else None
        refs = choose_references(rover.tx_ids, groups, avail, elev, preferred, self.refs)
        base_range = ranges(base_pos, tx_pos_b_safe, self.sagnac)
        tx_corr = None
        if self.frame == "ecef" and cfg.measurement.tropo == "saastamoinen":
            base_range = base_range + self.tropo(base_pos, tx_pos_b_safe)
            tx_corr = self.tropo(pos_prior, tx_pos_safe)
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

        def code_model(dd: DDSet) -> DDRangeModel:
            return dd_range_model(
                dd, tx_pos_safe, base_range, pos_slice, sagnac=self.sagnac, tx_corr_m=tx_corr
            )

        check = self.rtk is None and code_dd.m >= 3 and self.frame == "ecef" and self.preferred_ref is None
        raw_dd = code_dd
        if check:
            # before the motion test: a faulty reference shifts every DD of its group
            code_dd = self.check_references(state, raw_dd, code_model(raw_dd), elev)
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
                    code_dd = self.check_references(state, raw_dd, code_model(raw_dd), elev)
        state, integ = self.check_integrity(prev, state, t, code_model(code_dd) if code_dd.m else None)
        if self.rtk is not None:
            state = self.rtk.ref_change(self.refs, refs, state)
        self.refs = refs
        if self.rtk is None:
            return self.with_integrity(self._step_code(state, t, code_dd, code_model), integ)
        sigma_ph = cfg.measurement.phase_sigma_m
        ep = DDEpoch(
            t_s=t, rover=rover, base=base, groups=groups, avail=avail, refs=refs, code_dd=code_dd,
            tx_pos_m=tx_pos_safe, base_range_m=base_range, tx_corr_m=tx_corr, elev_rad=elev,
            var_phase_r_m2=self.variances(sigma_ph, rover, pos_prior, tx_pos_safe, "phase"),
            var_phase_b_m2=self.variances(sigma_ph, base, base_pos, tx_pos_safe, "phase"),
            slip=inputs.slip, half_cycle=inputs.half_cycle, dd_rows=rows,
        )  # fmt: skip
        use_code = (cfg.measurement.rtk_use_code or not cfg.estimator.known_point) and code_dd.m > 0
        out = self.rtk.step(state, ep, code_model(code_dd) if use_code else None)
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
            snap = robust_snapshot(
                model.h, model.jacobian, model.z, model.R, state.x, model.pos_slice,
                min_redundancy=pol.min_redundancy,
            )  # fmt: skip
        self.snapshot = snap if pol.enabled else None
        self.started, first = True, not self.started
        if self.snapshot is None or snap is None:
            return state, []
        if t - prev.t_s > pol.max_gap_s:
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
            fixed = update.state.with_(x=update.state.x.copy(), P=update.state.P.copy())
            p = fixed.layout.slice("pos")
            fixed.x[p] = sol.pos_m
            fixed.P[p, p] = sol.cov_m2
            why = fix_agrees(fixed, snap, self.integrity.policy.alpha)
            if why:
                self.integrity.counts["fix_rejected"] += 1
                fl = update.state
                sol = solution_of(fl, sol.t_s, "float", sol.n_used, ratio=sol.ratio, n_amb=sol.n_amb)
                diag = diag + [
                    DiagRow(sol.t_s, "integrity:fix_rejected", "integrity", nan, nan, nan, nan, nan, 0)
                ]
                res = replace(res, events=res.events + (why,))
        elif sol.status == "code" and snap is not None and self.integrity.policy.floor_covariance:
            sol = replace(sol, cov_m2=covariance_floor(sol.cov_m2, snap.cov_m2))
        if sol.status in ("fixed", "partial", "float") and self.frame == "ecef":  # + unmodelled errors
            b = np.asarray(self.base.position(sol.t_s), float)
            c_u = unmodelled_covariance(float(np.linalg.norm(sol.pos_m - b)), sol.pos_m)
            sol = replace(sol, cov_m2=np.asarray(sol.cov_m2, float) + c_u)
        if sol is res.solution and diag is res.diagnostics:
            return res
        return replace(res, solution=sol, diagnostics=diag)

    # ------------------------------------------------------------------ code (DPL / DGNSS)
    def check_references(
        self, state: GaussianState, dd: DDSet, model: DDRangeModel, elev: FloatArray
    ) -> DDSet:
        """Re-express a group's DDs against another satellite when its reference looks faulty.

        A gross error ``e`` on the reference enters every DD of its group as ``−e``: the
        discriminant Δv̄ then sees no outlier (one system) or only a moderate one (the other
        faulty DDs inflate its denominator). Per group with at least two DDs, the prior
        innovations ``d`` are mapped to satellite values ``x = [0, d₁ … dₙ]`` (reference
        first, up to the common receiver term), centred on their median and scaled by each
        satellite's σ (from ``R``: its off-diagonal is the reference's variance),
        ``w = (x − median x)/σ``. When the reference has the largest ``|w|`` and
        ``|w_ref| / mean_{s≠ref} |w_s| > REF_CHECK_K`` the group is re-expressed, for this
        epoch only, against its highest satellite whose own ratio is at most 1
        (:func:`rereference`). The nominal DPL update does not depend on the reference, so
        only what the robust policy sees changes: the faulty reference becomes the single
        DD ``ref − new`` that the policy can single out. Satellites only (``frame="ecef"``)
        and only without a preferred reference: pseudolite runs keep their fixed reference.
        """
        d = dd.z - model.h(state.x)
        grp = np.asarray(dd.group)
        for g in dict.fromkeys(dd.group):
            rows = np.flatnonzero(grp == g)
            if rows.size < 2:
                continue
            Rg = dd.R[np.ix_(rows, rows)]
            var_ref = float(np.median(Rg[~np.eye(rows.size, dtype=bool)]))
            sig = np.sqrt(np.maximum(np.concatenate([[var_ref], np.diag(Rg) - var_ref]), 1e-12))
            x = np.concatenate([[0.0], d[rows]])
            a = np.abs(x - np.median(x)) / sig
            others = (a.sum() - a) / (a.size - 1)
            ratio = np.where(others > 0, a / np.where(others > 0, others, 1.0), np.inf)
            if not (ratio[0] > REF_CHECK_K and a[0] >= a.max()):
                continue
            ok = np.flatnonzero(ratio[1:] <= 1.0)
            if ok.size == 0:
                ok = np.array([int(np.argmin(a[1:]))])
            el = elev[dd.i_tx[rows[ok]]]
            dd = rereference(dd, rows, int(rows[ok[int(np.argmax(el))]]))
        return dd

    def _step_code(
        self, state: GaussianState, t: float, dd: DDSet, code_model: Callable[[DDSet], DDRangeModel]
    ) -> EpochResult:
        prev = self.state
        if dd.m < 3:
            self.state = state
            self.record(prev, state, state, restarted=False)
            return EpochResult(solution_of(state, t, "none", 0))
        model = code_model(dd)
        events: list[str] = []
        if self.bad_epochs >= self.cfg.estimator.reinit_epochs > 0:
            restarted = self.restart(state, model)
            if restarted is not None:
                state = restarted
                events.append("reinit")
        if self.imm is not None:
            res, adapt = self.imm.update(self.filter, state, model, self.robust, self.adaptive)
        else:
            res, adapt = adaptive_update(self.filter, state, model, self.robust, self.adaptive)
        self.count_bad(res, dd.m, bool(events))
        self.state = res.state
        if res.prior_scale is not None:
            state = state.with_(P=apply_prior_scale(state.P, res.prior_scale))
        self.record(prev, state, res.state, restarted=bool(events) or self.reinits[-1:] == [t])
        diag = diag_rows(t, dd.labels, ["code"] * dd.m, res)
        if adapt is not None:
            diag.append(adaptive_row(t, adapt))
        if self.imm is not None:  # mode probabilities in ``factor``
            nan = float("nan")
            mu = self.imm.probabilities
            diag += [
                DiagRow(t, f"imm:{n}", "imm", nan, nan, nan, nan, float(p), 0)
                for n, p in zip(self.imm.spec.names, mu, strict=True)
            ]
        if events:
            self.reinits.append(t)
            diag.append(event_row(t, "reinit"))
        return EpochResult(solution_of(res.state, t, "code", res.n_used), diag, tuple(events))

    def record(
        self, prev: GaussianState | None, prior: GaussianState, post: GaussianState, restarted: bool
    ) -> None:
        """Keep the epoch's prior, posterior and transition for the RTS smoother (when on)."""
        if self.steps is None:
            return
        F = None
        if prev is not None and not restarted and self.last_model is not None:
            F = self.last_model.transition(prev.layout, prior.t_s - prev.t_s)[0]
        from robustrtk.estimation.smoother import FilterStep

        self.steps.append(FilterStep(F, prior.x, prior.P, post.x, post.P, post.layout))

    def count_bad(self, res: UpdateResult, m: int, restarted: bool) -> None:
        """Count epochs in a row whose robust update rejected most rows."""
        rejected = int(np.count_nonzero(res.situation == 3))
        if not restarted and m >= 4 and rejected >= REINIT_REJECTED_FRACTION * m:
            self.bad_epochs += 1
        else:
            self.bad_epochs = 0

    def restart(self, state: GaussianState, model: DDRangeModel) -> GaussianState | None:
        """The state re-initialised on the single-epoch least-squares position (velocity zero).

        Position σ is ``max(init_sigma_m, 10 m)`` about the least-squares point (a loose
        centre, so this epoch's update does not count its data twice); ambiguities are
        dropped (the RTK stage re-adds them from the new position).
        """
        fix = least_squares_fix(model, state)
        if fix is None:
            return None
        pos, _ = fix
        est = self.cfg.estimator
        state = state.drop_ambiguities(list(state.layout.amb_keys))
        self.book.forget(list(self.book))
        x = state.x.copy()
        P = np.zeros_like(state.P)
        p = state.layout.slice("pos")
        x[p] = pos
        P[p, p] = np.eye(3) * max(est.init_sigma_m, 10.0) ** 2
        if state.layout.has("vel"):
            v = state.layout.slice("vel")
            x[v] = 0.0
            P[v, v] = np.eye(3) * max(est.init_sigma_vel_m_s, 10.0) ** 2
        return state.with_(x=x, P=P)


def smoothed_solutions(solutions: list[Solution], steps: list[FilterStep]) -> list[Solution]:
    """The solutions with positions (and velocities) from the RTS smoother over ``steps``
    (post-processing: each epoch uses the data before and after it); unsolved epochs stay."""
    from robustrtk.estimation.smoother import rts_smooth

    smooth = rts_smooth(steps)
    out = []
    for sol, step, (x, P) in zip(solutions, steps, smooth, strict=True):
        if sol.status == "none" or step.layout is None:
            out.append(sol)
            continue
        p = step.layout.slice("pos")
        vel = x[step.layout.slice("vel")].copy() if step.layout.has("vel") else sol.vel_m_s
        out.append(replace(sol, pos_m=x[p].copy(), cov_m2=P[p, p].copy(), vel_m_s=vel))
    return out


def paired_inputs(
    eng: DDEngine,
    rover: ObsBatch,
    base: ObsBatch,
    pair: BasePair,
    inputs: Callable[[int, int], EpochInputs] | None,
    lli_events: BaseEvents,
    sigma_age_m_s: float,
) -> EpochInputs:
    """The step inputs of one rover epoch and its base epoch (:mod:`~robustrtk.pipeline.base_buffer`):
    the base's loss-of-lock events since the last base epoch used, and a base epoch older
    than the pairing tolerance carried to the rover's tag. An exact pair of consecutive
    base epochs is left as it was built."""
    i, j = pair.i_rover, pair.i_base
    inp = inputs(i, j) if inputs is not None else EpochInputs(rover.epoch(i), base.epoch(j))
    b = inp.base
    if b.lli.shape == base.lli.shape[1:]:
        b = with_base_events(b, lli_events.since_last(j))
    if pair.exact:
        return inp if b is inp.base else replace(inp, base=b)
    t_r = float(rover.t_s[i])
    pos_b = inp.base_pos_m if inp.base_pos_m is not None else eng.base.position(float(b.t_s))
    return aged_inputs(
        replace(inp, base=b), t_r, eng.source, np.asarray(pos_b, float), sagnac=eng.sagnac,
        troposphere=eng.frame == "ecef", signal=eng.signal, sigma_age_m_s=sigma_age_m_s,
    )  # fmt: skip


#: Epochs whose inputs are built, and satellite positions evaluated, together in :func:`run_dd`.
PREFETCH_EPOCHS = 64


def run_dd(
    rover: ObsBatch,
    base: ObsBatch,
    cfg: Config,
    source: TransmitterSource,
    base_pos_m: FloatArray | PositionSource,
    rover_pos0_m: FloatArray,
    reference: str | None = None,
    progress: Callable[[int, int], None] | None = None,
    sagnac: bool = False,
    frame: str = "local",
    elev_mask_deg: float = 15.0,
    signal: int = 0,
    row_groups: bool = False,
    align_tol_s: float = 0.005,
    inputs: Callable[[int, int], EpochInputs] | None = None,
    engine: DDEngine | None = None,
    keep_diagnostics: bool = True,
    max_age_s: float = 0.0,
    sigma_age_m_s: float = 0.0,
    base_usable: BoolArray | None = None,
) -> RunResult:
    """Run the DD engine over all matched epochs.

    ``frame``, ``elev_mask_deg``, ``signal`` and ``row_groups`` are passed to
    :class:`DDEngine` (``frame="ecef"`` for satellites: ellipsoidal elevations and an
    elevation mask). Epochs pair when their tags agree within ``align_tol_s``; with
    ``max_age_s > 0`` a rover epoch without such a base epoch pairs with the latest base
    epoch at most that old, carried to the rover's tag with variances growing by
    ``sigma_age_m_s`` per second of age (:mod:`robustrtk.pipeline.base_buffer`; the
    solution's ``age_s`` says how old; ``base_usable`` (B,) marks the base epochs that
    may serve, default all);
    ``inputs(i_rover, i_base)`` builds each step's :class:`EpochInputs` (detector slip
    flags, a moving base's position) — by default just the two epochs. ``engine`` replaces
    the engine built from the other arguments (a filter or policy of one's own).
    ``keep_diagnostics=False`` keeps no diagnostics row, only their counts (a long run's
    rows outweigh its observations).

    Returns
    -------
    RunResult
        One :class:`Solution` per rover epoch with a base match, the diagnostics of each
        DD (none without ``keep_diagnostics``), and ``info`` (references used, epoch counts,
        re-initialisation times, ``row_tally``: the robust filter's decisions counted).
    """
    eng = engine or DDEngine(
        cfg, source, base_pos_m, rover_pos0_m, signal=signal, sagnac=sagnac, reference=reference, frame=frame,
        elev_mask_deg=elev_mask_deg, row_groups=row_groups,
    )  # fmt: skip
    out = RunResult()
    tally = RowTally()
    pairs = pair_base_epochs(rover.t_s, base.t_s, align_tol_s, max_age_s, base_usable)
    if not pairs:
        raise InputError("no common epochs between rover and base observations")
    refs_seen: set[str] = set()
    lli_events = base_lli_events(base.lli)
    from threadpoolctl import threadpool_limits  # here, not at start-up: its import is slow

    # the matrices are small: BLAS threads only contend (tens of times slower when the
    # machine is busy), so the loop runs single-threaded
    # epochs go in chunks: the satellite positions of a chunk are evaluated at once
    n = 0
    lambda_backend()  # read for this run; a bad ROBUSTRTK_LAMBDA_BACKEND stops it here, not in a search
    with threadpool_limits(limits=1, user_api="blas"):
        for c0 in range(0, len(pairs), PREFETCH_EPOCHS):
            part = pairs[c0 : c0 + PREFETCH_EPOCHS]
            chunk = [paired_inputs(eng, rover, base, p, inputs, lli_events, sigma_age_m_s) for p in part]
            prefetch = getattr(eng, "prefetch", None)
            if prefetch is not None:
                prefetch(chunk)
            for inp, pair in zip(chunk, part, strict=True):
                res = eng.step(inp)
                sol = res.solution
                out.solutions.append(sol if pair.age_s == 0.0 else replace(sol, age_s=pair.age_s))
                tally.add_epoch(res.diagnostics)
                if keep_diagnostics:
                    out.diagnostics.extend(res.diagnostics)
                refs_seen.update(eng.refs.values())
                n += 1
                notify_progress(progress, n, len(pairs), res.solution.status)
    if eng.steps is not None and len(eng.steps) == len(out.solutions):
        out.solutions = smoothed_solutions(out.solutions, eng.steps)
        out.info["smoothed"] = True
    out.info["references"] = sorted(refs_seen)
    out.info["epochs"] = len(pairs)
    out.info["reinitialised_at_s"] = list(eng.reinits)
    out.info["row_tally"] = tally.as_dict()
    out.info["integrity"] = dict(eng.integrity.counts)
    return out


__all__ = [
    "DDEngine", "DiagRow", "EpochInputs", "EpochResult", "RunResult", "align_epochs", "initial_state",
    "least_squares_fix", "make_adaptive", "make_filter", "make_process", "reindex", "rereference",
    "row_groups_of", "row_map", "run_dd", "take_rows",
]  # fmt: skip
