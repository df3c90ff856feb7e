"""The IMM (estimation/imm.py, algorithms.md §32): invariants and mode probabilities."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk.estimation.filters import EKF
from robustrtk.estimation.imm import (
    ImmModels,
    ImmTracker,
    make_imm_models,
    moment_match,
    posterior_probabilities,
    transition_matrix,
)
from robustrtk.estimation.models import ConstantVelocityModel, LinearMeasurement
from robustrtk.estimation.state import GaussianState, StateLayout

LAYOUT = StateLayout(blocks=(("pos", 3), ("vel", 3)))
H_POS = np.hstack([np.eye(3), np.zeros((3, 3))])


def _state(t: float = 0.0) -> GaussianState:
    P = np.diag([1.0, 1.0, 1.0, 0.5, 0.5, 0.5])
    return GaussianState(x=np.array([1.0, 2.0, 3.0, 0.5, -0.2, 0.0]), P=P, t_s=t, layout=LAYOUT)


def _meas(z: np.ndarray) -> LinearMeasurement:
    return LinearMeasurement(H=H_POS, z=z, R=np.eye(3) * 0.09)


@given(st.floats(0.01, 100.0), st.lists(st.floats(0.5, 1e4), min_size=1, max_size=4))
def test_transition_matrix_is_stochastic(dt: float, dwell: list[float]) -> None:
    Pi = transition_matrix(dwell, dt)
    assert Pi.shape == (len(dwell), len(dwell))
    assert np.all(Pi >= 0) and np.allclose(Pi.sum(axis=1), 1.0)
    if len(dwell) > 1:  # a longer dwell time keeps the model more often
        i, j = int(np.argmax(dwell)), int(np.argmin(dwell))
        assert Pi[i, i] >= Pi[j, j]


def test_moment_match_of_two_points() -> None:
    x, P = moment_match([np.array([0.0]), np.array([2.0])], [np.eye(1), np.eye(1)], np.array([0.5, 0.5]))
    assert np.allclose(x, [1.0]) and np.allclose(P, [[2.0]])  # 1 + spread 1


def test_posterior_probabilities_prefer_the_likelier_model() -> None:
    mu = posterior_probabilities(np.array([0.5, 0.5]), np.array([-10.0, -2.0]))
    assert np.isclose(mu.sum(), 1.0) and mu[1] > 0.99
    assert np.allclose(posterior_probabilities(np.array([0.3, 0.7]), np.array([np.nan, 0.0])), [0.3, 0.7])


@settings(max_examples=20, deadline=None)
@given(st.lists(st.floats(-3.0, 3.0), min_size=6, max_size=6), st.floats(0.2, 5.0))
def test_imm_of_one_model_is_its_kalman_filter(noise: list[float], sigma_acc: float) -> None:
    """Invariant: with a single model the IMM is exactly that model's Kalman filter."""
    cv = ConstantVelocityModel(sigma_m_s2=sigma_acc)
    imm = ImmTracker(ImmModels((cv,), (10.0,), (1.0,)))
    f = EKF()
    kf = imm_state = _state()
    for k, t in enumerate((1.0, 2.0)):
        z = np.array([1.0 + t, 2.0, 3.0]) + np.array(noise[3 * k : 3 * k + 3]) * 0.3
        kf = f.update(f.predict(kf, cv, t), _meas(z)).state
        prior = imm.predict(f, imm_state, t)
        imm_state = imm.update(f, prior, _meas(z), None)[0].state
        assert np.allclose(imm_state.x, kf.x) and np.allclose(imm_state.P, kf.P)
        assert np.allclose(imm.probabilities, [1.0])


