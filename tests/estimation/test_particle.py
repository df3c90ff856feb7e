"""Particle filter: systematic resampling is unbiased, ESS bounds, the cloud converges to the
Kalman filter on a linear-Gaussian problem, the linear-sub-state proposal is exact, seeds
reproduce runs."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk.estimation.filters import EKF
from robustrtk.estimation.models import LinearMeasurement, RandomWalkModel
from robustrtk.estimation.particle import (
    ParticleFilter,
    ParticleState,
    effective_sample_size,
    normalize_log_weights,
    roughen,
    systematic_resample,
)
from robustrtk.estimation.state import GaussianState, StateLayout


@settings(max_examples=50, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 200))
def test_systematic_resampling_copies_floor_or_ceil(seed, n):
    rng = np.random.default_rng(seed)
    w = rng.random(n) ** 3
    w /= w.sum()
    idx = systematic_resample(w, rng)
    assert idx.shape == (n,)
    assert np.all(np.diff(idx) >= 0)
    counts = np.bincount(idx, minlength=n)
    assert counts.sum() == n
    # each particle is copied floor(N w) or ceil(N w) times (round-off tolerance of one)
    assert np.all(counts >= np.floor(n * w - 1e-9))
    assert np.all(counts <= np.ceil(n * w + 1e-9))


def test_systematic_resampling_is_unbiased():
    rng = np.random.default_rng(7)
    w = np.array([0.5, 0.25, 0.125, 0.0625, 0.0625 - 1e-3, 1e-3])
    w /= w.sum()
    n_rep = 20000
    total = np.zeros(w.size)
    for _ in range(n_rep):
        total += np.bincount(systematic_resample(w, rng), minlength=w.size)
    mean_copies = total / n_rep
    np.testing.assert_allclose(mean_copies, w.size * w, atol=0.01)


@settings(max_examples=50, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 500))
def test_ess_between_one_and_n(seed, n):
    rng = np.random.default_rng(seed)
    lw = rng.normal(scale=rng.uniform(0.01, 30.0), size=n)
    ess = effective_sample_size(lw)
    assert 1.0 - 1e-9 <= ess <= n + 1e-9
    np.testing.assert_allclose(np.exp(normalize_log_weights(lw)).sum(), 1.0, rtol=1e-12)


def test_ess_extremes():
    assert effective_sample_size(np.zeros(37)) == pytest.approx(37.0)
    lw = np.full(10, -np.inf)
    lw[3] = 0.0
    assert effective_sample_size(lw) == pytest.approx(1.0)
    with pytest.raises(ValueError):
        normalize_log_weights(np.full(4, -np.inf))


def test_roughening_spread_follows_the_formula():
    rng = np.random.default_rng(1)
    X = np.zeros((40000, 2))
    X[:, 0] = np.linspace(0.0, 10.0, X.shape[0])  # range E = 10, second column E = 0
    Y = roughen(X, rng, k=0.2)
    sd = np.std(Y[:, 0] - X[:, 0])
    assert sd == pytest.approx(0.2 * 10.0 * X.shape[0] ** (-1 / 2), rel=0.02)
    np.testing.assert_array_equal(Y[:, 1], 0.0)
    np.testing.assert_array_equal(roughen(X, rng, k=0.0), X)


def _linear_problem(seed: int):
    rng = np.random.default_rng(seed)
    n, m = 3, 4
    x0 = rng.normal(size=n)
    A = rng.normal(size=(n, n))
    P0 = A @ A.T + np.eye(n)
    H = rng.normal(size=(m, n))
    R = np.diag(rng.uniform(0.5, 2.0, m))
    z = H @ x0 + rng.normal(size=m)
    layout = StateLayout(blocks=(("pos", n),))
    return GaussianState(x0, P0, 0.0, layout), LinearMeasurement(H, z, R)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_particle_filter_converges_to_kalman_on_linear_gaussian(seed):
    prior, meas = _linear_problem(seed)
    process = RandomWalkModel(sigma_m_s=0.7)
    kf = EKF()
    g = kf.predict(prior, process, 1.0)
    g = kf.update(g, meas).state
    pf = ParticleFilter(n_particles=200_000, ess_threshold=0.0, roughening=0.0, seed=seed)
    c = pf.predict(pf.init(prior), process, 1.0)
    up = pf.update(c, meas)
    s = up.state.summary()
    sd = np.sqrt(np.diag(g.P))
    np.testing.assert_allclose(s.x, g.x, atol=0.03 * sd.max())
    np.testing.assert_allclose(s.P, g.P, atol=0.05 * np.max(np.abs(g.P)))
    assert 1.0 <= up.ess <= pf.n_particles
    assert not up.resampled


def test_linear_substate_proposal_matches_kalman():
    """A clock with a process noise 10⁴ times the code noise: the bootstrap PF would
    keep a handful of particles; the optimal proposal of the linear sub-state is exact."""
    rng = np.random.default_rng(3)
    layout = StateLayout(blocks=(("pos", 3), ("clk", 1)))
    x0 = np.array([1.0, -2.0, 0.5, 0.0])
    P0 = np.diag([0.25, 0.25, 0.25, 1.0])
    H = np.hstack([rng.normal(size=(6, 3)), np.ones((6, 1))])
    R = np.eye(6) * 1.0
    z = H @ np.array([1.5, -1.0, 0.0, 300.0]) + rng.normal(scale=0.5, size=6)
    meas = LinearMeasurement(H, z, R)

    class ClockWalk:
        name = "clock-walk"

        def blocks(self):
            return layout.blocks

        def transition(self, lay, dt):
            return np.eye(4), np.diag([0.0, 0.0, 0.0, 1.0e6 * dt])

    prior = GaussianState(x0, P0, 0.0, layout)
    kf = EKF()
    g = kf.update(kf.predict(prior, ClockWalk(), 1.0), meas).state
    pf = ParticleFilter(n_particles=100_000, ess_threshold=0.0, roughening=0.0, seed=4, linear_idx=(3,))
    c = pf.predict(pf.init(prior), ClockWalk(), 1.0)
    assert c.P[3, 3] == pytest.approx(1.0e6 + 1.0, rel=0.02)  # pending noise in the summary
    up = pf.update(c, meas)
    s = up.state.summary()
    assert up.ess > 5000
    sd = np.sqrt(np.diag(g.P))
    # Monte Carlo error of a weighted mean ~ sd / sqrt(ESS)
    np.testing.assert_array_less(np.abs(s.x - g.x), 5 * sd / np.sqrt(up.ess))
    np.testing.assert_allclose(np.diag(s.P), np.diag(g.P), rtol=10 / np.sqrt(up.ess))
    boot = ParticleFilter(n_particles=100_000, ess_threshold=0.0, roughening=0.0, seed=4)
    up_boot = boot.update(boot.predict(boot.init(prior), ClockWalk(), 1.0), meas)
    assert up.ess > 20 * up_boot.ess


def test_resampling_under_threshold_and_reproducible():
    prior, meas = _linear_problem(5)
    tight = LinearMeasurement(meas.H, meas.z, meas.R * 1e-4)

    def run(seed):
        pf = ParticleFilter(n_particles=2000, ess_threshold=0.5, roughening=0.2, seed=seed)
        c = pf.init(prior)
        up = pf.update(c, tight)
        return up

    a, b, c = run(11), run(11), run(12)
    assert a.resampled and a.ess < 0.5 * 2000
    np.testing.assert_allclose(np.exp(a.state.log_w), 1.0 / 2000)
    np.testing.assert_array_equal(a.state.particles, b.state.particles)
    assert not np.array_equal(a.state.particles, c.state.particles)


def test_summary_is_weighted_moments():
    X = np.array([[0.0, 0.0], [2.0, 0.0], [0.0, 4.0]])
    w = np.array([0.5, 0.25, 0.25])
    st_ = ParticleState(X, np.log(w), 0.0, StateLayout(blocks=(("pos", 2),)))
    mean = w @ X
    np.testing.assert_allclose(st_.x, mean)
    d = X - mean
    np.testing.assert_allclose(st_.P, (d * w[:, None]).T @ d)


def _cloud(seed: int, n_particles: int = 4000) -> ParticleState:
    rng = np.random.default_rng(seed)
    X = rng.normal(size=(n_particles, 4)) @ np.array(
        [[1.0, 0.3, 0.0, 0.1], [0.0, 0.5, 0.2, 0.0], [0.0, 0.0, 0.8, 0.4], [0.0, 0.0, 0.0, 2.0]]
    )
    lw = normalize_log_weights(rng.normal(0.0, 0.5, n_particles))
    layout = StateLayout(blocks=(("pos", 2),), amb_keys=("a", "b"))
    return ParticleState(X, lw, 12.5, layout, pending_var=np.array([0.0, 0.0, 0.3, 0.0]))


def test_drop_ambiguities_is_the_marginal_of_the_summary():
    st_ = _cloud(1)
    dropped = st_.drop_ambiguities(["a", "zz"])  # an unknown key is ignored
    assert dropped.layout.amb_keys == ("b",)
    keep = [0, 1, 3]
    np.testing.assert_array_equal(dropped.particles, st_.particles[:, keep])
    np.testing.assert_array_equal(dropped.log_w, st_.log_w)
    np.testing.assert_array_equal(dropped.pending_var, st_.pending_var[keep])
    np.testing.assert_allclose(dropped.x, st_.x[keep], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(dropped.P, st_.P[np.ix_(keep, keep)], rtol=1e-12, atol=1e-12)
    assert st_.drop_ambiguities([]) is st_


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), var=st.floats(0.01, 100.0))
def test_add_ambiguities_draws_independent_components(seed, var):
    st_ = _cloud(seed % 1000)
    rng = np.random.default_rng(seed)
    mean = np.array([3.0, -7.0])
    added = st_.add_ambiguities(["c", "d"], mean, var, rng=rng)
    n = st_.n_particles
    assert added.layout.amb_keys == ("a", "b", "c", "d")
    np.testing.assert_array_equal(added.particles[:, :4], st_.particles)
    np.testing.assert_array_equal(added.log_w, st_.log_w)
    np.testing.assert_array_equal(added.pending_var, np.r_[st_.pending_var, 0.0, 0.0])
    new = added.particles[:, 4:]
    # unweighted moments of N independent draws: mean within 5 σ/√N, variance within 5 σ of
    # its sampling spread (σ² √(2/(N−1)))
    assert np.all(np.abs(new.mean(axis=0) - mean) < 5.0 * np.sqrt(var / n))
    assert np.all(np.abs(new.var(axis=0, ddof=1) - var) < 5.0 * var * np.sqrt(2.0 / (n - 1)))
    # independent of the existing components: sample correlations within 5/√N of zero
    c = np.corrcoef(np.hstack([st_.particles, new]).T)[:4, 4:]
    assert np.all(np.abs(c) < 5.0 / np.sqrt(n))
    # drop undoes add exactly
    back = added.drop_ambiguities(["c", "d"])
    np.testing.assert_array_equal(back.particles, st_.particles)
    assert back.layout == st_.layout


def test_add_ambiguities_is_reproducible_and_checks_its_input():
    st_ = _cloud(2, 500)
    a1 = st_.add_ambiguities(["c"], np.array([1.0]), 4.0)
    a2 = st_.add_ambiguities(["c"], np.array([1.0]), 4.0)
    np.testing.assert_array_equal(a1.particles, a2.particles)
    # a different time gives different draws
    a3 = st_.with_(t_s=13.5).add_ambiguities(["c"], np.array([1.0]), 4.0)
    assert not np.array_equal(a1.particles[:, -1], a3.particles[:, -1])
    # zero variance pins the component
    a0 = st_.add_ambiguities(["c"], np.array([2.5]), 0.0)
    np.testing.assert_array_equal(a0.particles[:, -1], 2.5)
    assert st_.add_ambiguities([], np.zeros(0), 1.0) is st_
    with pytest.raises(ValueError, match="variances"):
        st_.add_ambiguities(["c"], np.array([1.0]), -1.0)
    with pytest.raises(ValueError, match="finite"):
        st_.add_ambiguities(["c"], np.array([np.nan]), 1.0)
