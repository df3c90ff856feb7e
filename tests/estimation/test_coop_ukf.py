"""The cooperative UKF node (:class:`robustrtk.estimation.coop.KalmanNode`, which runs
:class:`robustrtk.estimation.filters.UKF`) against Zhou et al.'s formulation written out here as
the oracle: the augmented time update (eqs. 14–17: one 2n×2n Cholesky of ``blockdiag(P, Q̃)``,
each sigma point propagated as ``F χ_x + W χ_w``) and the correction (eqs. 18–19: every row
model's ``h`` on the sigma points, ``R`` dense, a general solve).
Random problems, 1e-9 relative to the scale each result is computed from:
``|x|`` for the state, the prior covariance for the posterior one (``P⁺ = P − K S Kᵀ`` is a
difference of terms of that size), ``|z|`` for the innovation (``z − ŷ`` with ``ŷ`` ≈ 2·10⁷ m,
whose last bit is 4·10⁻⁹ m). α ≥ 0.5: with a tiny α the sigma points sit within round-off of
the ECEF mean and any two implementations differ by the reference's own cancellation."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk.estimation.coop import KalmanNode, LocationTimeModel, node_layout
from robustrtk.estimation.models import LinearMeasurement
from robustrtk.estimation.state import GaussianState
from robustrtk.measurement.coop import PeerRangeModel, PseudorangeModel
from robustrtk.measurement.dd import StackedModel

RX = np.array([-3976219.19, 3382371.61, 3652511.14])
TOL = 1e-9


def _ref_sigma_points(x, P, alpha, beta):
    n = x.shape[0]
    lam = alpha**2 * n - n
    c = n + lam
    L = np.linalg.cholesky(P)
    D = np.sqrt(c) * L
    X = np.vstack([x, x + D.T, x - D.T])
    Wm = np.full(2 * n + 1, 1.0 / (2 * c))
    Wc = Wm.copy()
    Wm[0] = lam / c
    Wc[0] = lam / c + (1 - alpha**2 + beta)
    return X, Wm, Wc


def _ref_predict(state, process, t_s, alpha, beta):
    dt = t_s - state.t_s
    F, _ = process.transition(state.layout, dt)
    W, Qw = process.noise_input(state.layout, dt)
    n = state.n
    xa = np.concatenate([state.x, np.zeros(n)])
    Pa = np.zeros((2 * n, 2 * n))
    Pa[:n, :n] = state.P
    Pa[n:, n:] = Qw
    X, Wm, Wc = _ref_sigma_points(xa, Pa, alpha, beta)
    Xp = X[:, :n] @ F.T + X[:, n:] @ W.T
    x = Wm @ Xp
    d = Xp - x
    P = (d * Wc[:, None]).T @ d
    return x, 0.5 * (P + P.T)


def _ref_update(x, P, meas, alpha, beta):
    X, Wm, Wc = _ref_sigma_points(x, P, alpha, beta)
    Y = np.asarray(meas.h(X), float)
    y = Wm @ Y
    dY = Y - y
    S = (dY * Wc[:, None]).T @ dY + np.asarray(meas.R, float)
    Pxy = ((X - x) * Wc[:, None]).T @ dY
    K = np.linalg.solve(S, Pxy.T).T
    P_new = P - K @ S @ K.T
    d = np.asarray(meas.z, float) - y
    return x + K @ d, 0.5 * (P_new + P_new.T), d


def _close(a, b, scale=None):
    s = np.max(np.abs(b)) if scale is None else scale
    assert np.max(np.abs(np.asarray(a) - b)) <= TOL * max(s, 1e-300)


def _problem(rng: np.random.Generator, n_clocks: int, n_sat: int, n_peer: int):
    lay = node_layout(n_clocks)
    n = lay.size
    x = np.r_[RX + rng.normal(0, 30.0, 3), rng.normal(0, 1e4, n_clocks)]
    A = rng.normal(size=(n, n)) * np.r_[np.full(3, rng.uniform(0.1, 20.0)), np.full(n_clocks, 100.0)]
    P = A @ A.T + np.eye(n) * rng.uniform(1e-3, 1.0)
    up = RX / np.linalg.norm(RX)
    sats = []
    while len(sats) < n_sat:
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        if d @ up > 0.1:
            sats.append(RX + 2.2e7 * d)
    s = np.array(sats).reshape(-1, 3)
    clk = rng.integers(3, 3 + n_clocks, n_sat)
    truth = x + rng.multivariate_normal(np.zeros(n), P)
    pr0 = PseudorangeModel(np.zeros(n_sat), s, np.ones(n_sat), clk, 0, n)
    pr = PseudorangeModel(
        pr0.h(truth) + rng.normal(0, 3.0, n_sat), s, rng.uniform(1.0, 50.0, n_sat), clk, 0, n
    )
    peers = RX + rng.normal(0, 1000.0, (n_peer, 3))
    rm0 = PeerRangeModel(np.zeros(n_peer), peers, np.ones(n_peer), 0, n)
    rm = PeerRangeModel(
        rm0.h(truth) + rng.normal(0, 0.1, n_peer), peers, rng.uniform(0.01, 5.0, n_peer), 0, n
    )
    parts = tuple(p for p, k in ((pr, n_sat), (rm, n_peer)) if k > 0)
    return GaussianState(x, P, 0.0, lay), parts


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n_clocks=st.integers(1, 3),
    n_sat=st.integers(0, 9),
    n_peer=st.integers(0, 3),
    alpha=st.sampled_from([1.0, 0.7, 0.5]),
    stacked=st.booleans(),
)
def test_ukf_update_matches_reference(seed, n_clocks, n_sat, n_peer, alpha, stacked):
    if n_sat + n_peer == 0:
        n_sat = 1
    rng = np.random.default_rng(seed)
    g, parts = _problem(rng, n_clocks, n_sat, n_peer)
    meas = StackedModel(parts) if stacked or len(parts) > 1 else parts[0]
    step = KalmanNode("ukf", alpha=alpha).update(g, meas)
    x_ref, P_ref, d_ref = _ref_update(g.x, g.P, meas, alpha, 2.0)
    assert step.ok
    _close(step.belief.x, x_ref)
    _close(
        step.belief.x - g.x, x_ref - g.x, scale=np.max(np.abs(x_ref - g.x)) + np.sqrt(np.max(np.diag(g.P)))
    )
    _close(step.belief.P, P_ref, scale=np.max(np.abs(g.P)))
    _close(step.innovation, d_ref, scale=np.max(np.abs(meas.z)))
    assert step.labels == tuple(meas.labels)


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n_clocks=st.integers(1, 3),
    dt=st.floats(0.1, 30.0),
    alpha=st.sampled_from([1.0, 0.7, 0.5]),
)
def test_augmented_predict_matches_reference(seed, n_clocks, dt, alpha):
    """The shared linear time update ``F P Fᵀ + W Q̃ Wᵀ`` is the augmented UKF's (eq. 8 is
    linear), whatever α."""
    rng = np.random.default_rng(seed)
    g, _ = _problem(rng, n_clocks, 1, 0)
    proc = LocationTimeModel(sigma_pos_m_s=rng.uniform(0.001, 5.0), sigma_clk_m_s=rng.uniform(0.1, 300.0))
    out = KalmanNode("ukf", alpha=alpha).predict(g, proc, dt)
    x_ref, P_ref = _ref_predict(g, proc, dt, alpha, 2.0)
    _close(out.x, x_ref)
    _close(out.P, P_ref)
    assert out.t_s == dt and out.layout == g.layout


def test_other_models_update_alike():
    """Any measurement model (here linear) is corrected by the same update."""
    rng = np.random.default_rng(3)
    g, _ = _problem(rng, 1, 1, 0)
    H = rng.normal(size=(5, 4))
    meas = LinearMeasurement(H, H @ g.x + rng.normal(0, 1.0, 5), np.diag(rng.uniform(1.0, 4.0, 5)))
    step = KalmanNode("ukf").update(g, meas)
    x_ref, P_ref, d_ref = _ref_update(g.x, g.P, meas, 1.0, 2.0)
    _close(step.belief.x, x_ref)
    _close(step.belief.P, P_ref, scale=np.max(np.abs(g.P)))
    _close(step.innovation, d_ref, scale=np.max(np.abs(meas.z)))


def test_nonfinite_prior_is_refused():
    rng = np.random.default_rng(4)
    g, parts = _problem(rng, 1, 6, 1)
    bad = GaussianState(g.x, g.P * np.nan, g.t_s, g.layout)
    step = KalmanNode("ukf").update(bad, StackedModel(parts))
    assert not step.ok and step.belief is bad
    assert np.isnan(step.innovation).all()


@pytest.mark.parametrize("alpha", [1.0, 0.5])
def test_filter_run_matches_reference_over_epochs(alpha):
    """Fifty predict + update epochs: the node stays on the augmented reference's track."""
    rng = np.random.default_rng(5)
    g, _ = _problem(rng, 1, 7, 1)
    proc = LocationTimeModel()
    f = KalmanNode("ukf", alpha=alpha)
    x_ref, P_ref = g.x.copy(), g.P.copy()
    b = g
    scale = 0.0
    for k in range(50):
        _, parts = _problem(rng, 1, 7, 1)
        meas = StackedModel(parts)
        b = f.predict(b, proc, float(k + 1))
        x_ref, P_ref = _ref_predict(
            GaussianState(x_ref, P_ref, float(k), g.layout), proc, float(k + 1), alpha, 2.0
        )
        scale = float(np.max(np.abs(P_ref)))
        b = f.update(b, meas).belief
        x_ref, P_ref, _ = _ref_update(x_ref, P_ref, meas, alpha, 2.0)
    _close(b.x, x_ref)
    _close(b.P, P_ref, scale=scale)
