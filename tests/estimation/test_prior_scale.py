"""Prior-scaling hook of the filter update: the scaled update equals the plain update of a
state built with the scaled covariance (EKF and UKF, with robust policies, also for a
nonlinear model); the UKF equals the EKF on a linear model for every kind of factor; a
hook object sees the nominal prior's innovation; no scaling is bit-identical."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk.estimation.filters import EKF, UKF
from robustrtk.estimation.models import LinearMeasurement
from robustrtk.estimation.prior_scale import FixedPriorScale, PriorScale, apply_prior_scale
from robustrtk.estimation.robust import Chain, DeltaVIGG3, NoRobust, PrefitIGG3, RobustPolicy
from robustrtk.estimation.state import GaussianState, StateLayout, UpdateResult


def _spd(rng: np.random.Generator, n: int, scale: float = 1.0) -> np.ndarray:
    A = rng.normal(size=(n, n))
    return scale * (A @ A.T + n * np.eye(n) * 0.1)


def _problem(seed: int, n: int, m: int) -> tuple[GaussianState, LinearMeasurement]:
    rng = np.random.default_rng(seed)
    x = rng.normal(size=n)
    P = _spd(rng, n)
    H = rng.normal(size=(m, n))
    R = _spd(rng, m, 0.5)
    z = H @ x + rng.normal(size=m)
    return GaussianState(x, P, 0.0, StateLayout(blocks=(("pos", n),))), LinearMeasurement(H, z, R)


def _factor(kind: str, rng: np.random.Generator, n: int) -> float | np.ndarray:
    if kind == "float":
        return float(rng.uniform(0.2, 5.0))
    if kind == "vector":
        return rng.uniform(0.2, 5.0, size=n)
    return np.eye(n) + 0.3 * rng.normal(size=(n, n))


def _kf(x: np.ndarray, P: np.ndarray, H: np.ndarray, z: np.ndarray, R: np.ndarray) -> tuple:
    S = H @ P @ H.T + R
    K = P @ H.T @ np.linalg.inv(S)
    return x + K @ (z - H @ x), (np.eye(len(x)) - K @ H) @ P


@dataclass
class Recorder:
    """A PriorScale that records what it was called with and returns a fixed factor."""

    factor: float | np.ndarray
    calls: list[tuple[GaussianState, np.ndarray, np.ndarray, np.ndarray]] = field(default_factory=list)

    def scale(
        self, state: GaussianState, innovation: np.ndarray, innovation_cov: np.ndarray, R: np.ndarray
    ) -> float | np.ndarray:
        self.calls.append((state, innovation.copy(), innovation_cov.copy(), R.copy()))
        return self.factor


@dataclass(frozen=True)
class Range:
    """Nonlinear: distances from the first two state components to anchors."""

    anchors: np.ndarray
    z: np.ndarray
    R: np.ndarray
    labels: tuple[str, ...] = ()

    def h(self, X: np.ndarray) -> np.ndarray:
        X = np.asarray(X)
        return np.linalg.norm(X[..., None, :2] - self.anchors, axis=-1)

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        d = x[:2] - self.anchors
        J = np.zeros((len(self.anchors), len(x)))
        J[:, :2] = d / np.linalg.norm(d, axis=1)[:, None]
        return J


def _assert_same(a: UpdateResult, b: UpdateResult) -> None:
    np.testing.assert_array_equal(a.state.x, b.state.x)
    np.testing.assert_array_equal(a.state.P, b.state.P)
    np.testing.assert_array_equal(a.innovation, b.innovation)
    np.testing.assert_array_equal(a.innovation_cov, b.innovation_cov)
    np.testing.assert_array_equal(a.residual, b.residual)
    np.testing.assert_array_equal(a.factors, b.factors)
    np.testing.assert_array_equal(a.std_residual, b.std_residual)
    assert a.iterations == b.iterations


@settings(max_examples=30, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(1, 5),
    m=st.integers(1, 5),
    kind=st.sampled_from(["float", "vector", "matrix"]),
    hook=st.booleans(),
)
def test_ukf_equals_ekf_equals_kf_with_every_kind_of_prior_scale(
    seed: int, n: int, m: int, kind: str, hook: bool
) -> None:
    st0, meas = _problem(seed, n, m)
    f = _factor(kind, np.random.default_rng(seed + 1), n)
    if kind == "float":
        P_ref = f * st0.P
    elif kind == "vector":
        G = np.diag(np.sqrt(f))
        P_ref = G @ st0.P @ G
    else:
        Tm = np.asarray(f)
        P_ref = Tm @ st0.P @ Tm.T
    x_kf, P_kf = _kf(st0.x, P_ref, meas.H, meas.z, meas.R)
    arg = FixedPriorScale(f) if hook else f
    for flt in (EKF(), UKF(), UKF(alpha=0.5, kappa=1.0)):
        res = flt.update(st0, meas, prior_scale=arg)
        np.testing.assert_allclose(res.state.x, x_kf, rtol=1e-7, atol=1e-8)
        np.testing.assert_allclose(res.state.P, P_kf, rtol=1e-6, atol=1e-8)
        np.testing.assert_allclose(
            res.innovation_cov, meas.H @ P_ref @ meas.H.T + meas.R, rtol=1e-7, atol=1e-9
        )
        assert res.prior_scale is not None
        np.testing.assert_array_equal(res.prior_scale, f)


POLICIES: list[RobustPolicy] = [NoRobust(), DeltaVIGG3(), PrefitIGG3(), Chain()]


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(2, 5), policy=st.sampled_from(POLICIES))
def test_scaling_by_s_equals_state_built_with_s_times_P(seed: int, n: int, policy: RobustPolicy) -> None:
    rng = np.random.default_rng(seed)
    st0, meas = _problem(seed, n, 6)
    z = meas.z.copy()
    z[int(rng.integers(0, 6))] += 30.0  # an outlier so that the policies act
    meas = LinearMeasurement(meas.H, z, meas.R)
    s = float(rng.uniform(0.1, 10.0))
    anchors = rng.normal(size=(4, 2)) * 20
    rng_meas = Range(anchors, np.linalg.norm(st0.x[:2] - anchors, axis=1) + 0.3, 0.1 * np.eye(4))
    for mm in (meas, rng_meas):
        for flt in (EKF(), UKF()):
            a = flt.update(st0, mm, robust=policy, prior_scale=s)
            b = flt.update(st0.with_(P=s * st0.P), mm, robust=policy)
            _assert_same(a, b)
            assert a.prior_scale == s and b.prior_scale is None


def test_no_scaling_is_bit_identical_and_unit_factor_changes_nothing() -> None:
    st0, meas = _problem(7, 4, 5)
    for flt in (EKF(), UKF()):
        plain = flt.update(st0, meas, DeltaVIGG3())
        _assert_same(plain, flt.update(st0, meas, DeltaVIGG3(), prior_scale=None))
        _assert_same(plain, flt.update(st0, meas, DeltaVIGG3(), prior_scale=1.0))
        _assert_same(plain, flt.update(st0, meas, DeltaVIGG3(), prior_scale=FixedPriorScale(1.0)))
        assert plain.prior_scale is None


@pytest.mark.parametrize("flt", [EKF(), UKF()], ids=["ekf", "ukf"])
def test_hook_receives_the_nominal_innovation_and_its_result_is_applied(flt: EKF | UKF) -> None:
    st0, meas = _problem(11, 3, 4)
    g = np.array([2.0, 0.5, 3.0])
    rec = Recorder(g)
    assert isinstance(rec, PriorScale)
    res = flt.update(st0, meas, prior_scale=rec)
    assert len(rec.calls) == 1
    state, d, S, R = rec.calls[0]
    assert state is st0
    np.testing.assert_allclose(d, meas.z - meas.H @ st0.x, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(S, meas.H @ st0.P @ meas.H.T + meas.R, rtol=1e-9, atol=1e-12)
    np.testing.assert_array_equal(R, meas.R)
    _assert_same(res, flt.update(st0.with_(P=apply_prior_scale(st0.P, g)), meas))
    np.testing.assert_array_equal(res.prior_scale, g)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 6))
def test_vector_scaling_keeps_correlation_coefficients(seed: int, n: int) -> None:
    rng = np.random.default_rng(seed)
    P = _spd(rng, n)
    g = rng.uniform(0.01, 100.0, size=n)
    Ps = apply_prior_scale(P, g)
    corr = P / np.sqrt(np.outer(np.diag(P), np.diag(P)))
    corr_s = Ps / np.sqrt(np.outer(np.diag(Ps), np.diag(Ps)))
    np.testing.assert_allclose(corr_s, corr, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(np.diag(Ps), g * np.diag(P), rtol=1e-12)
    np.testing.assert_array_equal(Ps, Ps.T)


def test_bad_factors_raise() -> None:
    st0, meas = _problem(3, 3, 2)
    for bad in (0.0, -1.0, np.inf, np.ones(2), np.array([1.0, -1.0, 1.0]), np.eye(2), np.ones((3, 3, 1))):
        with pytest.raises(ValueError):
            EKF().update(st0, meas, prior_scale=bad)
    with pytest.raises(ValueError):
        UKF().update(st0, meas, prior_scale=FixedPriorScale(np.ones(4)))
