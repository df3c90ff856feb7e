"""The per-epoch loop for double-differenced positioning (DPL and RTK).

The engine owns nothing but the loop: per epoch it predicts the state, picks references,
forms DDs (``measurement.dd``), manages ambiguity states (add on appearance, drop on
disappearance, reset on slips), runs the filter update with the robust policy
(``estimation``), and resolves ambiguities (``ambiguity``). Transmitter positions come
from a :class:`~robustrtk.core.TransmitterSource`; pseudolites and satellites run through
the same code (satellites add the Sagnac term and need per-epoch positions).
"""

from __future__ import annotations

from collections.abc import Callable, Hashable, Iterator
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from threadpoolctl import threadpool_limits

from robustrtk.core import FloatArray, InputError, ObsBatch, ObsEpoch, Solution, TransmitterSource
from robustrtk.cycleslip.polyfit import PolyFitDetector
from robustrtk.estimation.filters import EKF, UKF, Filter
from robustrtk.estimation.models import (
    ConstantVelocityModel,
    ProcessModel,
    RandomWalkModel,
    StaticModel,
)
from robustrtk.estimation.robust import RobustPolicy, make_policy
from robustrtk.estimation.state import GaussianState, StateLayout, UpdateResult
from robustrtk.geometry.frames import ecef2geodetic
from robustrtk.geometry.los import azimuth_elevation
from robustrtk.measurement.corrections import tropo_saastamoinen
from robustrtk.measurement.dd import DDRangeModel, DDSet, choose_references, form_dd, ranges
from robustrtk.measurement.weighting import local_elevation, variance
from robustrtk.pipeline.config import Config

#: Faulty-reference test threshold on the reference's discriminant (satellite space).
REF_CHECK_K = 3.0


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
        dd,
        labels=tuple(f"{a}-{b}" for a, b in zip(tx, ref, strict=True)),
        tx=tuple(tx),
        ref=tuple(ref),
        i_tx=i_tx,
        i_ref=i_ref,
        D=T @ dd.D,
        z=T @ dd.z,
        R=0.5 * (R + R.T),
    )


@dataclass(frozen=True)
class DiagRow:
    """One DD of one epoch: what the robust filter saw and decided."""

    t_s: float
    dd: str
    kind: str
    innovation: float
    residual: float
    std_residual: float
    dv: float
    factor: float
    situation: int


@dataclass
class RunResult:
    """Solutions, diagnostics and facts about the run (reference chosen, counts)."""

    solutions: list[Solution] = field(default_factory=list)
    diagnostics: list[DiagRow] = field(default_factory=list)
    info: dict[str, object] = field(default_factory=dict)


def make_filter(cfg: Config) -> Filter:
    """EKF or UKF from the configuration."""
    if cfg.estimator.filter == "ekf":
        return EKF()
    return UKF(alpha=cfg.estimator.ukf_alpha, beta=cfg.estimator.ukf_beta, kappa=cfg.estimator.ukf_kappa)


def make_process(cfg: Config) -> ProcessModel:
    """Dynamics from the configuration (ambiguities: constant)."""
    if cfg.estimator.dynamics == "static":
        return StaticModel(q_m2_s=cfg.estimator.q_static_m2_s)
    cv = cfg.estimator.kinematic_model == "constant-velocity" or (
        cfg.estimator.kinematic_model == "auto" and cfg.mode == "rtk"
    )
    if cv:
        return ConstantVelocityModel(sigma_m_s2=cfg.estimator.sigma_acc_m_s2)
    return RandomWalkModel(sigma_m_s=cfg.estimator.sigma_vel_m_s)


