"""The compiled LAMBDA kernels against their pure-Python references (the oracles).

Same inputs, same outputs: the reduction's operations and factors and the search's candidates
exactly, the LᵀDL factors to rounding (LAPACK's Cholesky against the kernel's elimination),
the errors with the same types and messages.
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk import jit
from robustrtk.ambiguity import lambda_ as lm

pytest.importorskip("numba")

DATA = Path(__file__).parent / "data" / "ill_conditioned_26.npz"


@pytest.fixture(autouse=True, scope="module")
def _compiled_kernels() -> Iterator[None]:
    """These tests are about the numba path: the policy is forced on (algorithms.md §27) and
    the C kernels, which would serve first when built, are set aside
    (tests/ambiguity/test_lambda_ckernels.py checks those)."""
    with pytest.MonkeyPatch.context() as mp, jit.use("on"):
        mp.setenv("ROBUSTRTK_LAMBDA_BACKEND", "numba")
        jit.refresh()
        yield


@pytest.fixture(params=["numba", "c"])
def backend(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> str:
    """The public entry points on the numba kernels, then on the C kernels (when built)."""
    if request.param == "c":
        try:
            from robustrtk.ambiguity import lambda_ckernels  # noqa: F401
        except ImportError as err:
            pytest.skip(f"C LAMBDA kernels not built ({err})")
    monkeypatch.setenv("ROBUSTRTK_LAMBDA_BACKEND", request.param)
    jit.refresh()
    return str(request.param)


def _q(rng: np.random.Generator, n: int, cond: float) -> np.ndarray:
    """SPD matrix with eigenvalues log-spread over ``cond`` and a random rotation."""
    U, _ = np.linalg.qr(rng.normal(size=(n, n)))
    ev = np.geomspace(1e-3, 1e-3 * cond, n)
    Q = (U * ev) @ U.T
    return 0.5 * (Q + Q.T)


def test_kernels_are_on() -> None:
    assert lm.kernels() is not None


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 30), log_cond=st.floats(0.0, 6.0))
def test_kernel_equals_pure_on_random_problems(seed: int, n: int, log_cond: float) -> None:
    rng = np.random.default_rng(seed)
    Q = _q(rng, n, 10.0**log_cond)
    a = rng.normal(size=n) * 50.0
    L, d = lm.ltdl(Q)
    Lp, dp = lm.ltdl_py(Q)
    np.testing.assert_allclose(d, dp, rtol=1e-9)
    np.testing.assert_allclose(L, Lp, rtol=0, atol=1e-9 * max(1.0, float(np.abs(Lp).max())))
    # same input factors: the reduction is the same arithmetic in the same order
    ops, Lr, dr = lm.reduce_ops(Lp, dp)
    ops_p, Lr_p, dr_p = lm.reduce_ops_py(Lp, dp)
    assert ops == ops_p
    assert all(type(v) is int for op in ops for v in op)
    np.testing.assert_array_equal(Lr, Lr_p)
    np.testing.assert_array_equal(dr, dr_p)
    z = rng.normal(size=n) * 3.0
    for m in (1, 2, 4):
        try:
            Zp, sp = lm.search_py(Lr_p, dr_p, z, m)
        except lm.SearchLimitError as err:  # a weak random problem: both give up alike
            with pytest.raises(lm.SearchLimitError, match=re.escape(str(err))):
                lm.search(Lr_p, dr_p, z, m)
            continue
        Zk, sk = lm.search(Lr_p, dr_p, z, m)
        np.testing.assert_array_equal(Zk, Zp)
        np.testing.assert_array_equal(sk, sp)
    # whole pipeline: candidates identical, norms to rounding
    try:
        Fp, s_p = lm.lambda_search_py(a, Q, 2)
    except lm.SearchLimitError:
        with pytest.raises(lm.SearchLimitError):
            lm.lambda_search(a, Q, 2)
        return
    F, s = lm.lambda_search(a, Q, 2)
    np.testing.assert_array_equal(F, Fp)
    np.testing.assert_allclose(s, s_p, rtol=1e-7, atol=1e-12)
    Fi, si, di = lm.ils_search(a, lm.check_q(Q), 2, (ops_p, Lr_p, dr_p))
    Fi_p, si_p, di_p = lm.ils_search_py(a, lm.check_q(Q), 2, (ops_p, Lr_p, dr_p))
    np.testing.assert_array_equal(Fi, Fi_p)
    np.testing.assert_array_equal(si, si_p)
    np.testing.assert_array_equal(di, di_p)


def test_kernel_equals_pure_on_the_ill_conditioned_receiver_set(backend: str) -> None:
    data = np.load(DATA)
    a, Q = data["a"], data["Q"]
    L0, d0 = lm.ltdl_py(Q)
    ops, L, d = lm.reduce_ops(L0, d0)
    assert ops == lm.reduce_ops_py(L0, d0)[0]
    Z, Zinv = lm._ops_to_z(a.size, ops)
    assert np.array_equal(Z @ Zinv, np.eye(a.size))  # unimodular, exactly
    assert np.allclose(L.T @ np.diag(d) @ L, Z.T @ Q @ Z, rtol=0, atol=1e-12)
    F, s = lm.lambda_search(a, Q, 2)
    Fp, sp = lm.lambda_search_py(a, Q, 2)
    np.testing.assert_array_equal(F, Fp)
    np.testing.assert_allclose(s, sp, rtol=1e-7)


def test_kernel_equals_pure_on_the_reference_vectors(shared_data: Path, backend: str) -> None:
    with open(shared_data / "testvectors" / "testvectors.json") as fh:
        vec = json.load(fh)
    n_cases = 0
    for case in vec.values():
        if not isinstance(case, dict) or "Q" not in case:
            continue
        a = np.asarray(case["a_float"], float).reshape(-1)
        Q = np.asarray(case["Q"], float)
        F, s = lm.lambda_search(a, Q, 2)
        Fp, sp = lm.lambda_search_py(a, Q, 2)
        np.testing.assert_array_equal(F, Fp)
        np.testing.assert_allclose(s, sp, rtol=1e-7)
        n_cases += 1
    assert n_cases >= 3


@pytest.mark.parametrize(
    ("a", "Q", "exc", "msg"),
    [
        ([np.nan, 0.0], np.eye(2), ValueError, "a_float contains NaN"),
        ([0.0, 0.0], [[1.0, np.inf], [np.inf, 1.0]], ValueError, "Q contains NaN"),
        ([0.0, 0.0], [[1.0, 0.5], [0.4, 1.0]], ValueError, "Q must be symmetric"),
        ([0.0, 0.0], [[1.0, 2.0], [2.0, 1.0]], ValueError, "not positive definite"),
        ([0.0, 0.0], [[-1.0, 0.0], [0.0, 1.0]], ValueError, "not positive definite"),
        ([0.0], np.eye(2), ValueError, "float vector has length 1"),
        ([0.0, 0.0], np.ones(2), ValueError, "square"),
    ],
)
def test_errors_match_the_pure_path(
    a: list[float], Q: object, exc: type[Exception], msg: str, backend: str
) -> None:
    with pytest.raises(exc, match=msg):
        lm.lambda_search_py(a, Q, 2)  # type: ignore[arg-type]
    with pytest.raises(exc, match=msg):
        lm.lambda_search(a, Q, 2)  # type: ignore[arg-type]


def test_search_cap_is_reported_the_same_way(backend: str) -> None:
    n = 12
    Q = np.eye(n) * 1e6  # ~1e3 cycles of spread: astronomically many points per level
    a = np.full(n, 0.5)
    L, d = lm.ltdl(Q)
    for fn in (lm.search, lm.search_py):
        with pytest.raises(lm.SearchLimitError, match="exceeded 50 nodes"):
            fn(L, d, a, 2, max_nodes=50)


def test_pure_fallback_when_kernels_are_off(monkeypatch: pytest.MonkeyPatch) -> None:
    rng = np.random.default_rng(3)
    Q = _q(rng, 8, 1e3)
    a = rng.normal(size=8) * 4
    F_k, s_k = lm.lambda_search(a, Q, 2)
    monkeypatch.setattr(lm, "_KERNELS", [None])
    assert lm.kernels() is None
    F_p, s_p = lm.lambda_search(a, Q, 2)
    np.testing.assert_array_equal(F_k, F_p)
    np.testing.assert_allclose(s_k, s_p, rtol=1e-9)
