"""Cooperative positioning estimators (Zhou et al. 2018; algorithms.md §21).

Each node ``m`` estimates ``x_m = [p_m (3), b_m,1 .. b_m,c]`` (ECEF m; one clock per
satellite system, in metres; optionally a velocity block) from its own pseudoranges and the
ranges to its peers, using the positions and covariances the peers broadcast
(:mod:`robustrtk.measurement.coop` has the rows). This module holds what does not depend
on GNSS files:

* :class:`LocationTimeModel` — the process model of eq. 8, ``x_t = x_t−1 + Δt w``,
  ``w ~ N(0, Q̃)``, ``Q̃ = diag(σ_ẋ², σ_ẏ², σ_ż², σ_ḃ²)`` in m²/s²;
* four filters behind one interface (:class:`NodeFilter`): :class:`KalmanNode` ``ekf``
  (eqs. 12–13), :class:`KalmanNode` ``ukf`` — the augmented UKF of eqs. 14–19 with
  ``λ = (α² − 1) L`` (:func:`augmented_ukf_predict`), :class:`ParticleNode` (eqs. 20–23,
  :mod:`robustrtk.estimation.particle`) and :class:`LeastSquaresNode` (the paper's
  baseline: per-epoch Gauss–Newton, :func:`gauss_newton`);
* the cooperation modes (:data:`COOPERATION`): ``off`` (no peer rows), ``traditional``
  (the range variance as measured, no inflation, no reset) and ``improved`` — the range
  variance inflated by the peer's uncertainty, eq. 24, with the peer covariance reset at
  every update, eq. 29 (EKF, PF, LS) or eq. 30 (UKF), :func:`range_variance`;
  ``σ_set`` and ``σ_wset`` come from a short window of the peer's broadcasts
  (:class:`PeerWindow`) unless given (:class:`ResetSettings`).

Typical use for one node and epoch::

    filt = make_node_filter("pf", n_particles=10_000, linear_idx=(3,), seed=1)
    belief = filt.init(GaussianState(x0, P0, t0, layout))
    belief = filt.predict(belief, LocationTimeModel(), t1)
    rows = StackedModel((pseudoranges, peer_range_model(...)))
    step = filt.update(belief, rows)          # NodeStep: belief, summary, ESS, ...
    broadcast = PeerBroadcast.of("node2", step.summary)
"""

from __future__ import annotations

import functools
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from types import ModuleType
from typing import Literal, Protocol, get_args

import numpy as np
import numpy.typing as npt

from robustrtk import jit as kernel_policy
from robustrtk.core import CLIGHT, FloatArray, MeasurementModel
from robustrtk.estimation.filters import EKF, sigma_points, symmetrize
from robustrtk.estimation.models import ProcessModel
from robustrtk.estimation.particle import ParticleFilter, ParticleState
from robustrtk.estimation.state import GaussianState, StateLayout
from robustrtk.geometry.los import OMEGA_E_RAD_S
from robustrtk.measurement.coop import PeerRangeModel, PseudorangeModel
from robustrtk.measurement.dd import StackedModel

FilterKind = Literal["ekf", "ukf", "pf", "ls"]
Cooperation = Literal["improved", "traditional", "off"]
#: Filter names of :func:`make_node_filter`.
FILTER_KINDS: tuple[str, ...] = get_args(FilterKind)
#: Cooperation modes.
COOPERATION: tuple[str, ...] = get_args(Cooperation)

Belief = GaussianState | ParticleState

_KERNELS: list[ModuleType | None] = []


def _potrf(a: FloatArray, lower: int = 1, clean: int = 1) -> tuple[FloatArray, int]:
    """LAPACK ``dpotrf`` (scipy, imported on first use: start-up stays on numpy alone)."""
    from scipy.linalg.lapack import dpotrf

    L, info = dpotrf(a, lower=lower, clean=clean)
    return L, int(info)


def _posv(a: FloatArray, b: FloatArray) -> tuple[FloatArray, FloatArray, int]:
    """LAPACK ``dposv`` (scipy, imported on first use)."""
    from scipy.linalg.lapack import dposv

    c, x, info = dposv(a, b)
    return c, x, int(info)


def coop_kernels() -> ModuleType | None:
    """The compiled UKF kernels (:mod:`robustrtk.estimation.coop_kernels`) when the kernel
    policy (:mod:`robustrtk.jit`) says so now, else None (numba absent: the numpy path
    serves); imported on the first call that wants them. A call answered None charges one
    step's pure cost to the policy."""
    if not kernel_policy.compiled():
        kernel_policy.charge(kernel_policy.COOP_STEP_US)
        return None
    if not _KERNELS:
        mod: ModuleType | None = None
        try:
            from robustrtk.estimation import coop_kernels as mod
        except ImportError:  # numba absent: the numpy path serves
            mod = None
        _KERNELS.append(mod)
    return _KERNELS[0]


