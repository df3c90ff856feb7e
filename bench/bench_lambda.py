"""Benchmark of :func:`robustrtk.ambiguity.lambda_.lambda_search` on GNSS-like covariances.

Run with ``python bench/bench_lambda.py``. For each size n the float-ambiguity covariance is
that of a single-epoch, dual-frequency double-difference (DD) problem: ``n`` ambiguities split
over two carriers (GPS L1/L2 wavelengths), receiver-satellite geometry drawn from a fixed seed,
code σ = 0.3 m, phase σ = 3 mm (elevation weighted), the DD correlation of a common reference
satellite, and the baseline estimated jointly. ``Q = [(AᵀWA)⁻¹]_bb`` is the ambiguity block,
strongly correlated as in real RTK. Float ambiguities are the truth plus a draw from ``N(0, Q)``.

The same problems (``--problems`` per n, n = 10, 20, 30, 40) are written in the
``probs.txt`` format of RTKLIB's ``lambda_bench`` (``shared/tools/rtklib-demo5``, RTKLIB's C
``lambda()`` built with -O3) and timed there; ours are timed the same way (each problem's best of
``--reps`` calls, median over the problems). Printed per n: RTKLIB's C, ours with the C kernels
(``lambda_ckernels``, when built) and its ratio to RTKLIB, the pure-Python reference
(``lambda_pure``) and its ratio to RTKLIB, and the failures (errors, search-cap hits) of ours.

Usage: ``python bench/bench_lambda.py [--lambda-bench PATH] [--problems 50] [--reps 200]``
"""

from __future__ import annotations

import argparse
import math
import os
import re
import subprocess
import tempfile
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from robustrtk.ambiguity.lambda_ import backend, kernels, lambda_search, lambda_search_py
from robustrtk.gnss import wavelength_m

FloatArray = np.ndarray


def dd_float_problem(
    n_amb: int, rng: np.random.Generator, n_epochs: int = 1
) -> tuple[FloatArray, FloatArray]:
    """Float ambiguities (cycles) and covariance (cycles²) of a DD RTK problem.

    Parameters
    ----------
    n_amb : int
        Number of DD ambiguities: L1 only below 8, else split over L1 and L2.
    rng : numpy.random.Generator
        Source of geometry and noise.
    n_epochs : int
        Epochs of static data stacked (more epochs, weaker correlation).
    """
    lam1 = wavelength_m("G", "1C")
    lam2 = wavelength_m("G", "2W")
    n_f2 = n_amb // 2 if n_amb >= 8 else 0  # dual frequency from 8 ambiguities on
    n_f1 = n_amb - n_f2
    n_sat = n_f1 + 1
    az = rng.uniform(0.0, 2.0 * np.pi, n_sat)
    el = rng.uniform(np.radians(15.0), np.radians(85.0), n_sat)
    el[0] = np.radians(80.0)  # reference satellite: highest
    los = np.stack([np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)], axis=1)
    D = np.hstack([-np.ones((n_sat - 1, 1)), np.eye(n_sat - 1)])  # DD operator
    var_sd = 1.0 / np.sin(el) ** 2
    C_dd = D @ np.diag(var_sd) @ D.T  # correlated DD cofactor
    G = D @ (-los)  # DD geometry, (n_sat-1, 3)
    rows_A, blocks_R = [], []
    for f, (lam, n_f) in enumerate(((lam1, n_f1), (lam2, n_f2))):
        for sig_m, is_phase in ((0.3, False), (0.003, True)):
            for _ in range(n_epochs if n_f > 0 else 0):
                A = np.zeros((n_f, 3 + n_amb))
                A[:, :3] = G[:n_f]
                if is_phase:
                    off = 0 if f == 0 else n_f1
                    A[:, 3 + off : 3 + off + n_f] = lam * np.eye(n_f)
                rows_A.append(A)
                blocks_R.append(sig_m**2 * C_dd[:n_f, :n_f])
    A_all = np.vstack(rows_A)
    R = np.zeros((A_all.shape[0], A_all.shape[0]))
    i = 0
    for B in blocks_R:
        R[i : i + B.shape[0], i : i + B.shape[0]] = B
        i += B.shape[0]
    N = A_all.T @ np.linalg.solve(R, A_all)
    P = np.linalg.inv(N)
    Q = P[3:, 3:]
    Q = 0.5 * (Q + Q.T)
    truth = rng.integers(-1_000_000, 1_000_000, n_amb).astype(float)
    a_float = truth + np.linalg.cholesky(Q) @ rng.standard_normal(n_amb)
    return a_float, Q


def write_problems(path: Path, problems: list[tuple[int, FloatArray, FloatArray]]) -> None:
    """Write problems in ``lambda_bench``'s ``probs.txt`` format (n; â; Q row-major)."""
    with path.open("w") as f:
        for n, a, Q in problems:
            f.write(f"{n}\n")
            f.write(" ".join(repr(float(v)) for v in a) + "\n")
            f.write(" ".join(repr(float(v)) for v in Q.reshape(-1)) + "\n")


