"""The LAMBDA kernels used by PAR and validation are public and give the results of the
documented entry points (``lambda_search``, ``decorrelate``)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk.ambiguity.lambda_ import check_q, decorrelate, ils_search, lambda_search, ltdl, reduce_ops


def _q(rng: np.random.Generator, n: int) -> np.ndarray:
    A = rng.normal(size=(n, n))
    return A @ A.T + 0.05 * np.eye(n)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 7))
def test_ils_search_equals_lambda_search(seed: int, n: int) -> None:
    rng = np.random.default_rng(seed)
    Q = _q(rng, n)
    a = rng.normal(size=n) * 5
    F, s, d = ils_search(a, check_q(Q, n), 2)
    F2, s2 = lambda_search(a, Q, 2)
    np.testing.assert_array_equal(F, F2)
    np.testing.assert_array_equal(s, s2)
    # d are the decorrelated conditional variances: prod(d) = det(Q) (Z unimodular)
    np.testing.assert_allclose(np.prod(d), np.linalg.det(Q), rtol=1e-8)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 7))
def test_reduce_ops_gives_the_decorrelated_factors(seed: int, n: int) -> None:
    rng = np.random.default_rng(seed)
    Q = _q(rng, n)
    ops, L, d = reduce_ops(*ltdl(Q))
    Z, Lz, dz, _ = decorrelate(Q, np.zeros(n))
    np.testing.assert_array_equal(L, Lz)
    np.testing.assert_array_equal(d, dz)
    np.testing.assert_allclose(Z.T @ Q @ Z, L.T @ np.diag(d) @ L, rtol=1e-8, atol=1e-9)
    assert all(isinstance(op, tuple) and len(op) == 3 for op in ops)


def test_check_q_rejects_bad_input_and_symmetrises() -> None:
    with pytest.raises(ValueError, match="square"):
        check_q(np.ones(3))
    with pytest.raises(ValueError, match="length 2"):
        check_q(np.eye(3), 2)
    with pytest.raises(ValueError, match="symmetric"):
        check_q(np.array([[1.0, 0.5], [0.0, 1.0]]))
    q = np.array([[2.0, 1.0], [1.0 + 1e-12, 3.0]])
    np.testing.assert_array_equal(check_q(q), check_q(q).T)
