"""Cooperative-positioning core: measurement rows and their Jacobians, eq. 25 variance,
the time update, the filters on one interface (the Kalman nodes are the project's one
Kalman update), eq. 24/29/30 inflation and
reset, Gauss–Newton, a brute-force check of the cooperative update."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk.core import CLIGHT
from robustrtk.estimation.coop import (
    KalmanNode,
    LocationTimeModel,
    PeerBroadcast,
    PeerWindow,
    RangeObservation,
    ResetSettings,
    clock_index,
    gauss_newton,
    make_node_filter,
    node_layout,
    peer_range_model,
    range_variance,
    reset_covariance,
)
from robustrtk.estimation.models import LinearMeasurement
from robustrtk.estimation.state import GaussianState
from robustrtk.geometry.los import OMEGA_E_RAD_S
from robustrtk.measurement.coop import (
    InterNodeRangeModel,
    PeerRangeModel,
    PseudorangeModel,
    zhou_code_variance,
)
from robustrtk.measurement.dd import StackedModel

RX = np.array([-3976219.19, 3382371.61, 3652511.14])


def _sats(rng: np.random.Generator, k: int) -> np.ndarray:
    """Satellites ~20 000 km above random directions of the upper hemisphere at RX."""
    up = RX / np.linalg.norm(RX)
    out = []
    while len(out) < k:
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        if d @ up > 0.3:
            out.append(RX + 2.2e7 * d)
    return np.array(out)


def _fd_jacobian(h, x, eps=1.0):
    f0 = h(x)
    J = np.zeros((f0.size, x.size))
    for j in range(x.size):
        e = np.zeros(x.size)
        e[j] = eps
        J[:, j] = (h(x + e) - h(x - e)) / (2 * eps)
    return J


def test_eq25_variance_in_metres():
    el = np.deg2rad([90.0, 30.0, 10.0, 2.0])
    cn0 = np.array([45.0, 45.0, 35.0, np.nan])
    v = zhou_code_variance(el, cn0, sigma0_m=3.0, cn0_ref_dbhz=45.0, elev_floor_rad=np.deg2rad(5.0))
    K = 9.0 * 10 ** (0.1 * 45.0)  # scale so the zenith at C/N0_ref has σ0
    expect = (
        K * 10 ** (-0.1 * np.array([45.0, 45.0, 35.0, 45.0])) / np.sin(np.maximum(el, np.deg2rad(5.0))) ** 2
    )
    np.testing.assert_allclose(v, expect, rtol=1e-12)
    assert v[0] == pytest.approx(9.0)
    assert v[1] == pytest.approx(36.0)
    # a C/N0 above the reference lowers the variance (no clamp)
    assert zhou_code_variance(np.pi / 2, 55.0, sigma0_m=3.0)[()] == pytest.approx(0.9)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_row_models_and_jacobians(seed):
    rng = np.random.default_rng(seed)
    sats = _sats(rng, 5)
    n = 9  # joint state: node a [p, b] at 0, node b [p, b] at 4, one spare
    x = np.r_[RX, 100.0, RX + rng.normal(scale=50.0, size=3), -30.0, 0.0]
    pr = PseudorangeModel(
        z=np.zeros(5), sat_pos_m=sats, var_m2=np.ones(5), clk_index=np.full(5, 3), pos_start=0, n_state=n
    )
    d = sats - RX
    sagnac = OMEGA_E_RAD_S * (sats[:, 0] * RX[1] - sats[:, 1] * RX[0]) / CLIGHT
    np.testing.assert_allclose(pr.h(x), np.linalg.norm(d, axis=1) + sagnac + 100.0, rtol=1e-14)
    peer = RX + np.array([[2000.0, -500.0, 2600.0]])
    rg = PeerRangeModel(z=np.zeros(1), peer_pos_m=peer, var_m2=np.ones(1), pos_start=4, n_state=n)
    inter = InterNodeRangeModel(
        z=np.zeros(1), var_m2=np.ones(1), pos_a=np.array([0]), pos_b=np.array([4]), n_state=n
    )
    for model, eps in ((pr, 1.0), (rg, 1e-2), (inter, 1e-3)):
        J = model.jacobian(x)
        np.testing.assert_allclose(J, _fd_jacobian(model.h, x, eps), atol=1e-6)
        # batch evaluation equals row by row
        X = x + rng.normal(size=(7, n))
        np.testing.assert_allclose(model.h(X), np.array([model.h(r) for r in X]), rtol=1e-14)
    np.testing.assert_allclose(inter.h(x), np.linalg.norm(x[:3] - x[4:7]), rtol=1e-14)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), dt=st.floats(0.1, 60.0), vel=st.booleans())
def test_node_prediction_is_the_linear_prediction(seed, dt, vel):
    rng = np.random.default_rng(seed)
    lay = node_layout(2, velocity=vel)
    n = lay.size
    A = rng.normal(size=(n, n))
    P = A @ A.T + np.eye(n)
    x = rng.normal(size=n)
    proc = LocationTimeModel(sigma_pos_m_s=0.3, sigma_clk_m_s=5.0, sigma_acc_m_s2=0.2)
    s = GaussianState(x, P, 10.0, lay)
    F, Q = proc.transition(lay, dt)
    W, Qw = proc.noise_input(lay, dt)
    np.testing.assert_allclose(Q, dt**2 * Qw)  # eq. 8: W = Δt I
    for alpha in (0.5, 1.0):
        u = KalmanNode("ukf", alpha=alpha).predict(s, proc, 10.0 + dt)
        np.testing.assert_allclose(u.x, F @ x, atol=1e-9)
        np.testing.assert_allclose(u.P, F @ P @ F.T + Q, rtol=1e-8, atol=1e-8)
        assert u.t_s == 10.0 + dt


def test_filters_share_interface_and_agree_on_linear_model():
    rng = np.random.default_rng(0)
    lay = node_layout(1)
    x0 = np.array([1.0, 2.0, 3.0, 4.0])
    P0 = np.diag([4.0, 4.0, 4.0, 9.0])
    H = rng.normal(size=(6, 4))
    R = np.eye(6) * 4.0
    z = H @ np.array([1.5, 1.0, 3.5, 10.0]) + rng.normal(scale=0.7, size=6)
    meas = LinearMeasurement(H, z, R, labels=tuple(f"r{i}" for i in range(6)))
    proc = LocationTimeModel(sigma_pos_m_s=0.1, sigma_clk_m_s=3.0)
    out = {}
    pf_params = {
        "n_particles": 200_000,
        "seed": 2,
        "ess_threshold": 0.0,
        "roughening": 0.0,
        "linear_idx": (3,),
    }
    ess = np.nan
    for kind, params in (("ekf", {}), ("ukf", {"alpha": 0.8}), ("pf", pf_params)):
        f = make_node_filter(kind, **params)
        b = f.init(GaussianState(x0, P0, 0.0, lay))
        b = f.predict(b, proc, 1.0)
        step = f.update(b, meas)
        assert step.ok and step.labels == meas.labels
        out[kind] = step.summary
        if kind == "pf":
            ess = step.ess
    np.testing.assert_allclose(out["ukf"].x, out["ekf"].x, atol=1e-9)
    np.testing.assert_allclose(out["ukf"].P, out["ekf"].P, atol=1e-9)
    sd = np.sqrt(np.diag(out["ekf"].P))
    assert 5000 < ess < 200_000
    # Monte Carlo error of a weighted mean: ~ sd / sqrt(ESS)
    np.testing.assert_array_less(np.abs(out["pf"].x - out["ekf"].x), 5 * sd / np.sqrt(ess))
    np.testing.assert_allclose(np.diag(out["pf"].P), np.diag(out["ekf"].P), rtol=10 / np.sqrt(ess))
    with pytest.raises(ValueError):
        make_node_filter("kalman")
    with pytest.raises(ValueError):
        KalmanNode("ukf", alpha=2.0)


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), alpha=st.sampled_from([0.3, 1.0]))
def test_node_corrections_are_the_estimation_filters(seed, alpha):
    """KalmanNode's correction is filters.EKF / filters.UKF (no robust policy) on the
    nonlinear cooperative rows, bit for bit: one Kalman update in the project."""
    from robustrtk.estimation.filters import EKF, UKF

    truth, pr, obs, bc, lay = _scene(seed % 1000, 5)
    rng = np.random.default_rng(seed)
    pr = PseudorangeModel(pr.z + rng.normal(0, 3, 5), pr.sat_pos_m, np.full(5, 9.0), pr.clk_index, 0, 4)
    rows = StackedModel((pr, peer_range_model(obs, bc, "improved", "ukf")))
    prior = GaussianState(
        truth + np.r_[rng.normal(0, 5, 3), 30.0], np.diag([25.0, 25.0, 25.0, 1e4]), 0.0, lay
    )
    for node, ref in (
        (KalmanNode("ekf"), EKF()),
        (KalmanNode("ukf", alpha=alpha), UKF(alpha=alpha, kappa=0.0)),
    ):
        a = node.update(prior, rows)
        b = ref.update(prior, rows)
        np.testing.assert_array_equal(a.summary.x, b.state.x)
        np.testing.assert_array_equal(a.summary.P, b.state.P)
        np.testing.assert_array_equal(a.innovation, b.innovation)


def test_range_variance_inflation_and_reset():
    b = PeerBroadcast("n1", 0.0, np.r_[RX, 0.0], np.diag([4.0, 9.0, 1.0, 50.0]))
    fixed = PeerWindow(ResetSettings(sigma_set_m=2.0, sigma_wset_m_s=0.5))
    assert range_variance(0.01, b, "traditional", "ekf", fixed) == 0.01
    # eq. 24 with eq. 29: σ² + tr(σ_set² I₄)
    assert range_variance(0.01, b, "improved", "ekf", fixed) == pytest.approx(0.01 + 4 * 4.0)
    assert range_variance(0.01, b, "improved", "pf", fixed) == pytest.approx(0.01 + 4 * 4.0)
    # eq. 30: the UKF's noise block adds σ_wset² Δt² per component
    assert range_variance(0.01, b, "improved", "ukf", fixed, dt_s=30.0) == pytest.approx(
        0.01 + 4 * 4.0 + 4 * 0.25 * 900.0
    )
    np.testing.assert_array_equal(reset_covariance(4.0, "ekf"), 4.0 * np.eye(4))
    np.testing.assert_array_equal(reset_covariance(4.0, "ukf", 0.25), np.diag([4.0] * 4 + [0.25] * 4))
    with pytest.raises(ValueError):
        range_variance(0.01, b, "off", "ekf", fixed)


def test_short_window_estimates():
    rng = np.random.default_rng(5)
    win = PeerWindow(ResetSettings(window=6, sigma_set_floor_m=0.01, sigma_wset_floor_m_s=0.001))
    assert win.sigma_set2_m2() == pytest.approx(1e-4)
    pos = RX + rng.normal(scale=3.0, size=(10, 3))
    for k, p in enumerate(pos):
        win.push(PeerBroadcast("n1", 30.0 * k, np.r_[p, 0.0], np.eye(4)))
    last = pos[-6:]
    assert win.sigma_set2_m2() == pytest.approx(np.mean(np.var(last, axis=0, ddof=1)))
    rate = np.diff(last, axis=0) / 30.0
    assert win.sigma_wset2_m2_s2() == pytest.approx(np.mean(np.var(rate, axis=0, ddof=1)))
    # a still peer gives the floors
    still = PeerWindow(ResetSettings(sigma_set_floor_m=0.5, sigma_wset_floor_m_s=0.02))
    for k in range(5):
        still.push(PeerBroadcast("n1", float(k), np.r_[RX, 0.0], np.eye(4)))
    assert still.sigma_set2_m2() == pytest.approx(0.25)
    assert still.sigma_wset2_m2_s2() == pytest.approx(4e-4)


def _scene(seed: int, n_sats: int):
    rng = np.random.default_rng(seed)
    sats = _sats(rng, n_sats)
    truth = np.r_[RX, 1234.5]
    peer = RX + np.array([2022.8, -468.6, 2610.3])
    lay = node_layout(1)
    clk = clock_index(lay, ["G"])
    pr_true = PseudorangeModel(np.zeros(n_sats), sats, np.ones(n_sats), np.full(n_sats, clk["G"]), 0, 4)
    z = pr_true.h(truth)
    pr = PseudorangeModel(z, sats, np.full(n_sats, 1e-4), np.full(n_sats, clk["G"]), 0, 4)
    rng_m = float(np.linalg.norm(RX - peer))
    obs = [RangeObservation("n1", rng_m, 1e-4)]
    bc = {"n1": PeerBroadcast("n1", 0.0, np.r_[peer, 0.0], np.eye(4) * 1e-4)}
    return truth, pr, obs, bc, lay


def test_gauss_newton_three_satellites_need_the_range():
    truth, pr, obs, bc, lay = _scene(3, 3)
    x0 = np.r_[RX + np.array([30.0, -20.0, 15.0]), 0.0]
    alone = gauss_newton(pr, x0)
    assert not alone.ok  # 3 rows, 4 unknowns
    rows = StackedModel((pr, peer_range_model(obs, bc, "traditional", "ls")))
    coop = gauss_newton(rows, x0)
    assert coop.ok
    np.testing.assert_allclose(coop.state.x, truth, atol=1e-3)
    off = peer_range_model(obs, bc, "off", "ls")
    assert off.z.size == 0


def test_cooperative_ekf_update_matches_brute_force_posterior():
    """Node 2 with three satellites and a range: the EKF posterior mean of one update
    equals the minimiser of the MAP objective found by brute-force Gauss–Newton on the
    stacked [prior; rows] system (the rows are nearly linear over metres)."""
    truth, pr, obs, bc, lay = _scene(8, 3)
    pr = PseudorangeModel(pr.z, pr.sat_pos_m, np.full(3, 4.0), pr.clk_index, 0, 4)
    obs = [RangeObservation("n1", obs[0].range_m, 0.01)]
    rows = StackedModel((pr, peer_range_model(obs, bc, "traditional", "ekf")))
    x0 = truth + np.array([3.0, -2.0, 1.0, 5.0])
    P0 = np.diag([25.0, 25.0, 25.0, 400.0])
    step = KalmanNode("ekf").update(GaussianState(x0, P0, 0.0, lay), rows)
    prior_rows = LinearMeasurement(np.eye(4), x0, P0, labels=("p0", "p1", "p2", "p3"))
    aug = StackedModel((prior_rows, rows))
    map_ = gauss_newton(aug, x0)
    np.testing.assert_allclose(step.summary.x, map_.state.x, atol=0.05)
    np.testing.assert_allclose(step.summary.P, map_.state.P, rtol=0.02, atol=1e-6)