def run_c(exe: Path, problems: list[tuple[int, FloatArray, FloatArray]]) -> dict[int, float]:
    """Median (over problems) of the best-of-200 time (µs) of RTKLIB's C ``lambda()`` per n."""
    with tempfile.TemporaryDirectory() as tmp:
        write_problems(Path(tmp) / "probs.txt", problems)
        out = subprocess.run([str(exe)], cwd=tmp, capture_output=True, text=True, check=True).stdout
    res: dict[int, float] = {}
    for line in out.splitlines():
        m = re.match(r"C RTKLIB n=(\d+): median ([\d.]+) us", line)
        if m:
            res[int(m.group(1))] = float(m.group(2))
    return res


def run_ours(
    fn: Callable[[FloatArray, FloatArray], object], probs: list[tuple[FloatArray, FloatArray]], reps: int
) -> tuple[float, int]:
    """Median over problems of the best-of-``reps`` time (µs) of ``fn``; and the failures."""
    best = []
    fails = 0
    for a, Q in probs:
        try:
            fn(a, Q)
        except ValueError:
            fails += 1
            continue
        b = math.inf
        for _ in range(reps):
            t0 = time.perf_counter()
            fn(a, Q)
            b = min(b, time.perf_counter() - t0)
        best.append(b)
    return (float(np.median(best)) * 1e6 if best else math.nan), fails


def main() -> None:
    """Print ours (compiled and pure) against RTKLIB's C ``lambda()`` on the same problems."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--lambda-bench", type=Path, default=_default_c(), help="RTKLIB lambda_bench binary")
    ap.add_argument("--problems", type=int, default=50, help="problems per n (lambda_bench holds 50)")
    ap.add_argument("--reps", type=int, default=200, help="timed calls per problem (best kept)")
    ap.add_argument("--pure-reps", type=int, default=5, help="timed calls per problem, pure Python")
    args = ap.parse_args()
    rng = np.random.default_rng(20240501)
    sizes = (10, 20, 30, 40)
    per_n = {n: [dd_float_problem(n, rng) for _ in range(args.problems)] for n in sizes}
    flat = [(n, a, Q) for n in sizes for a, Q in per_n[n]]
    if args.lambda_bench.is_file():
        c_us = run_c(args.lambda_bench, flat)
    else:
        print(f"lambda_bench not found at {args.lambda_bench}: the C column is empty")
        c_us = {}
    has_c = _backend_module("c") is not None
    print(f"kernels: C {'built' if has_c else 'not built'}")
    print(
        f"median over {args.problems} problems per n of each problem's best of {args.reps} calls (µs); "
        f"pure: best of {args.pure_reps}"
    )
    hdr = ("n", "C RTKLIB", "ours C", "oursC/C", "pure", "pure/C", "fails", "corr_max")
    print("{:>4} {:>10} {:>10} {:>8} {:>10} {:>8} {:>6} {:>9}".format(*hdr))
    for n in sizes:
        probs = per_n[n]
        ours_c, fails_c = _timed_with("c", probs, args.reps) if has_c else (math.nan, 0)
        pure, fails_py = run_ours(lambda a, Q: lambda_search_py(a, Q), probs, args.pure_reps)
        c = c_us.get(n, math.nan)
        a, Q = probs[0]
        sd = np.sqrt(np.diag(Q))
        cmax = float(np.max(np.abs(Q / np.outer(sd, sd) - np.eye(n))))
        print(
            f"{n:>4} {c:>10.1f} {ours_c:>10.1f} {ours_c / c:>8.2f} "
            f"{pure:>10.1f} {pure / c:>8.1f} {fails_c + fails_py:>6} {cmax:>9.4f}"
        )


@contextmanager
def _backend(name: str) -> Iterator[None]:
    """``lambda_search`` on the backend ``name`` (``ROBUSTRTK_LAMBDA_BACKEND``)."""
    old = os.environ.get("ROBUSTRTK_LAMBDA_BACKEND")
    os.environ["ROBUSTRTK_LAMBDA_BACKEND"] = name
    backend()  # read, as a run does when it begins
    try:
        yield
    finally:
        if old is None:
            del os.environ["ROBUSTRTK_LAMBDA_BACKEND"]
        else:
            os.environ["ROBUSTRTK_LAMBDA_BACKEND"] = old
        backend()


def _backend_module(name: str) -> object | None:
    """The kernels module of the backend ``name``, None when absent."""
    with _backend(name):
        try:
            return kernels()
        except ValueError:  # c asked for and not built
            return None


def _timed_with(name: str, probs: list[tuple[FloatArray, FloatArray]], reps: int) -> tuple[float, int]:
    """:func:`run_ours` of ``lambda_search`` on the backend ``name`` (``c`` or ``pure``)."""
    with _backend(name):
        return run_ours(lambda a, Q: lambda_search(a, Q), probs, reps)


def _default_c() -> Path:
    return Path(__file__).resolve().parents[1].parent / "shared" / "tools" / "rtklib-demo5" / "lambda_bench"


if __name__ == "__main__":
    main()
