"""The C LAMBDA kernels (``lambda_ckernels``) against the pure-Python references (the oracles)
and against the numba kernels.

The reduction's operations and factors and the search's candidates exactly, the LᵀDL factors to
rounding, every kernel output bit for bit against the numba kernels, and the whole
``lambda_search`` identical with the C and numba backends. The checks on the ill-conditioned
receiver set, the reference vectors, the error messages and the search cap run on both
backends in tests/ambiguity/test_lambda_kernels.py (its ``backend`` fixture).
"""

from __future__ import annotations

import re
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk import jit
from robustrtk.ambiguity import lambda_ as lm

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
def _c_backend(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """The public entry points on the C kernels (the default whenever they are built)."""
    monkeypatch.setenv("ROBUSTRTK_LAMBDA_BACKEND", "c")
    monkeypatch.delenv("ROBUSTRTK_NO_JIT", raising=False)
    monkeypatch.delenv("ROBUSTRTK_JIT", raising=False)
    jit.refresh()
    yield
    jit.begin_run(None)


def _q(rng: np.random.Generator, n: int, cond: float) -> np.ndarray:
    """SPD matrix with eigenvalues log-spread over ``cond`` and a random rotation."""
    U, _ = np.linalg.qr(rng.normal(size=(n, n)))
    ev = np.geomspace(1e-3, 1e-3 * cond, n)
    Q = (U * ev) @ U.T
    return 0.5 * (Q + Q.T)


def test_the_c_kernels_serve_from_the_first_call_outside_the_policy() -> None:
    jit.begin_run(1000)
    assert lm.kernels() is ck
    lm.lambda_search(np.array([0.2, -1.3]), np.array([[0.5, 0.1], [0.1, 0.4]]))
    assert jit.meter().spent_us == 0.0  # nothing charged: C has no fixed cost to pay back
    with jit.use("off"):
        assert lm.kernels() is None


def test_backend_variable(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("ROBUSTRTK_LAMBDA_BACKEND", "pure")
    jit.refresh()
    assert lm.kernels() is None
    monkeypatch.setenv("ROBUSTRTK_LAMBDA_BACKEND", "numba")
    jit.refresh()
    with jit.use("on"):
        assert lm.kernels() is not ck
    monkeypatch.setenv("ROBUSTRTK_LAMBDA_BACKEND", "fortran")
    jit.refresh()
    with pytest.raises(ValueError, match="ROBUSTRTK_LAMBDA_BACKEND='fortran'"):
        lm.kernels()
    monkeypatch.setenv("ROBUSTRTK_LAMBDA_BACKEND", "c")
    monkeypatch.setenv("ROBUSTRTK_NO_JIT", "1")
    jit.refresh()
    assert lm.kernels() is None


def test_only_the_c_kernels_are_looked_up_once_for_many_calls(monkeypatch: pytest.MonkeyPatch) -> None:
    assert lm.fixed_kernels() is ck
    monkeypatch.setenv("ROBUSTRTK_LAMBDA_BACKEND", "numba")
    jit.refresh()
    with jit.use("on"):
        assert lm.kernels() is not None and lm.fixed_kernels() is None  # numba: per call
    monkeypatch.setenv("ROBUSTRTK_LAMBDA_BACKEND", "pure")
    jit.refresh()
    assert lm.fixed_kernels() is None
    monkeypatch.setenv("ROBUSTRTK_LAMBDA_BACKEND", "c")
    jit.refresh()
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


def test_same_interface_as_the_numba_kernels() -> None:
    nb_src = (PKG_PARENT / "robustrtk" / "ambiguity" / "lambda_kernels.py").read_text()
    names = re.findall(r"^def (\w+)\(", nb_src, flags=re.M)
    consts = re.findall(r"^([A-Z_]+) = ", nb_src, flags=re.M)
    assert len(names) >= 8 and len(consts) >= 6
    for name in names:
        assert callable(getattr(ck, name))
    for c in consts:
        assert getattr(ck, c) == float(re.search(rf"^{c} = (.+)$", nb_src, flags=re.M)[1])  # type: ignore[index]


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
    np.testing.assert_array_equal(ck.apply_zt_k(ops_arr, a), lm._apply_zt(ops_p, a))
    V = rng.normal(size=(n, 3))
    np.testing.assert_array_equal(ck.apply_zinvt_k(ops_arr, V), lm._apply_zinvt(ops_p, V))
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


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 30), log_cond=st.floats(0.0, 6.0))
def test_lambda_search_identical_with_the_c_and_numba_backends(seed: int, n: int, log_cond: float) -> None:
    pytest.importorskip("numba")
    from robustrtk.ambiguity import lambda_kernels as nk

    rng = np.random.default_rng(seed)
    Q = _q(rng, n, 10.0**log_cond)
    a = rng.normal(size=n) * 50.0
    # the kernels themselves: every output bit for bit
    for out_c, out_n in (
        (ck.ltdl_k(Q), nk.ltdl_k(Q)),
        (ck.reduce_k(*lm.ltdl_py(Q)), nk.reduce_k(*lm.ltdl_py(Q))),
        (ck.ils_k(a, lm.check_q(Q), 3, 5000), nk.ils_k(a, lm.check_q(Q), 3, 5000)),
        (ck.lambda_all(a, Q, 2, 5000), nk.lambda_all(a, Q, 2, 5000)),
    ):
        assert len(out_c) == len(out_n)
        for x, y in zip(out_c, out_n, strict=True):
            assert np.asarray(x).dtype == np.asarray(y).dtype
            np.testing.assert_array_equal(x, y)
    # and the public entry point with either backend
    results = []
    for name in ("c", "numba"):
        with pytest.MonkeyPatch.context() as mp, jit.use("on"):
            mp.setenv("ROBUSTRTK_LAMBDA_BACKEND", name)
            jit.refresh()
            assert (lm.kernels() is ck) == (name == "c")
            try:
                results.append(lm.lambda_search(a, Q, 2))
            except lm.SearchLimitError as err:
                results.append((str(err),))
    assert len(results[0]) == len(results[1])
    for x, y in zip(results[0], results[1], strict=True):
        np.testing.assert_array_equal(x, y)


