"""Integrity monitor: the filter's prediction confronted with an independent snapshot.

A robust filter whose prior is wrong sees every good measurement as an outlier: it
down-weights or rejects them, coasts on its own prediction and passes its own validation,
because the rejected rows no longer speak. The monitor breaks that loop with a test the
filter cannot talk itself out of (``docs/algorithms.md`` §30):

1. *snapshot*: a single-epoch, robust least-squares position of the epoch's own rows
   (:func:`robust_snapshot`: iteratively reweighted Gauss–Newton with Huber weights), with
   its covariance ``C_s`` scaled by the a-posteriori variance factor when the rows scatter
   more than their nominal σ says. It uses no state memory, so it is independent of the
   prediction;
2. *test*: ``d = x̄_pos − x_s``, ``T = dᵀ (P̄_pos + C_s)⁻¹ d``; the prediction is
   consistent when ``T ≤ χ²₃(1 − α)`` (:meth:`IntegrityMonitor.check`);
3. *reaction*: when inconsistent, the position/velocity prior is widened by the smallest
   scale ``s`` with ``dᵀ (s P̄_pos + C_s)⁻¹ d = χ²₃(1 − α)`` (the data then decide); when
   the test has failed ``patience`` epochs in a row, the caller re-initialises the
   position and velocity from the snapshot (:meth:`IntegrityMonitor.reinitialised`).

The same snapshot bounds the reported covariance from below (:func:`covariance_floor`):
code errors that are correlated in time (multipath, atmospheric residuals) do not average
out over epochs, so a filter cannot know the position better than one epoch of the same
code rows does. A carrier-phase solution's reported covariance carries the unmodelled-error
budget (:func:`unmodelled_covariance`: a fixed position with a millimetre σ and a
centimetre error is the worst thing to print). And a fixed solution is reported only when
it agrees with the float snapshot (:func:`fix_agrees`).

The policy (:class:`IntegrityPolicy`) is an object passed in, so a caller may replace it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from robustrtk.core import FloatArray, median_of, vector_norm
from robustrtk.estimation.adaptive import MEDIAN_ABS_NORMAL
from robustrtk.estimation.prior_scale import apply_prior_scale
from robustrtk.estimation.state import GaussianState
from robustrtk.measurement.chi2 import chi2_ppf

#: Huber tuning constant (standardized residual) of the snapshot's reweighting.
HUBER_K = 1.5


@dataclass(frozen=True)
class IntegrityPolicy:
    """How the monitor tests and reacts.

    Attributes
    ----------
    alpha : float
        False-alarm probability of the χ² test (3 degrees of freedom).
    patience : int
        Failed tests in a row before the position/velocity are re-initialised from the
        snapshot (the prior widening had its chance on the epochs before).
    max_gap_s : float
        A prediction across a longer gap (s) is not tested but replaced by the snapshot:
        its linearisation point may be anywhere.
    min_redundancy : int
        Rows beyond the three position unknowns the snapshot needs (without redundancy a
        faulty row cannot show).
    floor_covariance : bool
        Bound the reported position covariance below by the snapshot's.
    reinit_with_ambiguities : bool
        Whether a state that carries carrier-phase ambiguities may be re-initialised from
        the code snapshot when the widening does not reconcile them. Off by default: the
        ambiguities tie the position to the phase, which is far more precise than a code
        snapshot (metres on a patch antenna); re-starting from the snapshot throws that away
        and, measured on a low-cost kinematic rover, led to wrong integers where widening
        alone let the phase pull the position back. A gap longer than ``max_gap_s`` and the
        first epoch re-initialise whatever this says.
    enabled : bool
        False: no test, no reaction (the filter alone).
    """

    alpha: float = 1e-3
    patience: int = 3
    max_gap_s: float = 600.0
    min_redundancy: int = 1
    floor_covariance: bool = True
    reinit_with_ambiguities: bool = False
    enabled: bool = True

    @property
    def threshold(self) -> float:
        """χ²₃(1 − α)."""
        return chi2_ppf(1.0 - self.alpha, 3)


@dataclass(frozen=True)
class Snapshot:
    """A single-epoch position: ``pos_m`` (3,) ECEF or local (m) and ``cov_m2`` (3, 3)."""

    pos_m: FloatArray
    cov_m2: FloatArray


@dataclass(frozen=True)
class IntegrityEvent:
    """One epoch's test: ``kind`` ``"inflate"`` or ``"reinit"`` (``"ok"`` when consistent),
    the test value ``T`` and the scale applied to the position/velocity prior."""

    kind: str
    test: float
    scale: float = 1.0


#: Condition number of the snapshot's normal matrix above which its geometry counts as
#: singular (about 1/√ε of double precision: beyond it the inverse has no correct digits
#: left for the covariance a χ² test would use).
MAX_NORMAL_CONDITION = 1e8


def robust_snapshot(
    h: Callable[[FloatArray], FloatArray],
    jacobian: Callable[[FloatArray], FloatArray],
    z: FloatArray,
    R: FloatArray,
    x0: FloatArray,
    pos: slice,
    iterations: int = 8,
    min_redundancy: int = 1,
) -> Snapshot | None:
    """Robust single-epoch least squares of the position block of ``x0``.

    Gauss–Newton on the rows ``z ≈ h(x)`` (only ``x[pos]`` moves), each iteration with
    Huber weights ``w = min(1, k/|v|)`` on the whitened residuals ``v = L⁻¹(z − h(x))``
    (``R = L Lᵀ``, ``k = HUBER_K``); the covariance ``(Hᵀ W R⁻¹ H)⁻¹`` is multiplied by
    the larger of the a-posteriori variance factor ``σ̂₀² = vᵀ W v / (m − 3)`` and the
    robust one ``(median |v| / 0.6745)²`` when either exceeds 1. The robust factor matters
    when most rows are wrong (a burst of reflected signals): the fit then sits on no
    consistent set of rows, its residuals are large on most rows, and its covariance
    grows with them, so a wrong snapshot cannot pass for a precise one.

    Parameters
    ----------
    h, jacobian : callable
        Model ``h(x)`` (m,) and its Jacobian (m, n).
    z : ndarray, shape (m,)
    R : ndarray, shape (m, m)
    x0 : ndarray, shape (n,)
        Linearisation start (other components are held).
    pos : slice
        The position block of ``x``.

    Returns
    -------
    Snapshot or None
        None with fewer than ``3 + min_redundancy`` rows or a singular geometry (normal
        matrix condition number above :data:`MAX_NORMAL_CONDITION`).
    """
    m = int(np.size(z))
    if m < 3 + min_redundancy:
        return None
    x = np.array(x0, float, copy=True)
    R = np.asarray(R, float)
    try:
        L = np.linalg.cholesky(R)
        Linv = np.linalg.inv(L)
    except np.linalg.LinAlgError:
        return None
    w = np.ones(m)
    z = np.asarray(z, float)
    for it in range(iterations):
        H = Linv @ np.asarray(jacobian(x), float)[:, pos]
        v = Linv @ (z - np.asarray(h(x), float))
        if it > 0:
            a = np.abs(v)
            w = np.where(a > HUBER_K, HUBER_K / np.maximum(a, 1e-12), 1.0)
        Hw = H * w[:, None]
        try:
            dx = np.linalg.solve(H.T @ Hw, Hw.T @ v)
        except np.linalg.LinAlgError:
            return None
        x[pos] = x[pos] + dx
        if it > 0 and vector_norm(dx) < 1e-4:
            break
    H = Linv @ np.asarray(jacobian(x), float)[:, pos]
    v = Linv @ (z - np.asarray(h(x), float))
    a = np.abs(v)
    w = np.where(a > HUBER_K, HUBER_K / np.maximum(a, 1e-12), 1.0)
    N = H.T @ (H * w[:, None])
    try:
        C = np.linalg.inv(N)
    except np.linalg.LinAlgError:
        return None  # singular: its condition number is infinite
    # ‖N‖_F ‖N⁻¹‖_F ≥ cond₂(N): a decade below the limit it decides without the singular
    # values (the inverse's rounding, ~cond·ε relative, cannot bridge a decade)
    if not vector_norm(N.ravel()) * vector_norm(C.ravel()) <= 0.1 * MAX_NORMAL_CONDITION and (
        normal_condition(N) > MAX_NORMAL_CONDITION
    ):
        # a degenerate geometry: the fit wandered off to where every row looks the same
        # way (a gross error on rows that barely over-determine a near, nonlinear
        # geometry such as a pseudolite room); its covariance is numerical noise, no evidence
        return None
    s02 = float((w * v * v).sum()) / max(m - 3, 1)
    mad2 = (median_of(a) / MEDIAN_ABS_NORMAL) ** 2
    C = C * max(1.0, s02, mad2)
    if not (np.isfinite(x[pos]).all() and np.isfinite(C).all()):
        return None
    return Snapshot(x[pos].copy(), 0.5 * (C + C.T))


def normal_condition(N: FloatArray) -> float:
    """2-norm condition number of a square matrix, the number :func:`numpy.linalg.cond` gives
    (largest over smallest singular value; inf for a singular matrix without NaN), from one
    call of the singular values instead of its generic checks."""
    s = np.linalg.svd(N, compute_uv=False)
    with np.errstate(all="ignore"):
        r = float(s[0] / s[-1])
    if np.isnan(r) and not np.isnan(N).any():
        return float("inf")
    return r


def consistency(prior_pos_m: FloatArray, prior_cov_m2: FloatArray, snap: Snapshot) -> float:
    """``T = dᵀ (P̄ + C_s)⁻¹ d`` with ``d = x̄ − x_s`` (χ²₃ when both are right); inf
    when the joint covariance is singular."""
    d = np.asarray(prior_pos_m, float) - snap.pos_m
    S = np.asarray(prior_cov_m2, float) + snap.cov_m2
    try:
        return float(d @ np.linalg.solve(S, d))
    except np.linalg.LinAlgError:
        return float("inf")


def widening(prior_pos_m: FloatArray, prior_cov_m2: FloatArray, snap: Snapshot, threshold: float) -> float:
    """The smallest ``s ≥ 1`` with ``dᵀ (s P̄ + C_s)⁻¹ d ≤ threshold`` (bisection on the
    logarithm; ``T(s)`` decreases with ``s``), capped at 1e12."""
    lo, hi = 0.0, 12.0
    if consistency(prior_pos_m, prior_cov_m2 * 10.0**hi, snap) > threshold:
        return 10.0**hi
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        if consistency(prior_pos_m, prior_cov_m2 * 10.0**mid, snap) > threshold:
            lo = mid
        else:
            hi = mid
    return float(10.0**hi)


def kinematic_indices(state: GaussianState, blocks: tuple[str, ...] = ("pos", "vel", "acc")) -> np.ndarray:
    """State indices of the kinematic blocks present."""
    idx = [
        np.arange(state.layout.slice(b).start, state.layout.slice(b).stop)
        for b in blocks
        if state.layout.has(b)
    ]
    return np.concatenate(idx).astype(int) if idx else np.zeros(0, int)


def widen(state: GaussianState, scale: float) -> GaussianState:
    """The state with its kinematic block's covariance times ``scale`` (cross-covariances
    times √scale: every correlation kept, ``P^α`` of algorithms.md §23)."""
    f = np.ones(state.n)
    f[kinematic_indices(state)] = scale
    return state.with_(P=apply_prior_scale(state.P, f))


def reinitialise(state: GaussianState, snap: Snapshot, vel_sigma_m_s: float) -> GaussianState:
    """Position from the snapshot (covariance ``C_s``), velocity zero with σ
    ``vel_sigma_m_s``, no correlation of either with the other states (which are kept)."""
    x = state.x.copy()
    P = state.P.copy()
    k = kinematic_indices(state)
    P[k, :] = 0.0
    P[:, k] = 0.0
    p = state.layout.slice("pos")
    x[p] = snap.pos_m
    P[p, p] = snap.cov_m2
    for b in ("vel", "acc"):
        if state.layout.has(b):
            s = state.layout.slice(b)
            x[s] = 0.0
            P[s, s] = np.eye(s.stop - s.start) * vel_sigma_m_s**2
    return state.with_(x=x, P=P)


@dataclass
class IntegrityMonitor:
    """Per-run memory of the test (failed epochs in a row) and the counts of events."""

    policy: IntegrityPolicy = field(default_factory=IntegrityPolicy)
    failed: int = 0
    counts: dict[str, int] = field(default_factory=lambda: {"inflate": 0, "reinit": 0, "fix_rejected": 0})

    def check(
        self, prior: GaussianState, snap: Snapshot | None, first: bool = False
    ) -> tuple[GaussianState, IntegrityEvent | None]:
        """Test the prediction against the snapshot and widen it when inconsistent.

        ``first``: the prior is the starting guess (no data behind it, nothing worth
        widening): an inconsistency re-initialises at once. A prior with ambiguity states is
        only widened unless ``policy.reinit_with_ambiguities``.

        Returns the (possibly widened) prior and the event (None when there is no
        snapshot; kind ``"ok"`` when consistent). When the event is ``"reinit"`` the caller
        re-initialises (:func:`reinitialise` or its own start-up) and the prior returned is
        unchanged.
        """
        if snap is None or not self.policy.enabled:
            return prior, None
        p = prior.layout.slice("pos")
        xp, Pp = prior.x[p], prior.P[p, p]
        thr = self.policy.threshold
        T = consistency(xp, Pp, snap)
        if T <= thr:
            self.failed = 0
            return prior, IntegrityEvent("ok", T)
        self.failed += 1
        may_reinit = self.policy.reinit_with_ambiguities or not prior.layout.amb_keys
        if first or (self.failed >= self.policy.patience and may_reinit):
            self.failed = 0
            self.counts["reinit"] += 1
            return prior, IntegrityEvent("reinit", T)
        s = widening(xp, Pp, snap, thr)
        self.counts["inflate"] += 1
        return widen(prior, s), IntegrityEvent("inflate", T, s)

    def reinit_now(self) -> None:
        """Count a re-initialisation decided outside :meth:`check` (a time gap)."""
        self.failed = 0
        self.counts["reinit"] += 1


def fix_agrees(
    fixed: GaussianState, snap: Snapshot | None, alpha: float = 1e-3, require: bool = False
) -> str:
    """Why a fixed solution must not be reported ("" when it may).

    The fixed position must agree with the epoch's snapshot within ``P_fixed + C_s`` (the
    same test as the prediction's). The float solution is not the reference: under
    fix-and-hold it already carries the integers held before, and its covariance is as
    optimistic as the filter's model, so a right fix can sit outside it (phone-like data:
    70 of 360 right fixes refused) while the independent snapshot still sees a gross one.
    Without a snapshot (too few code rows for a redundant single-epoch solution) nothing
    confirms the fix: it is refused when ``require`` (the engine's integrity monitor on),
    else passed.
    """
    p = fixed.layout.slice("pos")
    return fixed_position_agrees(fixed.x[p], fixed.P[p, p], snap, alpha, require)


def fixed_position_agrees(
    pos_m: FloatArray, cov_m2: FloatArray, snap: Snapshot | None, alpha: float = 1e-3, require: bool = False
) -> str:
    """:func:`fix_agrees` of a fixed position ``pos_m`` (3,) and its covariance ``cov_m2``
    (3, 3) (m, m²): the test reads nothing else of the fixed state."""
    if snap is None:
        return "no snapshot to confirm the fix" if require else ""
    thr = chi2_ppf(1.0 - alpha, 3)
    if not consistency(pos_m, cov_m2, snap) <= thr:
        return "fix disagrees with snapshot"
    return ""


#: Unmodelled-error budget of a carrier-phase position (1σ): horizontal and vertical
#: constant (m) and baseline-proportional part (ppm), the figures survey-grade receivers
#: state for their own RTK (8 mm + 1 ppm horizontal, 15 mm + 1 ppm vertical RMS): antenna
#: phase-centre variations, phase multipath, residual troposphere and orbit errors that no
#: term of the filter models.
CARRIER_FLOOR_H_M = 0.008
CARRIER_FLOOR_V_M = 0.015
CARRIER_FLOOR_PPM = 1.0


def unmodelled_covariance(baseline_m: float, up: FloatArray) -> FloatArray:
    """Covariance (3, 3) of the unmodelled errors of a carrier-phase position.

    ``C_u = σ_h² (I − u uᵀ) + σ_v² u uᵀ`` with ``σ_h = 8 mm + 1 ppm·b`` and
    ``σ_v = 15 mm + 1 ppm·b`` (:data:`CARRIER_FLOOR_H_M`, ...), ``b`` the baseline
    length (m) and ``u`` the local vertical (unit vector in the position's frame)."""
    u = np.asarray(up, float)
    u = u / np.sqrt(u.dot(u))  # np.linalg.norm(u), the same number
    ppm = CARRIER_FLOOR_PPM * 1e-6 * abs(float(baseline_m))
    sh, sv = CARRIER_FLOOR_H_M + ppm, CARRIER_FLOOR_V_M + ppm
    uu = u[:, None] * u[None, :]  # np.outer(u, u)
    return np.asarray(sh**2 * (np.eye(3) - uu) + sv**2 * uu, float)


def covariance_floor(cov_m2: FloatArray, snap_cov_m2: FloatArray) -> FloatArray:
    """The smallest covariance above both ``cov_m2`` and ``snap_cov_m2`` along the
    snapshot's axes: with ``C_s = L Lᵀ``, the eigenvalues of ``L⁻¹ P L⁻ᵀ`` are raised to at
    least 1 (so the result ⪰ C_s and ⪰ P in the Loewner order)."""
    P = np.asarray(cov_m2, float)
    C = np.asarray(snap_cov_m2, float)
    try:
        L = np.linalg.cholesky(C)
    except np.linalg.LinAlgError:
        return P
    Li = np.linalg.inv(L)
    M = Li @ P @ Li.T
    lam, V = np.linalg.eigh(0.5 * (M + M.T))
    out = L @ (V * np.maximum(lam, 1.0)) @ V.T @ L.T
    return 0.5 * (out + out.T)


def phase_variance_factor(residual_m: FloatArray, cov_m2: FloatArray, dof: int) -> float:
    """A-posteriori variance factor of a carrier solution's phase rows, at least 1.

    ``σ̂₀² = vᵀ R⁻¹ v / f`` with ``v`` the post-fit DD phase residuals of the reported
    (fixed) state, ``R`` their covariance and ``f`` the redundancy (rows minus the position
    and the ambiguities left float). Under the model ``E[σ̂₀²] = 1``; a larger value says the
    phase is noisier than ``R`` (patch-antenna multipath), and the position covariance
    scaled by it is what the same residuals support. Never below 1 (one epoch's few rows
    cannot prove the model pessimistic); 1 without redundancy or with a singular ``R``.

    Parameters
    ----------
    residual_m : ndarray, shape (m,)
        Post-fit residuals (m).
    cov_m2 : ndarray, shape (m, m)
        Their covariance (m²).
    dof : int
        Redundancy ``f``.

    Returns
    -------
    float
        ``max(1, σ̂₀²)``.
    """
    v = np.asarray(residual_m, float)
    if dof <= 0 or v.size == 0 or not np.isfinite(v).all():
        return 1.0
    try:
        q = float(v @ np.linalg.solve(np.asarray(cov_m2, float), v))
    except np.linalg.LinAlgError:
        return 1.0
    return max(1.0, q / dof) if np.isfinite(q) else 1.0


__all__ = [
    "CARRIER_FLOOR_H_M", "CARRIER_FLOOR_PPM", "CARRIER_FLOOR_V_M", "HUBER_K", "IntegrityEvent",
    "IntegrityMonitor", "IntegrityPolicy", "Snapshot", "consistency", "covariance_floor", "fix_agrees",
    "fixed_position_agrees", "kinematic_indices", "normal_condition", "phase_variance_factor", "reinitialise",
    "robust_snapshot", "unmodelled_covariance", "widen", "widening",
]  # fmt: skip