def initial_state(cfg: Config, pos0_m: FloatArray, t_s: float, process: ProcessModel) -> GaussianState:
    """Known-point initialization: position at ``pos0_m`` with ``init_sigma_m``.

    With ``known_point = False`` the position is only an approximation (σ ≥ 1 m) and RTK
    converges from DD code (see :mod:`robustrtk.pipeline.rtk`)."""
    layout = StateLayout(blocks=process.blocks())
    n = layout.size
    x = np.zeros(n)
    P = np.zeros((n, n))
    p = layout.slice("pos")
    x[p] = pos0_m
    # without known-point initialization the initial position is only approximate
    sigma0 = cfg.estimator.init_sigma_m if cfg.estimator.known_point else max(cfg.estimator.init_sigma_m, 1.0)
    P[p, p] = np.eye(3) * sigma0**2
    if layout.has("vel"):
        v = layout.slice("vel")
        P[v, v] = np.eye(3) * cfg.estimator.init_sigma_vel_m_s**2
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


def _reindex(epoch: ObsEpoch, tx_ids: tuple[str, ...]) -> ObsEpoch:
    """The epoch's rows reordered to ``tx_ids`` (NaN rows for transmitters it lacks)."""
    if epoch.tx_ids == tx_ids:
        return epoch
    idx = np.array([epoch.tx_ids.index(t) if t in epoch.tx_ids else -1 for t in tx_ids])
    have = idx >= 0

    def take(a: np.ndarray, fill: float) -> np.ndarray:
        out = np.full((len(tx_ids),) + a.shape[1:], fill, dtype=a.dtype)
        out[have] = a[idx[have]]
        return out

    return replace(
        epoch,
        tx_ids=tx_ids,
        system=tuple(epoch.system[i] if i >= 0 else "P" for i in idx),
        code_m=take(epoch.code_m, np.nan),
        phase_cyc=take(epoch.phase_cyc, np.nan),
        doppler_hz=take(epoch.doppler_hz, np.nan),
        cn0_dbhz=take(epoch.cn0_dbhz, np.nan),
        lli=take(epoch.lli, 0),
        wavelength_m=take(epoch.wavelength_m, np.nan),
    )