# ---------------------------------------------------------------------- state and process
def node_layout(n_clocks: int = 1, velocity: bool = False) -> StateLayout:
    """``[pos(3), clk(n_clocks)]`` (+ ``vel(3)`` after the clocks when ``velocity``)."""
    blocks: tuple[tuple[str, int], ...] = (("pos", 3), ("clk", n_clocks))
    if velocity:
        blocks = blocks + (("vel", 3),)
    return StateLayout(blocks=blocks)


def clock_index(layout: StateLayout, systems: Sequence[str]) -> dict[str, int]:
    """State index of the clock of each system (in the order given)."""
    s = layout.slice("clk")
    if len(systems) > s.stop - s.start:
        raise ValueError(f"{len(systems)} systems but the layout has {s.stop - s.start} clocks")
    return {sys: s.start + k for k, sys in enumerate(systems)}


@dataclass(frozen=True)
class LocationTimeModel:
    """Location-time process model, Zhou et al. eq. 8::

        x_t = F x_t−1 + W w_t,   F = I,  W = Δt I,  w_t ~ N(0, Q̃),
        Q̃ = diag(σ_pos² I₃, σ_clk² I_c)   (m²/s²),   Q = W Q̃ Wᵀ = Δt² Q̃   (m²).

    With a ``vel`` block the position integrates it (``F[pos, vel] = Δt I``) and the
    velocity is driven by ``σ_acc`` (m/s²): ``Q̃_vel = σ_acc² I``, ``W_vel = Δt I``.

    Attributes
    ----------
    sigma_pos_m_s : float
        σ_ẋ = σ_ẏ = σ_ż, the position rate noise (m/s); small for a static node.
    sigma_clk_m_s : float
        σ_ḃ, the clock rate noise (m/s).
    sigma_acc_m_s2 : float
        Velocity noise (only with a ``vel`` block).
    """

    sigma_pos_m_s: float = 0.01
    sigma_clk_m_s: float = 100.0
    sigma_acc_m_s2: float = 1.0
    name: str = "location-time"

    def blocks(self) -> tuple[tuple[str, int], ...]:
        return (("pos", 3), ("clk", 1))

    def noise_input(self, layout: StateLayout, dt_s: float) -> tuple[FloatArray, FloatArray]:
        """``W`` (n, n) and ``Q̃`` (n, n, m²/s²) of eq. 8 for ``layout`` (read-only arrays,
        memoised per model, layout and interval)."""
        return _location_time(self, layout, float(dt_s))[2:]

    def transition(self, layout: StateLayout, dt_s: float) -> tuple[FloatArray, FloatArray]:
        """``F`` and ``Q = W Q̃ Wᵀ`` (m²) over ``dt_s`` (read-only, memoised)."""
        return _location_time(self, layout, float(dt_s))[:2]

    def _build(
        self, layout: StateLayout, dt_s: float
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        n = layout.size
        q = np.zeros(n)
        q[layout.slice("pos")] = self.sigma_pos_m_s**2
        q[layout.slice("clk")] = self.sigma_clk_m_s**2
        if layout.has("vel"):
            q[layout.slice("vel")] = self.sigma_acc_m_s2**2
        W = np.eye(n) * abs(dt_s)
        Qw = np.diag(q)
        F = np.eye(n)
        if layout.has("vel"):
            F[layout.slice("pos"), layout.slice("vel")] = np.eye(3) * dt_s
        out = (F, W @ Qw @ W.T, W, Qw)
        for a in out:
            a.setflags(write=False)
        return out


@functools.lru_cache(maxsize=256)
def _location_time(
    model: LocationTimeModel, layout: StateLayout, dt_s: float
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    return model._build(layout, dt_s)


def augmented_ukf_predict(
    state: GaussianState,
    process: ProcessModel,
    t_s: float,
    alpha: float = 1.0,
    beta: float = 2.0,
    jit: bool = True,
) -> GaussianState:
    """Time update of the augmented UKF, Zhou et al. eqs. 14–17.

    ``X_a = [x̂, E(w) = 0]``, ``P_a = blockdiag(P, Q̃)``, ``L = 2n``, sigma points of
    ``N(X_a, P_a)`` with ``λ = (α² − 1) L`` (κ = 0), each propagated as
    ``χ_x ← F χ_x + W χ_w``; mean and covariance by the weights of eq. 16. For the linear
    eq. 8 this equals ``F P Fᵀ + W Q̃ Wᵀ`` exactly (the test checks it).

    ``process`` gives ``W, Q̃`` through ``noise_input(layout, dt)`` when it has it
    (:class:`LocationTimeModel`); otherwise ``W = I``, ``Q̃ = Q``.

    The Cholesky factor of the block-diagonal ``P_a`` is ``blockdiag(chol P, chol Q̃)``
    (two 4×4 LAPACK ``potrf``, no 8×8 factorisation; algorithms.md §26), the weights are memoised per
    ``(L, α, β)``; the arithmetic is otherwise that of
    :func:`robustrtk.estimation.filters.sigma_points` (the test compares both to 1e-9).
    With ``jit`` (and numba present) the whole update is one compiled kernel,
    :func:`robustrtk.estimation.coop_kernels.ukf_predict`.
    """
    dt = t_s - state.t_s
    if type(process) is LocationTimeModel:  # F, Q, W, Q̃ by one memo look-up
        F, _, W, Qw = _location_time(process, state.layout, float(dt))
    else:
        F, Q = process.transition(state.layout, dt)
        noise = getattr(process, "noise_input", None)
        if callable(noise):
            W, Qw = noise(state.layout, dt)
        else:
            W, Qw = np.eye(state.n), Q
    x0 = state.x
    n = x0.shape[0]
    kern = coop_kernels() if jit else None
    if kern is not None:
        Wm, Wc, sqrt_c = _ukf_weights(2 * n, float(alpha), float(beta))
        x_out = np.empty(n)
        P_out = np.empty((n, n))
        if kern.ukf_predict(x0, state.P, F, W, Qw, Wm, Wc, sqrt_c, x_out, P_out) == 0:
            if type(state) is GaussianState:
                return GaussianState(x_out, P_out, t_s, state.layout)
            return replace(state, x=x_out, P=P_out, t_s=t_s)
    Lp, info_p = _potrf(state.P, lower=1, clean=1)
    Lq, info_q = _potrf(Qw, lower=1, clean=1)
    if info_p != 0 or info_q != 0:  # not positive definite: the jittered factor of sigma_points
        xa = np.concatenate([x0, np.zeros(n)])
        Pa = np.zeros((2 * n, 2 * n))
        Pa[:n, :n] = state.P
        Pa[n:, n:] = Qw
        X, Wm, Wc = sigma_points(xa, Pa, alpha, beta, 0.0)
        Xp = X[:, :n] @ F.T + X[:, n:] @ W.T
    else:
        Wm, Wc, sqrt_c = _ukf_weights(2 * n, float(alpha), float(beta))
        # rows of X_a: [x̂, 0], [x̂ + √c Lp_i, 0], [x̂, √c Lq_i], [x̂ − √c Lp_i, 0], [x̂, −√c Lq_i]
        Dp = sqrt_c * Lp.T
        Dq = sqrt_c * Lq.T
        Xx = np.empty((4 * n + 1, n))
        Xx[:] = x0
        Xx[1 : n + 1] += Dp
        Xx[2 * n + 1 : 3 * n + 1] -= Dp
        Xw = np.zeros((4 * n + 1, n))
        Xw[n + 1 : 2 * n + 1] = Dq
        Xw[3 * n + 1 :] = -Dq
        Xp = Xx @ F.T + Xw @ W.T
    x = Wm @ Xp
    d = Xp - x
    P = (d * Wc[:, None]).T @ d
    P = 0.5 * (P + P.T)
    if type(state) is GaussianState:
        return GaussianState(x, P, t_s, state.layout)
    return replace(state, x=x, P=P, t_s=t_s)


@functools.lru_cache(maxsize=64)
def _ukf_weights(n: int, alpha: float, beta: float) -> tuple[FloatArray, FloatArray, float]:
    """``Wm, Wc`` (2n+1,) of :func:`~robustrtk.estimation.filters.sigma_points` (κ = 0) and
    ``√(n + λ)``; read-only."""
    lam = alpha**2 * n - n
    c = n + lam
    Wm = np.full(2 * n + 1, 1.0 / (2 * c))
    Wc = Wm.copy()
    Wm[0] = lam / c
    Wc[0] = lam / c + (1 - alpha**2 + beta)
    Wm.setflags(write=False)
    Wc.setflags(write=False)
    return Wm, Wc, float(np.sqrt(c))


# ---------------------------------------------------------------------- least squares
@dataclass(frozen=True)
class LsqResult:
    """A Gauss–Newton solution: ``state`` (x, covariance ``(Hᵀ R⁻¹ H)⁻¹``), its post-fit
    residuals, and whether it converged with a non-singular normal matrix."""

    state: GaussianState
    residual: FloatArray
    ok: bool


def gauss_newton(
    meas: MeasurementModel,
    x0: FloatArray,
    *,
    cols: npt.ArrayLike | None = None,
    max_iter: int = 10,
    tol_m: float = 1e-4,
    t_s: float = 0.0,
    layout: StateLayout | None = None,
) -> LsqResult:
    """Weighted least squares ``min (z − h(x))ᵀ R⁻¹ (z − h(x))`` by Gauss–Newton from ``x0``.

    Parameters
    ----------
    meas : MeasurementModel
    x0 : ndarray, shape (n,)
        Start; components outside ``cols`` stay fixed at their start values.
    cols : array_like of int, optional
        Estimated components (default all). Needs ``len(z) ≥ len(cols)``.
    max_iter : int
    tol_m : float
        Stop when ``|Δx| < tol_m``.
    t_s : float
    layout : StateLayout, optional

    Returns
    -------
    LsqResult
        Components outside ``cols`` get a zero covariance row; ``ok`` False when the
        problem is under-determined, singular (condition > 1e12) or did not converge.
    """
    x = np.array(x0, float, copy=True)
    n = x.shape[0]
    c = np.arange(n) if cols is None else np.asarray(cols, dtype=np.int64)
    lay = layout if layout is not None else StateLayout(blocks=(("x", n),))
    z = np.asarray(meas.z, float)
    R = np.asarray(meas.R, float)
    P = np.full((n, n), np.nan)
    if z.shape[0] < c.size:
        return LsqResult(GaussianState(x, P, t_s, lay), z - meas.h(x), False)
    Li = np.linalg.inv(np.linalg.cholesky(R))
    ok = False
    for _ in range(max_iter):
        H = np.asarray(meas.jacobian(x), float)[:, c]
        v = z - meas.h(x)
        Hw, vw = Li @ H, Li @ v
        N = Hw.T @ Hw
        if not np.all(np.isfinite(N)) or np.linalg.cond(N) > 1e12:
            return LsqResult(GaussianState(x, P, t_s, lay), v, False)
        dx = np.linalg.solve(N, Hw.T @ vw)
        x[c] += dx
        if float(np.linalg.norm(dx)) < tol_m:
            ok = True
            break
    H = np.asarray(meas.jacobian(x), float)[:, c]
    Hw = Li @ H
    P = np.zeros((n, n))
    P[np.ix_(c, c)] = np.linalg.inv(Hw.T @ Hw)
    return LsqResult(GaussianState(x, P, t_s, lay), z - meas.h(x), ok)


# ---------------------------------------------------------------------- filters
@dataclass(frozen=True)
class NodeStep:
    """One correction of a node's filter.

    Attributes
    ----------
    belief : GaussianState or ParticleState
        The filter's posterior (what it carries to the next epoch).
    summary : GaussianState
        Its Gaussian summary (output and broadcast).
    innovation : ndarray, shape (m,)
        ``z − h(x̄)`` (EKF), ``z − ŷ`` (UKF, PF: over the prior cloud), ``z − h(x̂)`` (LS).
    labels : tuple of str
    ess : float
        Effective sample size after the correction (NaN except for the PF).
    resampled : bool
    ok : bool
        The correction was carried out (finite, non-singular).
    """

    belief: Belief
    summary: GaussianState
    innovation: FloatArray
    labels: tuple[str, ...]
    ess: float = float("nan")
    resampled: bool = False
    ok: bool = True


class NodeFilter(Protocol):
    """The interface every cooperative filter shares."""

    @property
    def name(self) -> str: ...

    def init(self, state: GaussianState) -> Belief:
        """The filter's belief started from the Gaussian ``state``."""
        ...

    def predict(self, belief: Belief, process: ProcessModel, t_s: float) -> Belief:
        """Time update to ``t_s``."""
        ...

    def update(self, belief: Belief, meas: MeasurementModel) -> NodeStep:
        """Correction with the stacked rows ``meas``."""
        ...

    def summary(self, belief: Belief) -> GaussianState:
        """Gaussian summary of ``belief``."""
        ...


def _gaussian(belief: Belief) -> GaussianState:
    if isinstance(belief, ParticleState):
        return belief.summary()
    return belief


_RowPart = PseudorangeModel | PeerRangeModel
#: ``ω_e / c`` of the Sagnac term of the pseudorange rows (1/m · m/s · s = rad/m).
_SAGNAC = OMEGA_E_RAD_S / CLIGHT


def _row_parts(meas: MeasurementModel) -> tuple[_RowPart, ...] | None:
    """The parts of ``meas`` when all are pseudorange / peer-range rows on one position
    block (what :func:`_sigma_rows` evaluates in a batch), else None."""
    parts: tuple[object, ...] = meas.parts if type(meas) is StackedModel else (meas,)
    out: list[_RowPart] = []
    for p in parts:
        if type(p) is not PseudorangeModel and type(p) is not PeerRangeModel:
            return None
        assert isinstance(p, PseudorangeModel | PeerRangeModel)
        if out and p.pos_start != out[0].pos_start:
            return None
        out.append(p)
    return tuple(out) if out else None


def _sigma_rows(parts: tuple[_RowPart, ...], X: FloatArray, m: int) -> FloatArray:
    """``h`` of every part for every sigma point ``X`` (k, n) → (k, m), in one batch.

    The geometric ranges to all anchors (satellites and peers, ``a_j``) come from one
    expansion about the first point ``c = X[0]`` (as in the pseudorange model):
    ``|a_j − p|² = |a_j'|² − 2 a_j'·p' + |p'|²``, ``a' = a − c``, ``p' = p − c``; the
    pseudorange rows then add the Sagnac term ``ω_e (s_x p_y − s_y p_x)/c`` and their clock.
    """
    s0 = parts[0].pos_start
    pos = X[:, s0 : s0 + 3]
    c = pos[0]
    if len(parts) == 1:
        p0 = parts[0]
        anchors = p0.sat_pos_m if type(p0) is PseudorangeModel else p0.peer_pos_m  # type: ignore[union-attr]
    else:
        anchors = np.concatenate(
            [p.sat_pos_m if type(p) is PseudorangeModel else p.peer_pos_m for p in parts]  # type: ignore[union-attr]
        )
    ap = anchors - c
    pp = pos - c
    r2 = np.einsum("ij,ij->i", ap, ap)[None, :] - 2.0 * (pp @ ap.T) + np.einsum("ij,ij->i", pp, pp)[:, None]
    Y: FloatArray = np.sqrt(np.maximum(r2, 0.0))
    i = 0
    for p in parts:
        k = p.z.shape[0]
        if type(p) is PseudorangeModel:
            s = p.sat_pos_m
            sag = (OMEGA_E_RAD_S / CLIGHT) * np.array([-s[:, 1], s[:, 0]])
            blk = Y[:, i : i + k]
            blk += pos[:, :2] @ sag
            blk += X[:, p.clk_index]
        i += k
    return Y


def _row_clocks(parts: tuple[_RowPart, ...]) -> npt.NDArray[np.int64]:
    """Clock index of every row (m,), −1 for a peer row (the kernel's row kind)."""
    out = [p.clk_index if type(p) is PseudorangeModel else _no_clock(p.z.shape[0]) for p in parts]
    return out[0] if len(out) == 1 else np.concatenate(out)


@functools.lru_cache(maxsize=64)
def _no_clock(k: int) -> npt.NDArray[np.int64]:
    a = np.full(k, -1, dtype=np.int64)
    a.setflags(write=False)
    return a


def _failed(g: GaussianState, labels: tuple[str, ...], m: int) -> NodeStep:
    """A refused correction: the prior kept, NaN innovations."""
    return NodeStep(g, g, np.full(m, np.nan), labels, ok=False)


@dataclass
class KalmanNode:
    """EKF (eqs. 12–13) or augmented UKF (eqs. 14–19) on :mod:`robustrtk.estimation.filters`.

    Parameters
    ----------
    kind : {"ekf", "ukf"}
    alpha, beta : float
        UKF spread and prior-knowledge parameters (``λ = (α² − 1) L``, κ = 0);
        ``1e-4 ≤ α ≤ 1``.
    jit : bool
        UKF: use the compiled kernels of :mod:`robustrtk.estimation.coop_kernels` when
        numba is available (same numbers as the numpy path to round-off).
    """

    kind: Literal["ekf", "ukf"] = "ekf"
    alpha: float = 1.0
    beta: float = 2.0
    jit: bool = True

    def __post_init__(self) -> None:
        if self.kind not in ("ekf", "ukf"):
            raise ValueError(f"kind: expected ekf or ukf, got {self.kind!r}")
        if not 1e-4 <= self.alpha <= 1.0:
            raise ValueError("alpha must be in [1e-4, 1]")

    @property
    def name(self) -> str:
        return self.kind

    def init(self, state: GaussianState) -> GaussianState:
        return state

    def predict(self, belief: Belief, process: ProcessModel, t_s: float) -> GaussianState:
        g = _gaussian(belief)
        if self.kind == "ukf":
            return augmented_ukf_predict(g, process, t_s, self.alpha, self.beta, self.jit)
        return EKF().predict(g, process, t_s)

    def update(self, belief: Belief, meas: MeasurementModel) -> NodeStep:
        """One correction, the arithmetic of :mod:`robustrtk.estimation.filters` without a
        robust policy (the test checks the two agree): EKF in Joseph form, UKF with the
        sigma points of ``(x̄, P̄)`` (eq. 19).

        The UKF step on pseudorange and peer-range rows (:class:`PseudorangeModel`,
        :class:`PeerRangeModel`, or a :class:`StackedModel` of them) evaluates every sigma
        point's rows in one batch (:func:`_sigma_rows`), factors ``P̄`` and solves with
        ``S`` (symmetric positive definite) by LAPACK ``potrf`` / ``posv``, and adds the
        diagonal ``R`` in place; other models go through ``meas.h``. A test compares it with
        the plain formulation to 1e-9.
        """
        g = _gaussian(belief)
        if self.kind == "ukf":
            return self._ukf_update(g, meas)
        labels = tuple(meas.labels)
        z = np.asarray(meas.z, float)
        if z.size == 0:
            return NodeStep(g, g, np.zeros(0), labels)
        R = np.asarray(meas.R, float)
        x, P = g.x, g.P
        fail = NodeStep(g, g, np.full(z.size, np.nan), labels, ok=False)
        try:  # non-finite inputs give a non-finite posterior, refused below
            H = np.asarray(meas.jacobian(x), float)
            y = np.asarray(meas.h(x), float)
            PHt = P @ H.T
            S = H @ PHt + R
            K = np.linalg.solve(S, PHt.T).T
            IKH = np.eye(x.shape[0]) - K @ H
            P_new = IKH @ P @ IKH.T + K @ R @ K.T
        except np.linalg.LinAlgError:
            return fail
        d = z - y
        x_new = x + K @ d
        if not (np.isfinite(x_new).all() and np.isfinite(P_new).all()):
            return fail
        post = replace(g, x=x_new, P=symmetrize(P_new))
        return NodeStep(post, post, d, labels)

    def _ukf_update(self, g: GaussianState, meas: MeasurementModel) -> NodeStep:
        rows = _row_parts(meas)
        labels = tuple(meas.labels)
        if rows is None:
            z = np.asarray(meas.z, float)
            var = None
        else:
            z = np.concatenate([p.z for p in rows]) if len(rows) > 1 else np.asarray(rows[0].z, float)
            var = np.concatenate([p.var_m2 for p in rows]) if len(rows) > 1 else rows[0].var_m2
        m = z.shape[0]
        if m == 0:
            return NodeStep(g, g, np.zeros(0), labels)
        x, P = g.x, g.P
        n = x.shape[0]
        Wm, Wc, sqrt_c = _ukf_weights(n, float(self.alpha), float(self.beta))
        kern = coop_kernels() if self.jit and rows is not None else None
        if kern is not None and rows is not None and var is not None:
            if len(rows) == 1:
                p0 = rows[0]
                anchors = p0.sat_pos_m if type(p0) is PseudorangeModel else p0.peer_pos_m  # type: ignore[union-attr]
            else:
                anchors = np.concatenate(
                    [p.sat_pos_m if type(p) is PseudorangeModel else p.peer_pos_m for p in rows]  # type: ignore[union-attr]
                )
            x_new = np.empty(n)
            P_new = np.empty((n, n))
            d = np.empty(m)
            code = kern.ukf_update(
                x,
                P,
                anchors,
                _row_clocks(rows),
                _SAGNAC,
                z,
                var,
                rows[0].pos_start,
                Wm,
                Wc,
                sqrt_c,
                x_new,
                P_new,
                d,
            )
            if code == kern.NONFINITE:
                return _failed(g, labels, m)
            if code == kern.OK:
                if type(g) is GaussianState:
                    post = GaussianState(x_new, P_new, g.t_s, g.layout)
                else:
                    post = replace(g, x=x_new, P=P_new)
                return NodeStep(post, post, d, labels)
        L, info = _potrf(P, lower=1, clean=1)
        try:  # non-finite inputs give a non-finite posterior, refused below
            if info != 0:
                X, Wm, Wc = sigma_points(x, P, self.alpha, self.beta, 0.0)
            else:
                D = sqrt_c * L.T
                X = np.empty((2 * n + 1, n))
                X[:] = x
                X[1 : n + 1] += D
                X[n + 1 :] -= D
            if rows is None:
                Y = np.asarray(meas.h(X), float)
                R = np.asarray(meas.R, float)
            else:
                Y = _sigma_rows(rows, X, m)
            y = Wm @ Y
            dY = Y - y
            dYw = dY * Wc[:, None]
            S = dYw.T @ dY
            if var is None:
                S = S + R
            else:
                S.flat[:: m + 1] += var
            Pxy = ((X - x) * Wc[:, None]).T @ dY
            _, Kt, info = _posv(S, Pxy.T)
            if info != 0:  # not positive definite: a general solve (raises when singular)
                Kt = np.linalg.solve(S, Pxy.T)
            K = Kt.T
            P_new = P - K @ S @ Kt
        except np.linalg.LinAlgError:
            return _failed(g, labels, m)
        d = z - y
        x_new = x + K @ d
        if not (np.isfinite(x_new).all() and np.isfinite(P_new).all()):
            return _failed(g, labels, m)
        P_new = 0.5 * (P_new + P_new.T)
        post = (
            GaussianState(x_new, P_new, g.t_s, g.layout)
            if type(g) is GaussianState
            else replace(g, x=x_new, P=P_new)
        )
        return NodeStep(post, post, d, labels)

    def summary(self, belief: Belief) -> GaussianState:
        return _gaussian(belief)


@dataclass
class ParticleNode:
    """The particle filter of :mod:`robustrtk.estimation.particle` behind :class:`NodeFilter`.

    Parameters are those of :class:`~robustrtk.estimation.particle.ParticleFilter`
    (``linear_idx``: the clock indices, drawn through the optimal linear proposal).
    """

    n_particles: int = 2000
    ess_threshold: float = 0.5
    roughening: float = 0.2
    seed: int = 0
    linear_idx: tuple[int, ...] = ()
    pf: ParticleFilter = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self.pf = ParticleFilter(
            n_particles=self.n_particles,
            ess_threshold=self.ess_threshold,
            roughening=self.roughening,
            seed=self.seed,
            linear_idx=self.linear_idx,
        )

    @property
    def name(self) -> str:
        return "pf"

    def init(self, state: GaussianState) -> ParticleState:
        return self.pf.init(state)

    def predict(self, belief: Belief, process: ProcessModel, t_s: float) -> ParticleState:
        cloud = belief if isinstance(belief, ParticleState) else self.pf.init(belief)
        return self.pf.predict(cloud, process, t_s)

    def update(self, belief: Belief, meas: MeasurementModel) -> NodeStep:
        cloud = belief if isinstance(belief, ParticleState) else self.pf.init(belief)
        if len(meas.labels) == 0:
            return NodeStep(cloud, cloud.summary(), np.zeros(0), (), cloud.ess, False)
        try:
            up = self.pf.update(cloud, meas)
        except (np.linalg.LinAlgError, ValueError):
            return NodeStep(
                cloud, cloud.summary(), np.full(len(meas.labels), np.nan), tuple(meas.labels), ok=False
            )
        return NodeStep(up.state, up.state.summary(), up.innovation, tuple(meas.labels), up.ess, up.resampled)

    def summary(self, belief: Belief) -> GaussianState:
        return _gaussian(belief)


@dataclass
class LeastSquaresNode:
    """Per-epoch weighted least squares (the paper's baseline): the prior only supplies the
    start of :func:`gauss_newton`; the estimated components are those some row depends on.
    """

    max_iter: int = 10

    @property
    def name(self) -> str:
        return "ls"

    def init(self, state: GaussianState) -> GaussianState:
        return state

    def predict(self, belief: Belief, process: ProcessModel, t_s: float) -> GaussianState:
        return replace(_gaussian(belief), t_s=t_s)

    def update(self, belief: Belief, meas: MeasurementModel) -> NodeStep:
        g = _gaussian(belief)
        if len(meas.labels) == 0:
            return NodeStep(g, g, np.zeros(0), (), ok=False)
        H = np.asarray(meas.jacobian(g.x), float)
        cols = np.flatnonzero(np.any(H != 0.0, axis=0))
        res = gauss_newton(meas, g.x, cols=cols, max_iter=self.max_iter, t_s=g.t_s, layout=g.layout)
        if not res.ok:
            return NodeStep(g, g, res.residual, tuple(meas.labels), ok=False)
        return NodeStep(res.state, res.state, res.residual, tuple(meas.labels))

    def summary(self, belief: Belief) -> GaussianState:
        return _gaussian(belief)


def make_node_filter(kind: str, **params: object) -> NodeFilter:
    """``ekf`` / ``ukf`` (:class:`KalmanNode`: alpha, beta), ``pf`` (:class:`ParticleNode`:
    n_particles, ess_threshold, roughening, seed, linear_idx) or ``ls``
    (:class:`LeastSquaresNode`: max_iter).

    Raises
    ------
    ValueError
        Unknown kind.
    """
    if kind in ("ekf", "ukf"):
        return KalmanNode(kind, **params)  # type: ignore[arg-type]
    if kind == "pf":
        return ParticleNode(**params)  # type: ignore[arg-type]
    if kind == "ls":
        return LeastSquaresNode(**params)  # type: ignore[arg-type]
    raise ValueError(f"unknown cooperative filter {kind!r}; expected one of {', '.join(FILTER_KINDS)}")


# ---------------------------------------------------------------------- cooperation
@dataclass(frozen=True)
class PeerBroadcast:
    """What a node broadcasts each epoch: its position and clock and their covariance.

    Attributes
    ----------
    node : str
    t_s : float
    x : ndarray, shape (4,)
        ``[x, y, z, b]`` (ECEF m; the first clock, m).
    P : ndarray, shape (4, 4)
        Covariance of ``x`` (m²).
    """

    node: str
    t_s: float
    x: FloatArray
    P: FloatArray

    @property
    def pos_ecef_m(self) -> FloatArray:
        return self.x[:3]

    @classmethod
    def of(cls, node: str, state: GaussianState) -> PeerBroadcast:
        """The ``[pos, first clock]`` block of a node's Gaussian summary."""
        idx = np.r_[state.layout.slice("pos"), state.layout.slice("clk").start]
        return cls(node, state.t_s, state.x[idx].copy(), state.P[np.ix_(idx, idx)].copy())


@dataclass(frozen=True)
class ResetSettings:
    """Covariance reset of the improved algorithm (eqs. 29–30).

    Attributes
    ----------
    sigma_set_m : float or None
        σ_set (m); None: the short-window estimate of :class:`PeerWindow`.
    sigma_wset_m_s : float or None
        σ_wset (m/s) of the UKF's process-noise block; None: short-window estimate.
    window : int
        Broadcasts in the short window (≥ 2).
    sigma_set_floor_m, sigma_wset_floor_m_s : float
        Floors of the window estimates (a window of identical broadcasts gives 0).
    """

    sigma_set_m: float | None = None
    sigma_wset_m_s: float | None = None
    window: int = 10
    sigma_set_floor_m: float = 0.5
    sigma_wset_floor_m_s: float = 0.01

    def __post_init__(self) -> None:
        if self.window < 2:
            raise ValueError("window must be at least 2")


class PeerWindow:
    """The last ``window`` broadcasts of one peer and the short-window σ_set, σ_wset.

    ``σ_set² = max(floor², mean_j var_j(p̂))`` — the sample variance (ddof 1) of each
    broadcast coordinate over the window, averaged over x, y, z; ``σ_wset² =
    max(floor², mean_j var_j(Δp̂ / Δt))`` of the coordinate rates between successive
    broadcasts (m²/s²). Fewer than two broadcasts (three for the rate) give the floors.
    """

    def __init__(self, settings: ResetSettings | None = None):
        self.settings = settings or ResetSettings()
        self._hist: deque[PeerBroadcast] = deque(maxlen=self.settings.window)

    def push(self, b: PeerBroadcast) -> None:
        """Add a broadcast (finite positions only)."""
        if np.all(np.isfinite(b.x[:3])):
            self._hist.append(b)

    def sigma_set2_m2(self) -> float:
        s = self.settings
        if s.sigma_set_m is not None:
            return float(s.sigma_set_m**2)
        floor = s.sigma_set_floor_m**2
        if len(self._hist) < 2:
            return floor
        p = np.array([b.x[:3] for b in self._hist])
        return float(max(floor, np.mean(np.var(p, axis=0, ddof=1))))

    def sigma_wset2_m2_s2(self) -> float:
        s = self.settings
        if s.sigma_wset_m_s is not None:
            return float(s.sigma_wset_m_s**2)
        floor = s.sigma_wset_floor_m_s**2
        if len(self._hist) < 3:
            return floor
        p = np.array([b.x[:3] for b in self._hist])
        t = np.array([b.t_s for b in self._hist])
        dt = np.diff(t)
        good = dt > 0
        if good.sum() < 2:
            return floor
        rate = np.diff(p, axis=0)[good] / dt[good, None]
        return float(max(floor, np.mean(np.var(rate, axis=0, ddof=1))))


def reset_covariance(
    sigma_set2_m2: float, kind: str, sigma_wset2_m2_s2: float = 0.0, n_state: int = 4, n_noise: int = 4
) -> FloatArray:
    """The reset peer covariance: eq. 29 ``σ_set² I₄`` (EKF, PF, LS) or, for the UKF,
    eq. 30 ``blockdiag(σ_set² I₄, σ_wset² I_n)`` (the augmented state's noise block)."""
    if kind == "ukf":
        return np.diag(np.r_[np.full(n_state, sigma_set2_m2), np.full(n_noise, sigma_wset2_m2_s2)])
    return np.eye(n_state) * sigma_set2_m2


def range_variance(
    sigma_range2_m2: float,
    broadcast: PeerBroadcast,
    cooperation: str,
    kind: str,
    window: PeerWindow | None = None,
    dt_s: float = 1.0,
) -> float:
    """Variance σ̂² of one range row to ``broadcast.node`` (m²).

    * ``traditional``: ``σ²`` (no inflation, no reset);
    * ``improved``: eq. 24 ``σ̂² = σ² + tr(P̃_n)`` with the reset covariance ``P̃_n`` of
      :func:`reset_covariance` — ``tr = 4 σ_set²`` (eq. 29) or, for the UKF (eq. 30),
      ``4 σ_set² + 4 σ_wset² Δt²`` (the noise block mapped to metres by ``W = Δt I`` of
      eq. 8, so the trace adds like units).

    ``off`` has no range rows (``ValueError``).
    """
    if cooperation == "traditional":
        return float(sigma_range2_m2)
    if cooperation != "improved":
        raise ValueError(f"cooperation {cooperation!r} has no range rows")
    win = window if window is not None else PeerWindow()
    s2 = win.sigma_set2_m2()
    w2 = win.sigma_wset2_m2_s2() * dt_s**2 if kind == "ukf" else 0.0
    Pn = reset_covariance(s2, kind, w2)
    return float(sigma_range2_m2 + np.trace(Pn))


@dataclass(frozen=True)
class RangeObservation:
    """A measured range from this node to ``peer`` (m) and its variance (m²)."""

    peer: str
    range_m: float
    var_m2: float


def peer_range_model(
    observations: Sequence[RangeObservation],
    broadcasts: dict[str, PeerBroadcast],
    cooperation: str,
    kind: str,
    windows: dict[str, PeerWindow] | None = None,
    *,
    pos_start: int = 0,
    n_state: int = 4,
    dt_s: float = 1.0,
) -> PeerRangeModel:
    """The range rows (eq. 11) to the peers that broadcast, variances by :func:`range_variance`.

    Observations of peers without a finite broadcast are skipped; ``off`` gives no rows.
    """
    rows = [
        o
        for o in observations
        if cooperation != "off"
        and o.peer in broadcasts
        and np.all(np.isfinite(broadcasts[o.peer].pos_ecef_m))
        and np.isfinite(o.range_m)
        and np.isfinite(o.var_m2)
    ]
    win = windows or {}
    var = [
        range_variance(o.var_m2, broadcasts[o.peer], cooperation, kind, win.get(o.peer), dt_s) for o in rows
    ]
    return PeerRangeModel(
        z=np.array([o.range_m for o in rows], float),
        peer_pos_m=np.array([broadcasts[o.peer].pos_ecef_m for o in rows], float).reshape(-1, 3),
        var_m2=np.array(var, float),
        pos_start=pos_start,
        n_state=n_state,
        labels=tuple(f"range:{o.peer}" for o in rows),
    )


__all__ = [
    "COOPERATION",
    "FILTER_KINDS",
    "Belief",
    "Cooperation",
    "FilterKind",
    "KalmanNode",
    "LeastSquaresNode",
    "LocationTimeModel",
    "LsqResult",
    "NodeFilter",
    "NodeStep",
    "ParticleNode",
    "PeerBroadcast",
    "PeerWindow",
    "RangeObservation",
    "ResetSettings",
    "augmented_ukf_predict",
    "clock_index",
    "gauss_newton",
    "make_node_filter",
    "node_layout",
    "peer_range_model",
    "range_variance",
    "reset_covariance",
]
