"""State operations as methods: a unimodular re-reference map keeps integers integer and
det P; the conditional update equals brute-force Gaussian conditioning (and the ambiguity
wrapper); the hold constraint is bit-identical to the explicit EKF update; GaussianState
satisfies the State protocol."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk.ambiguity.par import conditional_update
from robustrtk.estimation.filters import EKF
from robustrtk.estimation.models import LinearMeasurement
from robustrtk.estimation.state import GaussianState, State, StateLayout


def _spd(rng: np.random.Generator, n: int, scale: float = 1.0) -> np.ndarray:
    A = rng.normal(size=(n, n))
    return scale * (A @ A.T + 0.2 * n * np.eye(n))


def _state(rng: np.random.Generator, n_amb: int) -> GaussianState:
    keys = tuple(("G", j) for j in range(1, n_amb + 1))  # DD G_j − G_0 (reference G_0)
    layout = StateLayout(blocks=(("pos", 3),), amb_keys=keys)
    n = layout.size
    x = rng.normal(size=n)
    x[3:] = rng.integers(-50, 50, size=n_amb).astype(float)
    return GaussianState(x, _spd(rng, n), 12.5, layout)


def _rereference(layout: StateLayout, new_ref: int) -> tuple[np.ndarray, StateLayout]:
    """DD ambiguities ``N_j − N_0`` (j = 1..k) re-expressed against satellite ``new_ref``:
    ``N_j − N_r = (N_j − N_0) − (N_r − N_0)`` and ``N_0 − N_r = −(N_r − N_0)``."""
    k = len(layout.amb_keys)
    nf = layout.n_fixed
    T = np.eye(layout.size)
    r = nf + new_ref - 1  # row of N_r − N_0
    new_keys = []
    for j in range(1, k + 1):
        row = nf + j - 1
        if j == new_ref:
            T[row, :] = 0.0
            T[row, r] = -1.0
            new_keys.append(("G", 0))
        else:
            T[row, r] -= 1.0
            new_keys.append(("G", j))
    return T, StateLayout(blocks=layout.blocks, amb_keys=tuple(new_keys))


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), k=st.integers(1, 6), data=st.data())
def test_rereference_is_unimodular_keeps_integers_and_det(seed: int, k: int, data: st.DataObject) -> None:
    rng = np.random.default_rng(seed)
    s0 = _state(rng, k)
    ref = data.draw(st.integers(1, k))
    T, lay = _rereference(s0.layout, ref)
    s1 = s0.transform(T, lay)
    assert round(abs(np.linalg.det(T))) == 1
    assert s1.layout == lay and s1.t_s == s0.t_s
    a = s1.x[3:]
    np.testing.assert_array_equal(a, np.round(a))
    np.testing.assert_allclose(np.linalg.det(s1.P), np.linalg.det(s0.P), rtol=1e-8)
    np.testing.assert_array_equal(s1.P, s1.P.T)
    np.testing.assert_array_equal(s1.get("pos"), s0.get("pos"))
    # the inverse map is integer too: back to the old reference restores the state
    back = np.linalg.inv(T)
    np.testing.assert_array_equal(back, np.round(back))
    s2 = s1.transform(np.round(back), s0.layout)
    np.testing.assert_allclose(s2.x, s0.x, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(s2.P, s0.P, rtol=1e-9, atol=1e-10)


def test_transform_checks_shapes() -> None:
    s0 = _state(np.random.default_rng(0), 2)
    with pytest.raises(ValueError):
        s0.transform(np.eye(4))
    with pytest.raises(ValueError, match="layout"):
        s0.transform(np.eye(5)[:4])  # 4 rows, layout still has 5 states
    s1 = s0.transform(np.eye(5)[:4], StateLayout(blocks=(("pos", 3),), amb_keys=(("G", 1),)))
    np.testing.assert_array_equal(s1.x, s0.x[:4])


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), k=st.integers(1, 6), data=st.data())
def test_conditional_update_equals_brute_force_conditioning(seed: int, k: int, data: st.DataObject) -> None:
    rng = np.random.default_rng(seed)
    s0 = _state(rng, k)
    n = s0.n
    f = np.array(sorted(data.draw(st.sets(st.integers(0, n - 1), min_size=1, max_size=n - 1))))
    v = np.round(s0.x[f] + rng.normal(size=f.size))
    s1 = s0.conditional_update(f, v)
    # brute force: joint Gaussian, partition into free (u) and fixed (f) by explicit inverse
    u = np.setdiff1d(np.arange(n), f)
    Puu, Puf, Pff = s0.P[np.ix_(u, u)], s0.P[np.ix_(u, f)], s0.P[np.ix_(f, f)]
    G = Puf @ np.linalg.inv(Pff)
    np.testing.assert_allclose(s1.x[u], s0.x[u] + G @ (v - s0.x[f]), rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(s1.P[np.ix_(u, u)], Puu - G @ Puf.T, rtol=1e-8, atol=1e-9)
    np.testing.assert_array_equal(s1.x[f], v)
    assert np.all(s1.P[f, :] == 0.0) and np.all(s1.P[:, f] == 0.0)
    assert s1.layout == s0.layout and s1.t_s == s0.t_s
    # the ambiguity wrapper gives the same numbers
    xc, Pc = conditional_update(s0.x, s0.P, f, v)
    np.testing.assert_array_equal(xc, s1.x)
    np.testing.assert_array_equal(Pc, s1.P)


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    k=st.integers(1, 6),
    sigma=st.sampled_from([1e-3, 0.01, 0.5]),
    data=st.data(),
)
def test_constrain_is_bit_identical_to_the_explicit_ekf_update(
    seed: int, k: int, sigma: float, data: st.DataObject
) -> None:
    rng = np.random.default_rng(seed)
    s0 = _state(rng, k)
    n = s0.n
    idx = np.array(data.draw(st.lists(st.integers(3, n - 1), min_size=1, max_size=k, unique=True)))
    values = np.round(s0.x[idx] + rng.normal(size=idx.size))
    H = np.zeros((idx.size, n))
    H[np.arange(idx.size), idx] = 1.0
    ref = EKF().update(s0, LinearMeasurement(H, np.asarray(values, float), np.eye(idx.size) * sigma**2)).state
    got = s0.constrain(idx, values, sigma)
    np.testing.assert_array_equal(got.x, ref.x)
    np.testing.assert_array_equal(got.P, ref.P)
    assert got.layout == s0.layout and got.t_s == s0.t_s
    # a per-row sigma equal to the scalar gives the same result (diag R)
    vec = s0.constrain(idx, values, np.full(idx.size, sigma))
    np.testing.assert_allclose(vec.x, ref.x, rtol=1e-12, atol=1e-12)
    # a tight hold pulls the constrained components to the values
    tight = s0.constrain(idx, values, 1e-6)
    np.testing.assert_allclose(tight.x[idx], values, atol=1e-6)


def test_constrain_nothing_is_a_no_op() -> None:
    s0 = _state(np.random.default_rng(1), 2)
    s1 = s0.constrain(np.zeros(0, dtype=int), np.zeros(0), 0.01)
    np.testing.assert_array_equal(s1.x, s0.x)
    np.testing.assert_array_equal(s1.P, s0.P)


def test_gaussian_state_is_a_state() -> None:
    s0 = _state(np.random.default_rng(2), 2)
    assert isinstance(s0, State)
    st_: State = s0  # static check (mypy): GaussianState satisfies the protocol
    assert st_.n == 5
    dropped = st_.drop_ambiguities([("G", 1)]).add_ambiguities([("G", 9)], np.array([3.0]), 100.0)
    assert dropped.layout.amb_keys == (("G", 2), ("G", 9))


def test_cholesky_solve_matches_scipy_cho_solve() -> None:
    """The numpy substitution that replaced scipy's cho_solve, on random SPD systems."""
    import scipy.linalg

    from robustrtk.estimation.gaussian import cholesky_solve

    rng = np.random.default_rng(7)
    for m in (1, 2, 5, 17, 40):
        A = rng.normal(size=(m, m))
        S = A @ A.T + m * np.eye(m)
        L = np.linalg.cholesky(S)
        for B in (rng.normal(size=m), rng.normal(size=(m, 3))):
            ref = scipy.linalg.cho_solve(scipy.linalg.cho_factor(S, lower=True), B)
            got = cholesky_solve(L, B)
            assert got.shape == np.shape(B)
            np.testing.assert_allclose(got, ref, rtol=1e-10, atol=1e-12)
            np.testing.assert_allclose(S @ got, B, rtol=1e-9, atol=1e-10)


def test_condition_on_refuses_non_finite_and_indefinite_blocks() -> None:
    from robustrtk.estimation.gaussian import condition_on

    P = np.diag([1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="positive definite"):
        condition_on(np.zeros(3), np.diag([1.0, -2.0, 3.0]), [0, 1], [0.0, 0.0])
    bad = P.copy()
    bad[1, 1] = np.nan
    with pytest.raises(ValueError, match="finite"):
        condition_on(np.zeros(3), bad, [1], [0.0])


def test_with_is_dataclasses_replace() -> None:
    """``with_`` builds what ``dataclasses.replace`` builds, and refuses unknown fields."""
    import dataclasses

    s = GaussianState(np.arange(3.0), np.eye(3), 2.0, StateLayout(blocks=(("pos", 3),)))
    for kw in ({}, {"x": np.ones(3)}, {"P": 2 * np.eye(3), "t_s": 5.0}, {"layout": s.layout}):
        a, b = s.with_(**kw), dataclasses.replace(s, **kw)  # type: ignore[arg-type]
        assert a.t_s == b.t_s and a.layout == b.layout and a.x is b.x and a.P is b.P
    with pytest.raises(TypeError, match="unknown"):
        s.with_(q=1.0)
