"""Yang's adaptive factor from the predicted-state discrepancy (algorithms.md §23).

The three segments of α(Δ) against the formula written out independently; the two-factor
equivalent covariance is symmetric positive definite, keeps every correlation coefficient
and is the unscaled covariance for α = 1; on a linear model with a known discrepancy the
factor is the one computed by hand; a consistent prior is left alone (bit-identical update),
a single gross outlier does not pass for a dynamics error, and a wrong prediction is let go.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk.estimation.adaptive import (
    InnovationAdaptiveFactor,
    StateDiscrepancyFactor,
    adaptive_update,
    equivalent_covariance,
    make_adaptive_factor,
    state_discrepancy,
    yang_factor,
    yang_factors,
)
from robustrtk.estimation.filters import EKF, UKF
from robustrtk.estimation.models import LinearMeasurement
from robustrtk.estimation.prior_scale import apply_prior_scale
from robustrtk.estimation.robust import Chain, FixedFactors, NoRobust, PostfitIGG3
from robustrtk.estimation.state import GaussianState, StateLayout

C0, C1, FLOOR = 1.0, 2.5, 1e-3


def _spd(rng: np.random.Generator, n: int) -> np.ndarray:
    A = rng.normal(size=(n, n))
    return A @ A.T + 0.1 * n * np.eye(n)


def _corr(P: np.ndarray) -> np.ndarray:
    s = np.sqrt(np.diag(P))
    return P / np.outer(s, s)


# ----------------------------------------------------------------------------- α(Δ)
def test_three_segments_of_the_factor() -> None:
    # segment 1: the prediction is kept
    for d in (0.0, 0.3, 0.999, 1.0):
        assert yang_factor(d, C0, C1, FLOOR) == 1.0
    # segment 2: (c0/Δ)·((c1 − Δ)/(c1 − c0))², written out
    for d, expect in (
        (1.5, (1 / 1.5) * (1.0 / 1.5) ** 2),
        (2.0, 0.5 * (0.5 / 1.5) ** 2),
        (1.1, (1 / 1.1) * (1.4 / 1.5) ** 2),
    ):
        assert yang_factor(d, C0, C1, FLOOR) == pytest.approx(expect, rel=1e-12)
    # segment 3: the floor, never 0; a non-finite statistic counts as beyond c1
    for d in (2.5 + 1e-9, 3.0, 100.0, np.inf, np.nan):
        assert yang_factor(d, C0, C1, FLOOR) == FLOOR
    # continuous at c0 (→ 1) and reaching the floor at c1
    assert yang_factor(C0 + 1e-9, C0, C1, FLOOR) == pytest.approx(1.0, abs=1e-8)
    assert yang_factor(C1 - 1e-6, C0, C1, FLOOR) == FLOOR
    np.testing.assert_array_equal(
        yang_factors(np.array([[0.5, 2.0], [9.0, 1.0]]), C0, C1, FLOOR),
        [[1.0, yang_factor(2.0, C0, C1, FLOOR)], [FLOOR, 1.0]],
    )


@given(st.floats(0.0, 10.0), st.floats(0.0, 10.0))
def test_factor_is_monotone_and_bounded(a: float, b: float) -> None:
    lo, hi = sorted((a, b))
    fa, fb = yang_factor(lo, C0, C1, FLOOR), yang_factor(hi, C0, C1, FLOOR)
    assert FLOOR <= fb <= fa <= 1.0


# ----------------------------------------------------------------------------- P̄ᵢⱼ/√(αᵢαⱼ)
@settings(max_examples=60, deadline=None)
@given(st.integers(0, 10_000), st.integers(1, 7))
def test_equivalent_covariance_symmetric_pd_and_keeps_correlations(seed: int, n: int) -> None:
    rng = np.random.default_rng(seed)
    P = _spd(rng, n)
    alpha = rng.uniform(FLOOR, 1.0, n)
    Pa = equivalent_covariance(P, alpha)
    np.testing.assert_array_equal(Pa, Pa.T)
    assert np.linalg.eigvalsh(Pa).min() > 0.0
    np.testing.assert_allclose(np.diag(Pa), np.diag(P) / alpha, rtol=1e-12)
    np.testing.assert_allclose(_corr(Pa), _corr(P), rtol=1e-10, atol=1e-12)
    # α = 1 leaves the covariance as it is
    np.testing.assert_array_equal(equivalent_covariance(P, np.ones(n)), P)


def test_equivalent_covariance_by_hand() -> None:
    P = np.array([[4.0, 1.2], [1.2, 1.0]])
    Pa = equivalent_covariance(P, np.array([0.25, 1.0]))
    np.testing.assert_allclose(Pa, [[16.0, 2.4], [2.4, 1.0]])


# ----------------------------------------------------------------------------- linear model
def _direct(sig_prior: float, r: float, delta: np.ndarray) -> tuple[GaussianState, LinearMeasurement]:
    """A 3-state prior at 0 with σ̄ = sig_prior, observed directly (H = I, σ = r), z = delta."""
    n = delta.size
    prior = GaussianState(np.zeros(n), sig_prior**2 * np.eye(n), 0.0, StateLayout(blocks=(("pos", n),)))
    return prior, LinearMeasurement(np.eye(n), delta.astype(float), r**2 * np.eye(n))


@pytest.mark.parametrize("filt", [EKF(), UKF()], ids=["ekf", "ukf"])
def test_known_discrepancy_gives_the_known_factor(filt: EKF | UKF) -> None:
    # x̂ − x̄ = σ̄²/(σ̄² + r²)·δ, so Δᵢ = σ̄ δᵢ/(σ̄² + r²): with σ̄ = r = 1, Δ = δ/2
    delta = np.array([1.0, 3.5, 8.0])
    prior, meas = _direct(1.0, 1.0, delta)
    res, out = StateDiscrepancyFactor(C0, C1, FLOOR, max_iter=1).update(filt, prior, meas, NoRobust())
    np.testing.assert_allclose(out.delta, delta / 2.0, rtol=1e-9)
    expect = np.array([1.0, (1 / 1.75) * (0.75 / 1.5) ** 2, FLOOR])
    np.testing.assert_allclose(out.alpha, expect, rtol=1e-9)
    assert out.at_floor and out.alpha_min == pytest.approx(FLOOR)
    # the final update is the Kalman update of the prior P̄/α (diagonal here)
    Pa = np.diag(1.0 / expect)
    x_expect = Pa @ np.linalg.solve(Pa + np.eye(3), delta)
    np.testing.assert_allclose(res.state.x, x_expect, rtol=1e-8)
    np.testing.assert_allclose(np.asarray(res.prior_scale), 1.0 / expect, rtol=1e-12)


def test_state_discrepancy_is_the_correction_in_predicted_sigmas() -> None:
    prior = GaussianState(np.array([1.0, 2.0, 3.0]), np.diag([4.0, 1.0, 0.25]))
    np.testing.assert_allclose(
        state_discrepancy(prior, np.array([3.0, 1.0, 3.5]), np.arange(3)), [1.0, 1.0, 1.0]
    )


def test_passes_widen_the_prior_until_it_agrees_with_the_data() -> None:
    """After the passes every component either agrees (Δ ≤ c0 on the adapted prior) or sits at
    the floor; the first pass alone (the paper's) widens less."""
    rng = np.random.default_rng(3)
    for _ in range(20):
        delta = rng.uniform(0.5, 20.0, 3) * rng.choice([-1, 1], 3)
        prior, meas = _direct(0.2, 1.0, delta)
        fac = StateDiscrepancyFactor(C0, C1, FLOOR, max_iter=50)
        _, out = fac.update(EKF(), prior, meas, NoRobust())
        _, one = StateDiscrepancyFactor(C0, C1, FLOOR, max_iter=1).update(EKF(), prior, meas, NoRobust())
        assert np.all(out.alpha <= one.alpha + 1e-15)
        adapted = prior.with_(P=equivalent_covariance(prior.P, out.alpha))
        trial = EKF().update(adapted, meas, NoRobust())
        d = state_discrepancy(adapted, trial.state.x, np.arange(3))
        assert np.all((d <= C0 + 1e-9) | (out.alpha == FLOOR))


def test_consistent_prior_is_left_alone_bit_identical() -> None:
    """A converged static prior (the covariance of 50 epochs of these data, ``Σ̃/50``) with the
    truth drawn from it: α = 1 at every trial, and the update is exactly the plain robust one."""
    rng = np.random.default_rng(11)
    H = rng.normal(size=(8, 3))
    R = 0.3**2 * np.eye(8)
    P = np.linalg.inv(H.T @ np.linalg.solve(R, H)) / 50.0
    policy = Chain()
    fac = StateDiscrepancyFactor()
    for _ in range(120):
        x_bar = rng.normal(size=3)
        x_true = x_bar + np.linalg.cholesky(P) @ rng.normal(size=3)
        prior = GaussianState(x_bar, P, 0.0, StateLayout(blocks=(("pos", 3),)))
        meas = LinearMeasurement(H, H @ x_true + 0.3 * rng.normal(size=8), R)
        res, out = fac.update(EKF(), prior, meas, policy)
        assert np.all(out.alpha == 1.0)
        plain = EKF().update(prior, meas, policy)
        np.testing.assert_array_equal(res.state.x, plain.state.x)
        np.testing.assert_array_equal(res.state.P, plain.state.P)
        assert res.prior_scale is None


def _geometry(rng: np.random.Generator, m: int) -> np.ndarray:
    H = rng.normal(size=(m, 3))
    return H / np.linalg.norm(H, axis=1, keepdims=True)


def test_one_gross_outlier_is_not_a_dynamics_error() -> None:
    """A +40 σ error on one of 10 rows: the measurement-only robust fit removes it, so the
    discrepancy stays small (α = 1); the same rows without that fit would widen the prior."""
    rng = np.random.default_rng(5)
    H = _geometry(rng, 10)
    x_true = np.zeros(3)
    prior = GaussianState(x_true.copy(), 0.2**2 * np.eye(3), 0.0, StateLayout(blocks=(("pos", 3),)))
    z = H @ x_true + 0.3 * rng.normal(size=10)
    z[4] += 40 * 0.3
    meas = LinearMeasurement(H, z, 0.3**2 * np.eye(10))
    _, out = StateDiscrepancyFactor().update(EKF(), prior, meas, PostfitIGG3())
    assert np.all(out.alpha == 1.0)
    plain = EKF().update(prior, meas, FixedFactors((1.0,) * 10))
    assert state_discrepancy(prior, plain.state.x, np.arange(3)).max() > C0


def test_wrong_prediction_is_let_go_despite_the_robust_policy() -> None:
    """The prediction is 3.7 m off with σ̄ = 10 cm (a car filtered as static; within the floor's
    reach, σ̄/√floor = 3.2 m): the robust policy alone down-weights the good rows and stays near
    the prediction; with the adaptive factor the estimate follows the data."""
    rng = np.random.default_rng(8)
    H = _geometry(rng, 10)
    x_true = np.array([3.0, -2.0, 1.0])
    prior = GaussianState(np.zeros(3), 0.1**2 * np.eye(3), 0.0, StateLayout(blocks=(("pos", 3),)))
    meas = LinearMeasurement(H, H @ x_true + 0.3 * rng.normal(size=10), 0.3**2 * np.eye(10))
    policy = Chain()
    stuck = EKF().update(prior, meas, policy)
    assert np.linalg.norm(stuck.state.x - x_true) > 3.0
    res, out = StateDiscrepancyFactor().update(EKF(), prior, meas, policy)
    assert out.at_floor
    # within about one σ of the measurement-only least squares (Σ̃ = σ² (HᵀH)⁻¹)
    lsq = np.linalg.lstsq(H, meas.z, rcond=None)[0]
    e = res.state.x - lsq
    assert float(e @ (H.T @ H) @ e) / 0.3**2 < 3.0
    assert np.linalg.norm(res.state.x - x_true) < 0.25 * np.linalg.norm(stuck.state.x - x_true)


def test_correlated_prior_keeps_its_correlations_and_other_blocks() -> None:
    """Only the kinematic blocks get a factor (a clock block keeps α = 1); the prior applied
    has the correlations of P̄."""
    rng = np.random.default_rng(2)
    layout = StateLayout(blocks=(("pos", 3), ("clk", 1)))
    P = 0.01 * _spd(rng, 4)
    prior = GaussianState(np.zeros(4), P, 0.0, layout)
    H = np.hstack([_geometry(rng, 9), np.ones((9, 1))])
    x_true = np.array([3.0, 1.0, -2.0, 0.0])
    meas = LinearMeasurement(H, H @ x_true + 0.1 * rng.normal(size=9), 0.01 * np.eye(9))
    res, out = StateDiscrepancyFactor().update(EKF(), prior, meas, NoRobust())
    assert out.alpha[3] == 1.0 and np.isnan(out.delta[3]) and out.alpha[:3].min() < 1.0
    applied = apply_prior_scale(P, np.asarray(res.prior_scale))
    np.testing.assert_allclose(_corr(applied), _corr(P), rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(applied, equivalent_covariance(P, out.alpha), rtol=1e-12)


def test_adaptive_update_dispatch_and_names() -> None:
    prior, meas = _direct(1.0, 1.0, np.array([0.1, 0.2, 0.3]))
    plain = EKF().update(prior, meas, NoRobust())
    res, out = adaptive_update(EKF(), prior, meas, NoRobust(), None)
    assert out is None
    np.testing.assert_array_equal(res.state.x, plain.state.x)
    big = _direct(0.01, 1.0, np.array([30.0, -40.0, 25.0, 30.0, 35.0]))
    res, out = adaptive_update(EKF(), *big, NoRobust(), InnovationAdaptiveFactor())
    assert out is not None and out.alpha_min < 1.0
    assert out.alpha_min == pytest.approx(1.0 / float(np.max(np.atleast_1d(res.prior_scale))))
    st_ = make_adaptive_factor("state")
    assert isinstance(st_, StateDiscrepancyFactor) and (st_.c0, st_.c1) == (1.0, 2.5)
    inn = make_adaptive_factor("innovation", c1=5.0)
    assert isinstance(inn, InnovationAdaptiveFactor) and (inn.c0, inn.c1) == (2.0, 5.0)
    assert make_adaptive_factor("off") is None
    with pytest.raises(ValueError, match="unknown adaptive"):
        make_adaptive_factor("yang")


def test_fixed_factors_policy_equals_dropping_the_rows() -> None:
    rng = np.random.default_rng(4)
    H = rng.normal(size=(6, 3))
    prior = GaussianState(np.zeros(3), np.eye(3))
    meas = LinearMeasurement(H, rng.normal(size=6), np.eye(6))
    g = (1.0, np.inf, 4.0, 1.0, 1.0, np.inf)
    res = EKF().update(prior, meas, FixedFactors(g))
    keep = np.isfinite(g)
    sub = LinearMeasurement(H[keep], meas.z[keep], np.diag(np.array(g)[keep]))
    np.testing.assert_allclose(res.state.x, EKF().update(prior, sub, NoRobust()).state.x, rtol=1e-12)
    with pytest.raises(ValueError, match="factors for"):
        EKF().update(prior, meas, FixedFactors((1.0,)))