def test_error_codes_are_those_of_the_numba_kernels() -> None:
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


def test_a_search_with_the_c_kernels_loads_no_numba() -> None:
    probe = (
        "import sys\nimport numpy as np\nfrom robustrtk import jit\n"
        "from robustrtk.ambiguity.lambda_ import kernels, lambda_search\n"
        "jit.begin_run(10)\n"
        "print(lambda_search(np.array([0.2, -1.3]), np.array([[0.5, 0.1], [0.1, 0.4]]))[0][:, 0])\n"
        "print(kernels().__name__, 'numba' in sys.modules, jit.meter().spent_us)\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", probe],
        env={"PYTHONPATH": str(PKG_PARENT), "PATH": "/usr/bin:/bin"},
        capture_output=True,
        text=True,
        check=True,
        timeout=120,
    ).stdout.split()
    assert out[-3:] == ["robustrtk.ambiguity.lambda_ckernels", "False", "0.0"]


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


def test_a_changed_variable_takes_effect_at_the_next_run_not_in_the_middle_of_one(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    jit.begin_run(None)
    assert lm.kernels() is ck
    monkeypatch.setenv("ROBUSTRTK_LAMBDA_BACKEND", "pure")
    monkeypatch.setenv("ROBUSTRTK_NO_JIT", "1")
    assert lm.kernels() is ck  # the run's settings, read when it began
    jit.begin_run(None)
    assert lm.kernels() is None
    monkeypatch.delenv("ROBUSTRTK_NO_JIT")
    assert lm.kernels() is None
    jit.begin_run(None)
    assert lm.kernels() is None  # still the pure backend
    monkeypatch.setenv("ROBUSTRTK_LAMBDA_BACKEND", "c")
    assert jit.mode() == "auto"  # reading the policy reads the backend again too
    assert lm.kernels() is ck
