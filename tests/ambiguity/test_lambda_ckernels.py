"""The C LAMBDA kernels (``lambda_ckernels``) against the pure-Python references of
``lambda_pure`` (the oracles).

Same inputs, same outputs: the reduction's operations and factors and the search's candidates
exactly, the LᵀDL factors to rounding (LAPACK's Cholesky against the kernel's elimination),
the errors with the same types and messages; on random problems, on an ill-conditioned real
receiver set and on the shared reference vectors.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk.ambiguity import lambda_ as lm
from robustrtk.ambiguity import lambda_pure as lp

try:
    from robustrtk.ambiguity import lambda_ckernels as ck
except ImportError as err:  # the optional library was not built
    pytest.skip(
        f"C LAMBDA kernels not built ({err}); build them with `python setup.py build_ext --inplace`",
        allow_module_level=True,
    )

DATA = Path(__file__).parent / "data" / "ill_conditioned_26.npz"
#: The directory holding the ``robustrtk`` this test imported (an installed copy carries the
#: built library; a source tree has it only after ``build_ext --inplace``).
PKG_PARENT = Path(lm.__file__).resolve().parents[2]


@pytest.fixture(autouse=True)
def _c_backend(monkeypatch: pytest.MonkeyPatch) -> None:
    """The public entry points on the C kernels (the default whenever they are built)."""
    _use(monkeypatch, "c")


def _use(monkeypatch: pytest.MonkeyPatch, value: str | None) -> None:
    """Set ``ROBUSTRTK_LAMBDA_BACKEND`` (None: unset) and read it, as a run does when it begins."""
    if value is None:
        monkeypatch.delenv("ROBUSTRTK_LAMBDA_BACKEND", raising=False)
    else:
        monkeypatch.setenv("ROBUSTRTK_LAMBDA_BACKEND", value)
    lm.backend()


def _q(rng: np.random.Generator, n: int, cond: float) -> np.ndarray:
    """SPD matrix with eigenvalues log-spread over ``cond`` and a random rotation."""
    U, _ = np.linalg.qr(rng.normal(size=(n, n)))
    ev = np.geomspace(1e-3, 1e-3 * cond, n)
    Q = (U * ev) @ U.T
    return 0.5 * (Q + Q.T)


def test_the_c_kernels_serve_by_default(monkeypatch: pytest.MonkeyPatch) -> None:
    _use(monkeypatch, None)
    assert lm.kernels() is ck
    _use(monkeypatch, "auto")
    assert lm.kernels() is ck


def test_backend_variable(monkeypatch: pytest.MonkeyPatch) -> None:
    assert lm.kernels() is ck
    _use(monkeypatch, "pure")
    assert lm.kernels() is None
    for bad in ("numba", "fortran"):
        monkeypatch.setenv("ROBUSTRTK_LAMBDA_BACKEND", bad)
        with pytest.raises(ValueError, match=f"ROBUSTRTK_LAMBDA_BACKEND='{bad}': expected auto, c or pure"):
            lm.backend()
    assert lm.kernels() is None  # a refused value leaves the one read before


def test_a_changed_variable_takes_effect_when_it_is_read_again(monkeypatch: pytest.MonkeyPatch) -> None:
    assert lm.kernels() is ck
    monkeypatch.setenv("ROBUSTRTK_LAMBDA_BACKEND", "pure")
    assert lm.kernels() is ck  # the value read when the run began
    lm.backend()  # the next run
    assert lm.kernels() is None


def test_the_kernels_passed_on_give_the_numbers_of_a_look_up_per_call() -> None:
    rng = np.random.default_rng(2)
    Q = _q(rng, 7, 1e4)
    a = rng.normal(0.0, 3.0, 7)
    ops, L, d = lm.reduce_q(Q)
    ops2, L2, d2 = lm.reduce_q(lm.check_q(Q), checked=True, kern=ck)
    np.testing.assert_array_equal(ops2, ops)
    np.testing.assert_array_equal(L2, L)
    np.testing.assert_array_equal(d2, d)
    F, s, _ = lm.ils_search(a, lm.check_q(Q), 2, (ops, L, d))
    F2, s2, _ = lm.ils_search(a, lm.check_q(Q), 2, (ops, L, d), kern=ck)
    np.testing.assert_array_equal(F2, F)
    np.testing.assert_array_equal(s2, s)
    assert s[0] <= s[1]


def test_pure_backend_gives_the_c_backends_results(monkeypatch: pytest.MonkeyPatch) -> None:
    rng = np.random.default_rng(3)
    Q = _q(rng, 8, 1e3)
    a = rng.normal(size=8) * 4
    F_k, s_k = lm.lambda_search(a, Q, 2)
    ops_k, L_k, d_k = lm.reduce_q(Q)
    _use(monkeypatch, "pure")
    assert lm.kernels() is None
    F_p, s_p = lm.lambda_search(a, Q, 2)
    ops_p, L_p, d_p = lm.reduce_q(Q)
    np.testing.assert_array_equal(F_k, F_p)
    np.testing.assert_allclose(s_k, s_p, rtol=1e-9)
    np.testing.assert_array_equal(ops_k, ops_p)
    np.testing.assert_allclose(d_k, d_p, rtol=1e-9)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 30), log_cond=st.floats(0.0, 6.0))
def test_c_kernels_equal_pure_on_random_problems(seed: int, n: int, log_cond: float) -> None:
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
    ops_a, Lq, dq = lm.reduce_q(Q)
    assert ops_a.dtype == np.int64 and ops_a.shape == (len(lm.reduce_ops(L, d)[0]), 3)
    # a room too small is reported as such, then enough room gives the same numbers
    if ops_p:
        assert ck.reduce_into_k(Lp, dp, len(ops_p) - 1)[1] == -1
        o2, k2, L2, d2 = ck.reduce_into_k(Lp, dp, len(ops_p))
        assert k2 == len(ops_p) and o2.tolist() == [list(op) for op in ops_p]
        np.testing.assert_array_equal(L2, Lr_p)
        np.testing.assert_array_equal(d2, dr_p)
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
    # the back-transforms
    ops_arr = np.array(ops_p, dtype=np.int64).reshape(-1, 3)
    np.testing.assert_array_equal(ck.apply_zt_k(ops_arr, a), lp.apply_zt(ops_p, a))
    V = rng.normal(size=(n, 3))
    np.testing.assert_array_equal(ck.apply_zinvt_k(ops_arr, V), lp.apply_zinvt(ops_p, V))
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


def test_error_codes() -> None:
    cases = [
        (np.array([np.nan, 0.0]), np.eye(2), ck.NONFINITE_A),
        (np.zeros(2), np.array([[1.0, np.inf], [np.inf, 1.0]]), ck.NONFINITE_Q),
        (np.zeros(2), np.array([[1.0, 0.5], [0.4, 1.0]]), ck.ASYMMETRIC_Q),
        (np.zeros(2), np.array([[1.0, 2.0], [2.0, 1.0]]), ck.NOT_PD),
        (np.full(12, 0.5), np.eye(12) * 1e6, ck.SEARCH_LIMIT),
    ]
    for a, Q, code in cases:
        assert ck.lambda_all(a, Q, 2, 50)[2] == code
    assert ck.ltdl_k(np.array([[1.0, 2.0], [2.0, 1.0]]))[2] == ck.NOT_PD


def test_bad_sizes_and_operations_raise_instead_of_reading_out_of_bounds() -> None:
    with pytest.raises(ValueError, match="shape"):
        ck.search_k(np.eye(3), np.ones(2), np.zeros(2), 2, 100)
    with pytest.raises(ValueError, match="m must be >= 1"):
        ck.lambda_all(np.zeros(2), np.eye(2), 0, 100)
    with pytest.raises(ValueError, match="at least one ambiguity"):
        ck.lambda_all(np.zeros(0), np.zeros((0, 0)), 2, 100)
    with pytest.raises(ValueError, match="do not index"):
        ck.apply_zt_k(np.array([[1, -1, 0]]), np.zeros(2))  # swap of 1 and 2 in a 2-vector
    with pytest.raises(ValueError, match="do not index"):
        ck.ils_from_reduced_k(np.zeros(2), np.array([[0, 5, 1]]), np.eye(2), np.ones(2), 2, 100)


def test_kernel_equals_pure_on_the_ill_conditioned_receiver_set() -> None:
    data = np.load(DATA)
    a, Q = data["a"], data["Q"]
    L0, d0 = lm.ltdl_py(Q)
    ops, L, d = lm.reduce_ops(L0, d0)
    assert ops == lm.reduce_ops_py(L0, d0)[0]
    Z, Zinv = lp.ops_to_z(a.size, ops)
    assert np.array_equal(Z @ Zinv, np.eye(a.size))  # unimodular, exactly
    assert np.allclose(L.T @ np.diag(d) @ L, Z.T @ Q @ Z, rtol=0, atol=1e-12)
    F, s = lm.lambda_search(a, Q, 2)
    Fp, sp = lm.lambda_search_py(a, Q, 2)
    np.testing.assert_array_equal(F, Fp)
    np.testing.assert_allclose(s, sp, rtol=1e-7)


def test_kernel_equals_pure_on_the_reference_vectors(shared_data: Path) -> None:
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
def test_errors_match_the_pure_path(a: list[float], Q: object, exc: type[Exception], msg: str) -> None:
    with pytest.raises(exc, match=msg):
        lm.lambda_search_py(a, Q, 2)  # type: ignore[arg-type]
    with pytest.raises(exc, match=msg):
        lm.lambda_search(a, Q, 2)  # type: ignore[arg-type]


def test_search_cap_is_reported_the_same_way() -> None:
    n = 12
    Q = np.eye(n) * 1e6  # ~1e3 cycles of spread: astronomically many points per level
    a = np.full(n, 0.5)
    L, d = lm.ltdl(Q)
    for fn in (lm.search, lm.search_py):
        with pytest.raises(lm.SearchLimitError, match="exceeded 50 nodes"):
            fn(L, d, a, 2, max_nodes=50)


def test_a_search_in_a_fresh_process_takes_the_c_kernels_and_loads_no_numba() -> None:
    probe = (
        "import sys\nimport numpy as np\n"
        "from robustrtk.ambiguity.lambda_ import kernels, lambda_search\n"
        "print(lambda_search(np.array([0.2, -1.3]), np.array([[0.5, 0.1], [0.1, 0.4]]))[0][:, 0])\n"
        "print(kernels().__name__, 'numba' in sys.modules)\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", probe],
        env={"PYTHONPATH": str(PKG_PARENT), "PATH": "/usr/bin:/bin"},
        capture_output=True,
        text=True,
        check=True,
        timeout=120,
    ).stdout.split()
    assert out[-2:] == ["robustrtk.ambiguity.lambda_ckernels", "False"]


def test_read_only_and_empty_arrays_are_accepted() -> None:
    rng = np.random.default_rng(7)
    Q = _q(rng, 6, 1e3)
    a = rng.normal(size=6) * 4
    want = ck.lambda_all(a, Q, 2, 10_000)
    Qr, ar = Q.copy(), a.copy()
    Qr.setflags(write=False)
    ar.setflags(write=False)
    got = ck.lambda_all(ar, Qr, 2, 10_000)
    for x, y in zip(got, want, strict=True):
        np.testing.assert_array_equal(x, y)
    no_ops = np.zeros((0, 3), dtype=np.int64)
    np.testing.assert_array_equal(ck.apply_zt_k(no_ops, a), a)
    L, d = lm.ltdl_py(Q)
    F, s, code = ck.ils_from_reduced_k(a, no_ops, L, d, 2, 10_000)  # Z = I
    Fp, sp, _ = lm.ils_search_py(a, Q, 2, ([], L, d))
    assert code == ck.OK
    np.testing.assert_array_equal(F, Fp)
    np.testing.assert_array_equal(s, sp)
