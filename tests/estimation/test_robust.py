"""Robust policies: IGG-III values, continuity and monotonicity; Δv̄; the robust UKF
rejects a 10 m DD code error and down-weights a 1.5 m one."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk.estimation.filters import EKF, UKF
from robustrtk.estimation.registry import make_robust_policy
from robustrtk.estimation.robust import (
    DeltaVIGG3,
    NoRobust,
    PostfitIGG3,
    PrefitIGG3,
    discriminant_statistic,
    huber_factor,
    igg3_factor,
    igg3_factor_scalar,
    igg3_weight,
)
from robustrtk.estimation.state import GaussianState, StateLayout
from robustrtk.measurement.dd import DDRangeModel, form_dd, ranges

TX = {
    "PL1": np.array([-3.5, -2.0, 4.0]),
    "PL4": np.array([3.8, -2.4, 3.9]),
    "PL5": np.array([3.2, 2.6, 4.0]),
    "PL6": np.array([0.2, 0.1, 4.0]),
    "PL8": np.array([-3.0, 2.8, 3.95]),
}
IDS = tuple(TX)
TX_POS = np.array([TX[k] for k in IDS])


def test_igg3_reference_values():
    k0, k1 = 2.0, 8.0
    assert igg3_factor(1.9, k0, k1) == 1.0
    assert igg3_factor(-2.0, k0, k1) == 1.0
    # middle segment: gamma = |u| (k1-k0)^2 / (k0 (k1-|u|)^2)
    assert np.isclose(igg3_factor(4.0, k0, k1), 4 * 36 / (2 * 16))
    assert np.isclose(igg3_factor(-5.0, k0, k1), 5 * 36 / (2 * 9))
    assert np.isinf(igg3_factor(8.01, k0, k1))
    assert igg3_weight(9.0, k0, k1) == 0.0
    assert np.isclose(igg3_weight(4.0, k0, k1), 32 / 144)
    with pytest.raises(ValueError):
        igg3_factor(1.0, 3.0, 2.0)


@settings(max_examples=60, deadline=None)
@given(k0=st.floats(0.5, 3.0), gap=st.floats(0.5, 6.0), seed=st.integers(0, 2**32 - 1))
def test_igg3_scalar_is_the_array_factor_to_the_bit(k0, gap, seed):
    k1 = k0 + gap
    u = np.random.default_rng(seed).uniform(-1.2 * k1, 1.2 * k1, 400)
    u = np.r_[u, k0, -k0, k1, -k1, 0.0, np.nan, np.inf, -np.inf]
    g = igg3_factor(u, k0, k1)
    gs = np.array([igg3_factor_scalar(v, k0, k1) for v in u])
    np.testing.assert_array_equal(gs.view(np.int64), g.view(np.int64))
    with pytest.raises(ValueError):
        igg3_factor_scalar(1.0, k1, k0)


@settings(max_examples=60, deadline=None)
@given(k0=st.floats(0.5, 3.0), gap=st.floats(0.5, 6.0))
def test_igg3_continuity_and_monotonicity(k0, gap):
    k1 = k0 + gap
    # continuous at k0 from above
    assert np.isclose(igg3_factor(k0 * (1 + 1e-9), k0, k1), 1.0, rtol=1e-6)
    u = np.linspace(0, k1, 2001)
    g = igg3_factor(u, k0, k1)
    assert np.all(np.diff(g) >= -1e-12)  # non-decreasing
    assert np.all(g >= 1.0)
    # weight tends to 0 as |u| -> k1 (continuous to rejection)
    assert igg3_weight(k1 * (1 - 1e-6), k0, k1) < 1e-6


def test_huber():
    assert huber_factor(1.0, 1.5) == 1.0
    assert np.isclose(huber_factor(-3.0, 1.5), 2.0)


def test_discriminant_statistic():
    v = np.array([1.0, -1.0, 2.0, 10.0])
    dv = discriminant_statistic(v)
    assert np.isclose(dv[3], 10 / ((1 + 1 + 2) / 3))
    assert np.isclose(dv[1], -1 / ((1 + 2 + 10) / 3))
    assert np.all(np.isnan(discriminant_statistic(np.array([1.0, 2.0]))))
    with_nan = discriminant_statistic(np.array([1.0, np.nan, 1.0, 4.0]))
    assert np.isnan(with_nan[1]) and np.isclose(with_nan[3], 4.0)
    assert np.all(discriminant_statistic(np.zeros(4)) == 0)


def _dd_problem(rng, err_m=0.0, err_tx="PL4", sigma=0.05, prior_sigma=0.05):
    """A 5-pseudolite DD code epoch with an optional gross error on one DD."""
    base = np.array([0.0, 0.0, 0.0])
    rover = np.array([1.2, -0.7, 1.0])
    r_r = ranges(rover, TX_POS)
    r_b = ranges(base, TX_POS)
    clk_tx = rng.normal(0, 1e3, 5)
    code_r = r_r + clk_tx + 123.0 + rng.normal(0, sigma, 5)
    code_b = r_b + clk_tx - 77.0 + rng.normal(0, sigma, 5)
    code_r[IDS.index(err_tx)] += err_m
    var = np.full(5, sigma**2)
    dd = form_dd(IDS, ["P:L1"] * 5, code_r, code_b, var, var, {"P:L1": "PL6"})
    layout = StateLayout()
    x0 = rover + rng.normal(0, prior_sigma, 3)
    state = GaussianState(x0, np.eye(3) * prior_sigma**2, 0.0, layout)
    model = DDRangeModel(
        TX_POS, r_b, dd.i_tx, dd.i_ref, slice(0, 3), np.full(dd.m, -1), np.zeros(dd.m), dd.z, dd.R, dd.labels
    )
    return state, model, rover, dd


@pytest.mark.parametrize("filt", [UKF(), EKF()], ids=["ukf", "ekf"])
def test_robust_rejects_10m_and_downweights_1p5m(filt):
    rng = np.random.default_rng(3)
    pol = DeltaVIGG3(k0=2.0, k1=8.0)
    state, model, truth, dd = _dd_problem(rng, err_m=10.0, sigma=0.2, prior_sigma=0.2)
    i_bad = dd.tx.index("PL4")
    res = filt.update(state, model, pol)
    assert res.situation[i_bad] == 3
    assert np.all(res.situation[np.arange(dd.m) != i_bad] == 1)
    std_res = filt.update(state, model, NoRobust())
    err_r = np.linalg.norm(res.state.x - truth)
    err_s = np.linalg.norm(std_res.state.x - truth)
    assert err_r < 0.3 < err_s
    # 1.5 m error (about 5 sigma of a DD): down-weighted, not rejected
    rng = np.random.default_rng(11)
    state, model, truth, dd = _dd_problem(rng, err_m=1.5, sigma=0.1, prior_sigma=0.1)
    res = filt.update(state, model, pol)
    assert res.situation[i_bad] == 2
    assert 1 < res.factors[i_bad] < np.inf
    assert abs(res.dv[i_bad]) == np.max(np.abs(res.dv))
    s = filt.update(state, model, NoRobust())
    assert np.linalg.norm(res.state.x - truth) < np.linalg.norm(s.state.x - truth)


def test_clean_epoch_untouched_and_policies_agree_with_standard():
    rng = np.random.default_rng(5)
    state, model, truth, dd = _dd_problem(rng, sigma=0.1, prior_sigma=0.1)
    ref = UKF().update(state, model, NoRobust())
    # Δv̄ is a ratio of residual magnitudes and heavy-tailed on clean data: wider k0
    thresholds = {"igg3": (6.0, 12.0), "huber": (3.0, None)}
    for name in ("igg3", "prefit", "postfit", "igg3-std", "huber"):
        k0, k1 = thresholds.get(name, (3.0, 9.0))
        res = UKF().update(state, model, make_robust_policy(name, k0=k0, k1=k1))
        assert np.all(res.factors == 1.0), name
        np.testing.assert_allclose(res.state.x, ref.state.x)


def test_prefit_and_postfit_catch_outlier():
    rng = np.random.default_rng(9)
    state, model, truth, dd = _dd_problem(rng, err_m=5.0, sigma=0.1, prior_sigma=0.1)
    i_bad = dd.tx.index("PL4")
    pre = UKF().update(state, model, PrefitIGG3())
    assert pre.factors[i_bad] > 1 and np.argmax(pre.factors) == i_bad
    post = UKF().update(state, model, PostfitIGG3())
    assert post.factors[i_bad] > 1
    # one row per iteration: the outlier first, so it carries the largest factor
    assert np.argmax(post.factors) == i_bad and post.iterations >= 2
    first = UKF().update(state, model, PostfitIGG3(max_iter=2))
    assert np.sum(first.factors > 1) == 1 and first.factors[i_bad] > 1
    plain = UKF().update(state, model, NoRobust())
    assert np.linalg.norm(post.state.x - truth) < np.linalg.norm(plain.state.x - truth) - 0.2


def test_make_policy_rejects_unknown():
    with pytest.raises(ValueError, match="unknown robust policy"):
        make_robust_policy("tukey")
