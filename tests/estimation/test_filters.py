"""EKF/UKF: the UKF equals the linear Kalman filter on a linear model; sigma points
reproduce mean and covariance; covariance stays symmetric positive definite."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk.estimation.filters import EKF, UKF, inflate, sigma_points
from robustrtk.estimation.models import (
    ConstantVelocityModel,
    LinearMeasurement,
    RandomWalkModel,
    StaticModel,
    predict,
)
from robustrtk.estimation.state import GaussianState, StateLayout


def _spd(rng: np.random.Generator, n: int, scale: float = 1.0) -> np.ndarray:
    A = rng.normal(size=(n, n))
    return scale * (A @ A.T + n * np.eye(n) * 0.1)


def _kf_update(x, P, H, z, R):
    S = H @ P @ H.T + R
    K = P @ H.T @ np.linalg.inv(S)
    return x + K @ (z - H @ x), (np.eye(len(x)) - K @ H) @ P


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(1, 6),
    m=st.integers(1, 5),
    alpha=st.sampled_from([0.5, 1.0, 1.5]),
    kappa=st.sampled_from([0.0, 1.0, 3.0]),
)
def test_ukf_equals_kf_on_linear_model(seed, n, m, alpha, kappa):
    rng = np.random.default_rng(seed)
    x = rng.normal(size=n)
    P = _spd(rng, n)
    H = rng.normal(size=(m, n))
    R = _spd(rng, m, 0.5)
    z = rng.normal(size=m)
    layout = StateLayout(blocks=(("pos", n),))
    st0 = GaussianState(x, P, 0.0, layout)
    meas = LinearMeasurement(H, z, R)
    x_kf, P_kf = _kf_update(x, P, H, z, R)
    for f in (UKF(alpha=alpha, beta=2.0, kappa=kappa), EKF()):
        res = f.update(st0, meas)
        np.testing.assert_allclose(res.state.x, x_kf, rtol=1e-7, atol=1e-8)
        np.testing.assert_allclose(res.state.P, P_kf, rtol=1e-6, atol=1e-8)
        # posterior residual covariance of a KF update: Cvv = R S^-1 R
        S = H @ P @ H.T + R
        np.testing.assert_allclose(res.residual_cov, R @ np.linalg.solve(S, R), rtol=1e-6, atol=1e-8)
        np.testing.assert_allclose(res.innovation, z - H @ x, rtol=1e-9, atol=1e-9)


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(1, 8),
    alpha=st.sampled_from([0.1, 0.5, 1.0]),
    beta=st.sampled_from([0.0, 2.0]),
    kappa=st.sampled_from([0.0, 1.0]),
)
def test_sigma_points_reproduce_mean_and_covariance(seed, n, alpha, beta, kappa):
    rng = np.random.default_rng(seed)
    x = rng.normal(size=n)
    P = _spd(rng, n)
    X, Wm, Wc = sigma_points(x, P, alpha, beta, kappa)
    assert X.shape == (2 * n + 1, n)
    np.testing.assert_allclose(Wm.sum(), 1.0, atol=1e-9)
    mean = Wm @ X
    np.testing.assert_allclose(mean, x, atol=1e-8 * (1 + abs(Wm[0])))
    d = X - x
    # the zeroth point sits on the mean, so Wc[0] does not enter the covariance
    cov = (d * Wc[:, None]).T @ d
    np.testing.assert_allclose(cov, P, rtol=1e-8, atol=1e-8)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), m=st.integers(2, 6))
def test_inflation_keeps_correlation_coefficients(seed, m):
    rng = np.random.default_rng(seed)
    R = _spd(rng, m)
    g = rng.uniform(1, 50, size=m)
    Rb = inflate(R, g)
    corr = R / np.sqrt(np.outer(np.diag(R), np.diag(R)))
    corr_b = Rb / np.sqrt(np.outer(np.diag(Rb), np.diag(Rb)))
    np.testing.assert_allclose(corr_b, corr, atol=1e-12)
    np.testing.assert_allclose(np.diag(Rb), g * np.diag(R))


def test_process_models():
    layout = StateLayout(blocks=(("pos", 3), ("vel", 3)), amb_keys=("a",))
    s = GaussianState(np.r_[1, 2, 3, 0.5, 0, 0, 7.0], np.eye(7), 0.0, layout)
    out = predict(s, ConstantVelocityModel(sigma_m_s2=0.1), 2.0)
    np.testing.assert_allclose(out.x, [2.0, 2, 3, 0.5, 0, 0, 7.0])
    assert out.t_s == 2.0
    # P grows by F P F^T + Q; the ambiguity stays constant without its own noise
    assert np.isclose(out.P[0, 0], 1 + 4 + 0.01 * 8 / 3)
    assert out.P[6, 6] == 1.0
    lay3 = StateLayout()
    s3 = GaussianState(np.zeros(3), np.eye(3), 0.0, lay3)
    assert np.isclose(predict(s3, RandomWalkModel(sigma_m_s=0.2), 4.0).P[0, 0], 1 + 0.04 * 4)
    assert np.isclose(predict(s3, StaticModel(q_m2_s=1e-6), 1.0).P[1, 1], 1 + 1e-6)


def test_state_add_drop_ambiguities():
    s = GaussianState(np.zeros(3), np.eye(3) * 2, 0.0, StateLayout())
    s2 = s.add_ambiguities(["A", "B"], np.array([1.0, 2.0]), 9.0)
    assert s2.n == 5 and s2.layout.amb_keys == ("A", "B")
    assert s2.x[s2.layout.amb_index("B")] == 2.0
    s3 = s2.drop_ambiguities(["A"])
    assert s3.layout.amb_keys == ("B",) and s3.n == 4
    assert s3.x[3] == 2.0 and s3.P[3, 3] == 9.0 and s3.P[0, 0] == 2.0


def test_constant_velocity_transition_repeated_is_the_same_and_independent():
    """The same layout object over the same step gives the matrices built afresh (for an
    equal layout object never seen before), as new arrays (a caller may modify them, e.g.
    a code-bias model's rows); another layout, step or model is not served the
    remembered ones."""
    model = ConstantVelocityModel(sigma_m_s2=0.3, q_amb_cyc2_s=1e-4, sigma_up_m_s2=0.7)

    def layout(*keys: str) -> StateLayout:  # a new object each time
        return StateLayout(blocks=(("pos", 3), ("vel", 3)), amb_keys=tuple(keys))

    lay = layout("a", "b")
    F0, Q0 = model.transition(layout("a", "b"), 1.0)
    F1, Q1 = model.transition(lay, 1.0)
    F1[0, 0], Q1[0, 0] = 99.0, 99.0  # the caller's own copies
    for _ in range(2):
        F2, Q2 = model.transition(lay, 1.0)
        assert F2.tobytes() == F0.tobytes() and Q2.tobytes() == Q0.tobytes()
        assert F2 is not F1 and F2.flags.writeable
    assert model.transition(layout("a"), 1.0)[0].shape == (7, 7)
    assert model.transition(lay, 2.0)[0].tobytes() == model.transition(layout("a", "b"), 2.0)[0].tobytes()
    assert model.transition(lay, 2.0)[0].tobytes() != F0.tobytes()
    wider = ConstantVelocityModel(sigma_m_s2=0.6, q_amb_cyc2_s=1e-4, sigma_up_m_s2=0.7)
    assert wider.transition(lay, 1.0)[1].tobytes() == wider.transition(layout("a", "b"), 1.0)[1].tobytes()
    assert not np.array_equal(wider.transition(lay, 1.0)[1], Q0)
    # a zero step is built afresh (its signed zeros follow the step's sign)
    assert np.signbit(model.transition(lay, -0.0)[0][0, 3])
    assert not np.signbit(model.transition(lay, 0.0)[0][0, 3])


def test_constant_velocity_with_array_parameters_still_transitions():
    model = ConstantVelocityModel(sigma_m_s2=0.3, sigma_up_m_s2=0.7, up=np.array([0.0, 0.6, 0.8]))  # type: ignore[arg-type]
    lay = StateLayout(blocks=(("pos", 3), ("vel", 3)))
    F, Q = model.transition(lay, 1.0)
    ref = ConstantVelocityModel(sigma_m_s2=0.3, sigma_up_m_s2=0.7, up=(0.0, 0.6, 0.8))
    assert F.tobytes() == ref.transition(lay, 1.0)[0].tobytes()
    assert Q.tobytes() == ref.transition(lay, 1.0)[1].tobytes()
