"""Speed of each LAMBDA stage: the C kernels (``lambda_ckernels``) against the pure-Python
references (``lambda_pure``), on the same problems, with their results compared.

Run with ``python bench/bench_kernels.py``. The problems are those of ``bench_lambda.py``
(single-epoch dual-frequency DD float ambiguities, ``n`` = 10, 20, 30, 40, strongly
correlated). Stages: the LᵀDL factorisation, the reduction (integer Gauss transformations
and permutations), the MLAMBDA search of the two best candidates in the reduced space, and the
whole integer least squares (reduction, search, back-transform). Printed per stage and n: the
median over ``--problems`` problems of each problem's best of ``--reps`` calls (µs) for C and
pure, their ratio, and whether the outputs agree: the reduction's operations and factors and the
search's candidates and norms exactly (same inputs); LᵀDL to 1e-9 relative (LAPACK's Cholesky
against the kernel's elimination) and so the whole ILS's norms and conditional variances to
1e-7, its candidates exactly (integers of up to 1e6 cycles, far apart at that tolerance).
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable

import numpy as np
from bench_lambda import dd_float_problem

from robustrtk.ambiguity import lambda_pure as lp
from robustrtk.ambiguity.lambda_ import kernels

Prepared = tuple[np.ndarray, ...]


def best_median_us(fn: Callable[..., object], prepared: list[Prepared], reps: int) -> float:
    """Median over problems of the best of ``reps`` calls of ``fn(*args)`` (µs)."""
    best = []
    for args in prepared:
        fn(*args)
        b = math.inf
        for _ in range(reps):
            t0 = time.perf_counter()
            fn(*args)
            b = min(b, time.perf_counter() - t0)
        best.append(b)
    return float(np.median(best)) * 1e6


def _arrays(out: object) -> list[np.ndarray]:
    """The outputs as float arrays (a list of reduction operations as an (k, 3) array)."""
    items = out if isinstance(out, tuple) else (out,)
    arrays = [np.asarray(v, float) for v in items]
    if isinstance(items[0], list):  # the reduction's operations
        arrays[0] = arrays[0].reshape(-1, 3)
    return arrays


def _same(x: object, y: object, rtol: float) -> bool:
    """Every output of ``x`` equal to ``y``'s (to ``rtol``, relative to ``y``'s largest, when > 0)."""
    for u, v in zip(_arrays(x), _arrays(y), strict=True):
        if u.shape != v.shape:
            return False
        if rtol == 0.0 and not np.array_equal(u, v):
            return False
        if rtol > 0.0 and not np.allclose(u, v, rtol=rtol, atol=rtol * max(1.0, float(np.abs(v).max()))):
            return False
    return True


def _reduced(a: np.ndarray, Q: np.ndarray) -> Prepared:
    """The search's inputs: reduced factors of ``Q`` and ``Zᵀ (â − round(â))``."""
    ops, L, d = lp.reduce_ops_py(*lp.ltdl_py(Q, checked=True))
    return L, d, lp.apply_zt(ops, a - np.round(a))


def main() -> None:
    """Print the table."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--problems", type=int, default=30)
    ap.add_argument("--reps", type=int, default=100, help="timed calls per problem, C (best kept)")
    ap.add_argument("--pure-reps", type=int, default=5, help="timed calls per problem, pure")
    args = ap.parse_args()
    ck = kernels()
    if ck is None:
        print("C LAMBDA kernels not built here (or ROBUSTRTK_LAMBDA_BACKEND=pure): nothing to compare")
        return
    cap = lp.MAX_SEARCH_NODES
    # name, inputs of a problem (prepared outside the clock), C, pure, tolerance of the comparison
    stages: list[tuple[str, Callable[..., Prepared], Callable[..., object], Callable[..., object], float]] = [
        ("LtDL", lambda a, Q: (Q,), lambda Q: ck.ltdl_k(Q)[:2], lambda Q: lp.ltdl_py(Q, checked=True), 1e-9),
        ("reduction", lambda a, Q: lp.ltdl_py(Q, checked=True), ck.reduce_k, lp.reduce_ops_py, 0.0),
        (
            "search",
            _reduced,
            lambda L, d, z: ck.search_k(L, d, z, 2, cap)[:2],
            lambda L, d, z: lp.search_py(L, d, z, 2, cap),
            0.0,
        ),
        (
            "whole ILS",
            lambda a, Q: (a, Q),
            lambda a, Q: ck.ils_k(a, Q, 2, cap)[:3],
            lambda a, Q: lp.ils_search_py(a, Q, 2),
            1e-7,  # from different LtDL factors: the candidates exactly, norms and d to rounding
        ),
    ]
    rng = np.random.default_rng(20240501)
    sizes = (10, 20, 30, 40)
    # the inputs as the entry points pass them on: checked, contiguous
    per_n = {n: [dd_float_problem(n, rng) for _ in range(args.problems)] for n in sizes}
    probs = {n: [(np.ascontiguousarray(a), lp.check_q(Q, n)) for a, Q in per_n[n]] for n in sizes}
    print(
        f"LAMBDA stages, median over {args.problems} problems of each problem's best of "
        f"{args.reps} (C) / {args.pure_reps} (pure) calls, µs"
    )
    print(f"{'stage':10s} {'n':>3s} {'C µs':>9s} {'pure µs':>10s} {'pure/C':>7s} {'same':>5s}")
    for name, prepare, c_fn, py_fn, rtol in stages:
        for n in sizes:
            prepared = [prepare(a, Q) for a, Q in probs[n]]
            same = all(_same(c_fn(*p), py_fn(*p), rtol) for p in prepared)
            t_c = best_median_us(c_fn, prepared, args.reps)
            t_py = best_median_us(py_fn, prepared, args.pure_reps)
            agree = "yes" if same else "NO"
            print(f"{name:10s} {n:>3d} {t_c:9.1f} {t_py:10.1f} {t_py / t_c:7.1f} {agree:>5s}")


if __name__ == "__main__":
    main()