class DDEngine:
    """Stateful epoch loop around immutable filter states (DPL and RTK modes).

    Parameters
    ----------
    cfg : Config
    source : TransmitterSource
        Transmitter positions (local frame for pseudolites).
    base_pos_m : ndarray, shape (3,)
        Known base position.
    rover_pos0_m : ndarray, shape (3,)
        Known-point initial rover position.
    signal : int
        Signal column used (0 for single-frequency pseudolites).
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
        base_pos_m: FloatArray,
        rover_pos0_m: FloatArray,
        signal: int = 0,
        sagnac: bool = False,
        reference: str | None = None,
        frame: str = "local",
        elev_mask_deg: float = 15.0,
        row_groups: bool = False,
    ) -> None:
        if frame not in ("local", "ecef"):
            raise ValueError(f"frame: expected local or ecef, got {frame!r}")
        self.frame = frame
        self.elev_mask_rad = float(np.deg2rad(elev_mask_deg))
        self.cfg = cfg
        self.source = source
        self.base_pos_m = np.asarray(base_pos_m, float)
        self.rover_pos0_m = np.asarray(rover_pos0_m, float)
        self.signal = signal
        self.sagnac = sagnac
        self.filter = make_filter(cfg)
        self.process = make_process(cfg)
        self.robust: RobustPolicy = make_policy(cfg.robust.policy, cfg.robust.k0, cfg.robust.k1)
        self.preferred_ref = reference
        self.refs: dict[str, str] = {}
        self.state: GaussianState | None = None
        self.fixed: dict[Hashable, float] = {}
        # RTK bookkeeping (robustrtk.pipeline.rtk)
        self._poly: PolyFitDetector | None = None
        self._slip_refs: dict[str, str] = {}
        self._amb_ref: dict[Hashable, str] = {}
        self._suspect: dict[Hashable, int] = {}
        self.row_groups = row_groups
        # per-epoch inputs of the RTK step: detector slips and half-cycle flags per row,
        # elevation of each row (rad), and lock counts per ambiguity key
        self.ext_slip: np.ndarray | None = None
        self.half_cycle: np.ndarray | None = None
        self.elev_rad: FloatArray | None = None
        self._lock: dict[Hashable, int] = {}
        self._fix_streak = 0
        self.tx_corr_m: FloatArray | None = None

    # ------------------------------------------------------------------ helpers
    def _groups(self, epoch: ObsEpoch) -> list[str]:
        if self.row_groups:
            return [f"{s}:{t.split(':', 1)[1]}" for s, t in zip(epoch.system, epoch.tx_ids, strict=True)]
        sig = epoch.signals[self.signal] if epoch.signals else "L1"
        return [f"{s}:{sig}" for s in epoch.system]

    def _elevation(self, pos_m: FloatArray, tx_pos: FloatArray) -> FloatArray:
        if self.frame == "ecef":
            return azimuth_elevation(tx_pos, pos_m)[1]
        return local_elevation(pos_m, tx_pos)

    def _variances(self, sigma: float, epoch: ObsEpoch, pos_m: FloatArray, tx_pos: FloatArray) -> FloatArray:
        cfg = self.cfg
        n = epoch.n_tx
        if cfg.measurement.weighting == "equal":
            return variance(sigma, "equal", n=n)
        if cfg.measurement.weighting == "elevation":
            return variance(sigma, "elevation", elev_rad=self._elevation(pos_m, tx_pos))
        if cfg.measurement.weighting == "distance":
            return variance(sigma, "distance", dist_m=np.linalg.norm(tx_pos - pos_m, axis=1))
        return variance(sigma, "snr", snr_dbhz=epoch.cn0_dbhz[:, self.signal])

    # ------------------------------------------------------------------ main step
    def step(self, rover: ObsEpoch, base: ObsEpoch) -> tuple[Solution, list[DiagRow]]:
        """Process one matched epoch pair and return its solution and diagnostics."""
        cfg = self.cfg
        base = _reindex(base, rover.tx_ids)
        t = rover.t_s
        if self.state is None:
            self.state = initial_state(cfg, self.rover_pos0_m, t, self.process)
        state = self.filter.predict(self.state, self.process, t)
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
        groups = self._groups(rover)
        avail = tx_ok & np.isfinite(code_r) & np.isfinite(code_b)
        if cfg.mode == "rtk":
            avail &= np.isfinite(rover.phase_cyc[:, k]) & np.isfinite(base.phase_cyc[:, k])
        if cfg.measurement.snr_mask_dbhz > 0:
            with np.errstate(invalid="ignore"):
                low = (rover.cn0_dbhz[:, k] < cfg.measurement.snr_mask_dbhz) | (
                    base.cn0_dbhz[:, k] < cfg.measurement.snr_mask_dbhz
                )
            avail &= ~low
        tx_pos_safe = np.where(tx_ok[:, None], tx_pos, 0.0)
        tx_pos_b_safe = np.where(tx_ok[:, None], tx_pos_b, 0.0)
        score = self._elevation(pos_prior, tx_pos_safe)
        self.elev_rad = score
        if self.frame == "ecef":
            avail &= score >= self.elev_mask_rad
        preferred = {g: self.preferred_ref for g in set(groups)} if self.preferred_ref else None
        refs = choose_references(rover.tx_ids, groups, avail, score, preferred, self.refs)
        state = self._ref_change(refs, state)
        self.refs = refs
        base_range = ranges(self.base_pos_m, tx_pos_b_safe, self.sagnac)
        self.tx_corr_m = None
        if self.frame == "ecef" and cfg.measurement.tropo == "saastamoinen":
            base_range = base_range + self._tropo(self.base_pos_m, tx_pos_b_safe)
            self.tx_corr_m = self._tropo(pos_prior, tx_pos_safe)
        var_code_r = self._variances(cfg.measurement.code_sigma_m, rover, pos_prior, tx_pos_safe)
        var_code_b = self._variances(cfg.measurement.code_sigma_m, base, self.base_pos_m, tx_pos_safe)
        code_dd = form_dd(
            rover.tx_ids,
            groups,
            np.where(avail, code_r, np.nan),
            np.where(avail, code_b, np.nan),
            var_code_r,
            var_code_b,
            refs,
        )
        if cfg.mode != "rtk":
            return self._step_dpl(state, t, code_dd, tx_pos_safe, base_range)
        from robustrtk.pipeline.rtk import rtk_step

        return rtk_step(
            self, state, t, rover, base, groups, avail, refs, code_dd, tx_pos_safe, base_range, pos_prior
        )

    def _tropo(self, pos_m: FloatArray, tx_pos: FloatArray) -> FloatArray:
        """Saastamoinen slant delays (m) from ``pos_m`` to each transmitter."""
        lat, _, h = ecef2geodetic(pos_m)
        el = azimuth_elevation(tx_pos, pos_m)[1]
        return np.asarray(tropo_saastamoinen(lat, h, el), float)

    def _ref_change(self, refs: dict[str, str], state: GaussianState) -> GaussianState:
        """Re-express DD ambiguities of groups whose reference changed (no reset).

        With old reference ``k`` and new reference ``k'`` (which had the ambiguity
        ``N^{k'k}``): ``N^{ik'} = N^{ik} − N^{k'k}`` for every other ``i``, and the old
        reference gets ``N^{kk'} = −N^{k'k}``; a linear map ``x ← T x``, ``P ← T P Tᵀ``
        that keeps all the information (and any fixed integers integer). Groups whose new
        reference had no ambiguity state are left to the usual drop-and-re-add.
        """
        if self.cfg.mode != "rtk" or not state.layout.amb_keys:
            return state
        layout = state.layout
        keys = list(layout.amb_keys)
        n = state.n
        T = np.eye(n)
        new_keys = list(keys)
        changed = False
        for g, new_ref in refs.items():
            old_ref = self.refs.get(g)
            if old_ref is None or old_ref == new_ref:
                continue
            kref = (new_ref, g)
            if kref not in keys:
                continue
            j = layout.amb_index(kref)
            for key in keys:
                if key == kref or key[1] != g:  # type: ignore[index]
                    continue
                T[layout.amb_index(key), j] -= 1.0
            # the new reference's slot now holds the old reference's ambiguity
            T[j, :] = 0.0
            T[j, j] = -1.0
            new_keys[keys.index(kref)] = (old_ref, g)
            for key in keys:
                if key[1] == g:  # type: ignore[index]
                    self._amb_ref[key] = new_ref
            self._amb_ref[(old_ref, g)] = new_ref
            self._amb_ref.pop(kref, None)
            self._lock[(old_ref, g)] = self._lock.pop(kref, 0)
            if kref in self.fixed:
                self.fixed[(old_ref, g)] = -self.fixed.pop(kref)
            changed = True
        if not changed:
            return state
        P = T @ state.P @ T.T
        return state.with_(x=T @ state.x, P=0.5 * (P + P.T), layout=replace(layout, amb_keys=tuple(new_keys)))

    def _model(
        self,
        dd: DDSet,
        tx_pos: FloatArray,
        base_range: FloatArray,
        state: GaussianState,
        amb_idx: np.ndarray | None,
        wavelength: FloatArray | None,
        scale: float = 1.0,
    ) -> DDRangeModel:
        m = dd.m
        return DDRangeModel(
            tx_pos_m=tx_pos,
            base_range_m=base_range,
            i_tx=dd.i_tx,
            i_ref=dd.i_ref,
            pos_slice=state.layout.slice("pos"),
            amb_idx=np.full(m, -1, dtype=np.int64) if amb_idx is None else amb_idx,
            wavelength_m=np.zeros(m) if wavelength is None else wavelength,
            z=dd.z * scale,
            R=dd.R * scale**2,
            labels=dd.labels,
            sagnac=self.sagnac,
            tx_corr_m=self.tx_corr_m,
        )

    def _diag(self, t: float, labels: tuple[str, ...], kinds: list[str], res: UpdateResult) -> list[DiagRow]:
        return [
            DiagRow(
                t,
                lab,
                kinds[i],
                float(res.innovation[i]),
                float(res.residual[i]),
                float(res.std_residual[i]),
                float(res.dv[i]),
                float(res.factors[i]),
                int(res.situation[i]),
            )
            for i, lab in enumerate(labels)
        ]

    def _solution(self, state: GaussianState, t: float, status: str, n_used: int, **kw: Any) -> Solution:
        vel = state.get("vel").copy() if state.layout.has("vel") else None
        return Solution(
            t_s=t,
            pos_m=state.get("pos").copy(),
            cov_m2=state.cov("pos").copy(),
            status=status,
            n_used=n_used,
            vel_m_s=vel,
            **kw,
        )

    def _check_references(
        self, state: GaussianState, dd: DDSet, tx_pos: FloatArray, base_range: FloatArray
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
        model = self._model(dd, tx_pos, base_range, state, None, None)
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
            el = self.elev_rad[dd.i_tx[rows[ok]]] if self.elev_rad is not None else np.zeros(ok.size)
            dd = rereference(dd, rows, int(rows[ok[int(np.argmax(el))]]))
        return dd

    def _step_dpl(
        self, state: GaussianState, t: float, dd: DDSet, tx_pos: FloatArray, base_range: FloatArray
    ) -> tuple[Solution, list[DiagRow]]:
        if dd.m < 3:
            self.state = state
            return self._solution(state, t, "none", 0), []
        if self.frame == "ecef" and self.preferred_ref is None:
            dd = self._check_references(state, dd, tx_pos, base_range)
        model = self._model(dd, tx_pos, base_range, state, None, None)
        res = self.filter.update(state, model, self.robust)
        self.state = res.state
        diag = self._diag(t, dd.labels, ["code"] * dd.m, res)
        return self._solution(res.state, t, "code", res.n_used), diag


def run_dd(
    rover: ObsBatch,
    base: ObsBatch,
    cfg: Config,
    source: TransmitterSource,
    base_pos_m: FloatArray,
    rover_pos0_m: FloatArray,
    reference: str | None = None,
    progress: Callable[[int, int], None] | None = None,
    sagnac: bool = False,
    frame: str = "local",
    elev_mask_deg: float = 15.0,
    signal: int = 0,
    row_groups: bool = False,
    align_tol_s: float = 0.005,
    epoch_hook: Callable[[DDEngine, int, int], None] | None = None,
) -> RunResult:
    """Run the DD engine over all matched epochs.

    ``frame``, ``elev_mask_deg``, ``signal`` and ``row_groups`` are passed to
    :class:`DDEngine` (``frame="ecef"`` for satellites: ellipsoidal elevations and an
    elevation mask). Epochs pair when their tags agree within ``align_tol_s``;
    ``epoch_hook(engine, i_rover, i_base)`` runs before each step (per-epoch inputs such
    as detector slip flags).

    Returns
    -------
    RunResult
        One :class:`Solution` per rover epoch with a base match, the diagnostics of each
        DD, and ``info`` (reference used, epoch counts).
    """
    eng = DDEngine(
        cfg,
        source,
        base_pos_m,
        rover_pos0_m,
        signal=signal,
        sagnac=sagnac,
        reference=reference,
        frame=frame,
        elev_mask_deg=elev_mask_deg,
        row_groups=row_groups,
    )
    out = RunResult()
    pairs = list(align_epochs(rover, base, tol_s=align_tol_s))
    if not pairs:
        raise InputError("no common epochs between rover and base observations")
    refs_seen: set[str] = set()
    # the matrices are small: BLAS threads only contend (tens of times slower when the
    # machine is busy), so the loop runs single-threaded
    with threadpool_limits(limits=1, user_api="blas"):
        for n, (i, j) in enumerate(pairs):
            if epoch_hook is not None:
                epoch_hook(eng, i, j)
            sol, diag = eng.step(rover.epoch(i), base.epoch(j))
            out.solutions.append(sol)
            out.diagnostics.extend(diag)
            refs_seen.update(eng.refs.values())
            if progress is not None:
                progress(n + 1, len(pairs))
    out.info["references"] = sorted(refs_seen)
    out.info["epochs"] = len(pairs)
    return out


__all__ = ["DDEngine", "DiagRow", "RunResult", "rereference", "run_dd"]
