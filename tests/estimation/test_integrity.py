"""The integrity monitor's pieces: snapshot, χ² test, widening, covariance floor, fix check."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk.estimation.integrity import (
    MAX_NORMAL_CONDITION,
    IntegrityMonitor,
    IntegrityPolicy,
    Snapshot,
    consistency,
    covariance_floor,
    fix_agrees,
    fixed_position_agrees,
    normal_condition,
    reinitialise,
    robust_snapshot,
    widening,
)
from robustrtk.estimation.state import GaussianState, StateLayout
from robustrtk.measurement.chi2 import chi2_ppf

ANCHORS = np.array(
    [[0, 0, 10], [20, 0, 12], [0, 20, 9], [20, 20, 11], [10, -5, 30], [-5, 10, 25], [10, 25, 3.0]]
)


def _ranges(x: np.ndarray) -> np.ndarray:
    return np.linalg.norm(ANCHORS - x[:3], axis=1)


def _jac(x: np.ndarray) -> np.ndarray:
    return -(ANCHORS - x[:3]) / _ranges(x)[:, None]


def _state(pos: np.ndarray, sigma: float) -> GaussianState:
    layout = StateLayout(blocks=(("pos", 3), ("vel", 3)))
    P = np.eye(6) * sigma**2
    return GaussianState(x=np.r_[pos, np.zeros(3)], P=P, t_s=0.0, layout=layout)


def test_snapshot_recovers_the_position_despite_one_gross_error() -> None:
    truth = np.array([7.0, 8.0, 1.5])
    z = _ranges(truth)
    z[2] += 15.0
    R = np.eye(len(z)) * 0.1**2
    snap = robust_snapshot(_ranges, _jac, z, R, np.array([5.0, 5.0, 5.0]), slice(0, 3))
    assert snap is not None
    assert np.linalg.norm(snap.pos_m - truth) < 0.3
    # without redundancy beyond the unknowns there is no snapshot
    assert robust_snapshot(_ranges, _jac, z[:3], R[:3, :3], np.zeros(3), slice(0, 3)) is None


def test_snapshot_covariance_grows_when_most_rows_are_wrong() -> None:
    truth = np.array([7.0, 8.0, 1.5])
    rng = np.random.default_rng(0)
    R = np.eye(len(ANCHORS)) * 0.1**2
    clean = robust_snapshot(_ranges, _jac, _ranges(truth), R, truth + 1.0, slice(0, 3))
    bad = _ranges(truth) + np.where(rng.random(len(ANCHORS)) < 0.7, rng.uniform(20, 80, len(ANCHORS)), 0.0)
    wrong = robust_snapshot(_ranges, _jac, bad, R, truth + 1.0, slice(0, 3))
    assert clean is not None and wrong is not None
    # the wrong fit does not pass for a precise one: its error stays within its own 3σ
    err = wrong.pos_m - truth
    assert float(err @ np.linalg.solve(wrong.cov_m2, err)) < chi2_ppf(0.999, 3)
    assert np.trace(wrong.cov_m2) > 100 * np.trace(clean.cov_m2)


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.floats(-50, 50), min_size=3, max_size=3),
    st.floats(0.01, 10.0),
    st.floats(0.01, 10.0),
)
def test_widening_makes_the_test_pass_at_its_threshold(d: list[float], sp: float, ss: float) -> None:
    prior = np.zeros(3)
    snap = Snapshot(np.asarray(d), np.eye(3) * ss**2)
    P = np.diag([sp**2, 2 * sp**2, 0.5 * sp**2])
    thr = chi2_ppf(0.999, 3)
    T = consistency(prior, P, snap)
    assert np.isclose(T, np.asarray(d) @ np.linalg.solve(P + snap.cov_m2, np.asarray(d)))
    s = widening(prior, P, snap, thr)
    if T <= thr:
        assert s <= 1.0 + 1e-9 or consistency(prior, P * s, snap) <= thr * (1 + 1e-6)
    else:
        assert consistency(prior, P * s, snap) <= thr * (1 + 1e-6)
        assert consistency(prior, P * s * 0.99, snap) > thr * (1 - 1e-6)


def test_monitor_widens_then_reinitialises_after_patience() -> None:
    mon = IntegrityMonitor(IntegrityPolicy(patience=3))
    snap = Snapshot(np.array([30.0, 0.0, 0.0]), np.eye(3) * 0.25)
    prior = _state(np.zeros(3), 0.1)
    kinds = []
    for _ in range(3):
        out, ev = mon.check(prior, snap)
        assert ev is not None
        kinds.append(ev.kind)
        if ev.kind == "inflate":
            assert consistency(out.x[:3], out.P[:3, :3], snap) <= mon.policy.threshold * (1 + 1e-6)
            assert out.P[3, 3] > prior.P[3, 3]  # the velocity is widened with the position
    assert kinds == ["inflate", "inflate", "reinit"]
    assert mon.counts["inflate"] == 2 and mon.counts["reinit"] == 1
    # a consistent prediction resets the run of failures
    _, ev = mon.check(_state(np.array([30.0, 0.1, 0.0]), 0.1), snap)
    assert ev is not None and ev.kind == "ok" and mon.failed == 0
    # the starting guess has no memory to widen: re-initialised at once
    _, ev = IntegrityMonitor().check(prior, snap, first=True)
    assert ev is not None and ev.kind == "reinit"
    re = reinitialise(prior, snap, 10.0)
    np.testing.assert_allclose(re.x[:3], snap.pos_m)
    np.testing.assert_allclose(re.P[:3, :3], snap.cov_m2)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 10_000))
def test_covariance_floor_is_above_both(seed: int) -> None:
    rng = np.random.default_rng(seed)
    A, B = rng.normal(size=(3, 3)), rng.normal(size=(3, 3))
    P = A @ A.T * 10.0 ** rng.uniform(-4, 2)
    C = B @ B.T + 1e-3 * np.eye(3)
    F = covariance_floor(P, C)
    assert np.min(np.linalg.eigvalsh(F - P)) > -1e-9 * np.max(np.abs(F))
    assert np.min(np.linalg.eigvalsh(F - C)) > -1e-9 * np.max(np.abs(F))


def test_fix_must_agree_with_the_snapshot() -> None:
    fixed = _state(np.array([0.01, 0.0, 0.0]), 0.002)
    snap = Snapshot(np.array([0.2, 0.1, -0.1]), np.eye(3) * 0.3**2)
    assert fix_agrees(fixed, snap) == ""
    # a fix metres from what the epoch's own code says is refused, whatever the float says
    far = Snapshot(np.array([3.0, 0.0, 0.0]), np.eye(3) * 0.3**2)
    assert "snapshot" in fix_agrees(fixed, far)
    # the boundary is the χ² quantile of P_fixed + C_s: just inside passes, just outside not
    thr = chi2_ppf(1.0 - 1e-3, 3)
    s2 = 0.3**2 + 0.002**2
    inside = Snapshot(np.array([0.01 + 0.999 * np.sqrt(thr * s2), 0.0, 0.0]), np.eye(3) * 0.3**2)
    outside = Snapshot(np.array([0.01 + 1.001 * np.sqrt(thr * s2), 0.0, 0.0]), np.eye(3) * 0.3**2)
    assert fix_agrees(fixed, inside) == "" and fix_agrees(fixed, outside) != ""
    assert fix_agrees(fixed, None) == ""
    # with the monitor on, a fix nothing independent can confirm is not reported
    assert "no snapshot" in fix_agrees(fixed, None, require=True)
    assert fix_agrees(fixed, snap, require=True) == ""


def test_unmodelled_covariance_is_the_stated_budget_along_the_local_axes() -> None:
    """8 mm + 1 ppm horizontally and 15 mm + 1 ppm vertically, whatever the frame."""
    from robustrtk.estimation.integrity import unmodelled_covariance

    up = np.array([1.0, 2.0, 2.0]) / 3.0
    C = unmodelled_covariance(5000.0, up * 6.4e6)
    assert np.isclose(up @ C @ up, (0.015 + 0.005) ** 2)
    east = np.cross([0.0, 0.0, 1.0], up)
    east /= np.linalg.norm(east)
    assert np.isclose(east @ C @ east, (0.008 + 0.005) ** 2)
    assert np.isclose(east @ C @ up, 0.0)


@settings(max_examples=100, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), rank=st.integers(1, 3))
def test_normal_condition_is_numpys_cond(seed: int, rank: int) -> None:
    """The condition number the snapshot tests, as ``np.linalg.cond`` gives it (a
    rank-deficient normal matrix included)."""
    rng = np.random.default_rng(seed)
    B = rng.normal(size=(3, rank))
    N = B @ B.T
    assert np.float64(normal_condition(N)).tobytes() == np.float64(np.linalg.cond(N)).tobytes()
    assert normal_condition(np.zeros((3, 3))) == np.inf == np.linalg.cond(np.zeros((3, 3)))


def test_fix_test_of_the_position_is_that_of_the_state() -> None:
    fixed = _state(np.array([0.01, 0.0, 0.0]), 0.002)
    p = fixed.layout.slice("pos")
    for s in (
        Snapshot(np.array([0.2, 0.1, -0.1]), np.eye(3) * 0.3**2),
        Snapshot(np.array([3.0, 0, 0]), np.eye(3) * 0.09),
        None,
    ):
        for req in (False, True):
            assert fixed_position_agrees(fixed.x[p], fixed.P[p, p], s, require=req) == fix_agrees(
                fixed, s, require=req
            )


@settings(max_examples=150, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), log_flat=st.floats(-12.0, 0.0))
def test_snapshot_refuses_exactly_the_geometries_over_the_condition_limit(seed: int, log_flat: float) -> None:
    """A linear snapshot (rows ``H x``) whose third direction is squeezed by ``10^log_flat``:
    a snapshot exactly when the normal matrix's condition number (``np.linalg.cond``) is
    within :data:`MAX_NORMAL_CONDITION`, whatever shortcut decides it, and then the
    covariance ``N⁻¹`` (no reweighting: exact rows)."""
    rng = np.random.default_rng(seed)
    H = rng.normal(size=(8, 3))
    H[:, 2] = H[:, 0] + 10.0**log_flat * H[:, 2]
    x_true = rng.normal(size=3)
    z = H @ x_true
    snap = robust_snapshot(lambda x: H @ x, lambda x: H, z, np.eye(8), np.zeros(3), slice(0, 3))
    N = H.T @ H
    cond = np.linalg.cond(N)
    assert (snap is not None) == (cond <= MAX_NORMAL_CONDITION)
    if snap is not None:
        C = np.linalg.inv(H.T @ H)
        np.testing.assert_allclose(snap.cov_m2, 0.5 * (C + C.T), rtol=1e-6, atol=0.0)