def test_imm_with_certain_model_and_no_transitions_is_its_kalman_filter() -> None:
    """Probability 1 on one model and infinite dwell times: the others never contribute."""
    spec = make_imm_models(3.0, 1e-8)
    spec = ImmModels(spec.models, (np.inf, np.inf, np.inf), (0.0, 1.0, 0.0))
    imm = ImmTracker(spec)
    f = EKF()
    kf = imm_state = _state()
    for t in (1.0, 2.0, 3.0):
        z = np.array([1.0 + 0.5 * t, 2.0 - 0.2 * t, 3.0])
        kf = f.update(f.predict(kf, spec.models[1], t), _meas(z)).state
        imm_state = imm.update(f, imm.predict(f, imm_state, t), _meas(z), None)[0].state
        assert np.allclose(imm_state.x, kf.x) and np.allclose(imm_state.P, kf.P)
    assert np.allclose(imm.probabilities, [0.0, 1.0, 0.0])


def _run(truth_pos: np.ndarray, seed: int = 1) -> np.ndarray:
    """Mode probabilities (T, 3) of the default IMM tracking noisy position fixes (σ 0.3 m)."""
    rng = np.random.default_rng(seed)
    imm = ImmTracker(make_imm_models(3.0, 1e-8))
    f = EKF()
    s = GaussianState(
        x=np.r_[truth_pos[0], 0, 0, 0], P=np.diag([1.0] * 3 + [1.0] * 3), t_s=0.0, layout=LAYOUT
    )
    out = []
    for k in range(1, len(truth_pos)):
        z = truth_pos[k] + 0.3 * rng.standard_normal(3)
        s = imm.update(f, imm.predict(f, s, float(k)), _meas(z), None)[0].state
        out.append(imm.probabilities)
    return np.array(out)


def test_mode_probabilities_follow_stop_go_turn() -> None:
    """Parked 40 s, straight at 10 m/s for 40 s, a 1 g turn of 40 s, parked again: the
    stationary model dominates when parked, a moving model when driving, and the
    manoeuvring model takes weight in the turn that it does not have on the straight."""
    t = np.arange(0.0, 161.0)
    pos = np.zeros((t.size, 3))
    for k in range(1, t.size):
        tk = t[k]
        if tk <= 40 or tk > 120:
            v = np.zeros(3)
        elif tk <= 80:
            v = np.array([10.0, 0.0, 0.0])
        else:  # turn: speed 10 m/s on a circle of radius 10 m (a = v²/r = 10 m/s²)
            th = 1.0 * (tk - 80)
            v = 10.0 * np.array([np.cos(th), np.sin(th), 0.0])
        pos[k] = pos[k - 1] + v
    pos[121:] = pos[120]
    mu = _run(pos)
    parked = np.r_[5:39, 125:159]
    straight, turn = np.r_[45:79], np.r_[85:119]
    assert np.median(mu[parked, 0]) > 0.9
    assert np.median(mu[straight, 1] + mu[straight, 2]) > 0.9
    assert np.median(mu[turn, 1] + mu[turn, 2]) > 0.9
    assert np.mean(mu[turn, 2]) > np.mean(mu[straight, 2]) + 0.1


def test_constant_velocity_acceleration_split_about_the_vertical() -> None:
    """``sigma_up_m_s2``: the acceleration's spectral density is σ_up² along ``up`` and σ²
    across it; without it the model is the isotropic one (Q unchanged)."""
    up = np.array([0.0, 0.6, 0.8])
    cv = ConstantVelocityModel(sigma_m_s2=3.0, sigma_up_m_s2=0.3, up=(0.0, 0.6, 0.8))
    A = cv.accel_psd()
    across = np.array([1.0, 0.0, 0.0])
    assert np.isclose(up @ A @ up, 0.09) and np.isclose(across @ A @ across, 9.0)
    Q = cv.transition(LAYOUT, 2.0)[1]
    assert np.allclose(Q[3:, 3:], 2.0 * A) and np.allclose(Q[:3, :3], 8.0 / 3.0 * A)
    iso = ConstantVelocityModel(sigma_m_s2=3.0).transition(LAYOUT, 2.0)[1]
    assert np.allclose(iso[3:, 3:], 18.0 * np.eye(3))
