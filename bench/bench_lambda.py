"""Benchmark of :func:`robustrtk.ambiguity.lambda_.lambda_search` on GNSS-like covariances.

Run with ``python bench/bench_lambda.py``. For each size n the float-ambiguity covariance is
that of a single-epoch, dual-frequency double-difference (DD) problem: ``n`` ambiguities split
over two carriers (GPS L1/L2 wavelengths), receiver-satellite geometry drawn from a fixed seed,
code σ = 0.3 m, phase σ = 3 mm (elevation weighted), the DD correlation of a common reference
satellite, and the baseline estimated jointly. ``Q = [(AᵀWA)⁻¹]_bb`` is the ambiguity block,
strongly correlated as in real RTK. Float ambiguities are the truth plus a draw from ``N(0, Q)``.

Prints the median wall time per call (µs) and calls per second.
"""

from __future__ import annotations

import time

import numpy as np

from robustrtk.ambiguity.lambda_ import decorrelate, lambda_search
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


def main() -> None:
    """Print the timing table."""
    rng = np.random.default_rng(20240501)
    budget_s = 5.0
    hdr = ("n", "median_us", "p90_us", "calls/s", "corr_max", "problems")
    print("{:>4} {:>12} {:>10} {:>10} {:>9} {:>9}".format(*hdr))
    for n in (4, 10, 20, 40):
        problems = [dd_float_problem(n, rng) for _ in range(20)]
        for a, Q in problems[:2]:  # warm-up
            lambda_search(a, Q)
        times = []
        t_end = time.perf_counter() + budget_s
        i = 0
        while time.perf_counter() < t_end and len(times) < 2000:
            a, Q = problems[i % len(problems)]
            t0 = time.perf_counter()
            lambda_search(a, Q)
            times.append(time.perf_counter() - t0)
            i += 1
        t = np.array(times) * 1e6
        a, Q = problems[0]
        sd = np.sqrt(np.diag(Q))
        corr = Q / np.outer(sd, sd)
        cmax = np.max(np.abs(corr - np.eye(n)))
        med = float(np.median(t))
        print(
            f"{n:>4} {med:>12.1f} {np.percentile(t, 90):>10.1f} {1e6 / med:>10.0f} "
            f"{cmax:>9.4f} {len(problems):>9}"
        )
    _ = decorrelate


if __name__ == "__main__":
    main()
