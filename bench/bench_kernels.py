"""Speed of one filter measurement update: compiled fast path against the pure path.

Run with ``python bench/bench_kernels.py``. The problem: a rover among five pseudolites (local
frame, m), four DD carrier-phase rows (cycles as metres, σ = 3 mm) against one reference
transmitter, state = position (3) + the four DD ambiguities (cycles), i.e. 7 states and 4
measurements; prior σ 0.1 m / 2 cycles, correlated. ``EKF().update`` / ``UKF().update`` with
the standard (non-robust) policy. Printed: the median over ``--problems`` problems of each
problem's best of ``--reps`` calls (µs), for the fast path (numba, the default), the pure path
(``ROBUSTRTK_NO_JIT``-equivalent) and the kernel call alone (no Python wrapping), and the
largest difference of the posteriors between the two paths.
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable

import numpy as np

from robustrtk import jit
from robustrtk.estimation import filters
from robustrtk.estimation.filters import EKF, UKF
from robustrtk.estimation.state import GaussianState, StateLayout
from robustrtk.measurement.dd import DDRangeModel, ranges

TX_M = np.array([[-3.6, -2.4, 1.9], [3.8, -2.5, 1.85], [3.5, 2.6, 1.92], [0.2, 0.3, 1.95], [-3.4, 2.7, 1.88]])
WAVELENGTH_M = 0.19029


def problem(rng: np.random.Generator) -> tuple[GaussianState, DDRangeModel]:
    """A 7-state, 4-row DD phase update (see the module notes)."""
    rover = np.array([1.5, 1.0, -1.55]) + rng.normal(0.0, 0.3, 3)
    base = np.array([-1.2, -0.6, -1.6])
    n_true = rng.integers(-50, 50, 4).astype(float)
    i_ref = np.full(4, 3)
    i_tx = np.array([0, 1, 2, 4])
    rr, rb = ranges(rover, TX_M), ranges(base, TX_M)
    z = (rr[i_tx] - rr[i_ref]) - (rb[i_tx] - rb[i_ref]) + WAVELENGTH_M * n_true + rng.normal(0, 0.003, 4)
    R = 0.003**2 * (np.eye(4) + 1.0)  # DD correlation of a common reference
    A = rng.normal(size=(7, 7)) * 0.3
    P = np.diag([0.01] * 3 + [4.0] * 4) + 0.01 * (A @ A.T)
    x = np.concatenate([rover + rng.normal(0.0, 0.1, 3), n_true + rng.normal(0.0, 2.0, 4)])
    model = DDRangeModel(
        TX_M, rb, i_tx, i_ref, slice(0, 3), np.arange(3, 7), np.full(4, WAVELENGTH_M), z, R, ("r",) * 4
    )
    return GaussianState(x, P, 0.0, StateLayout()), model


def best_median_us(fn: Callable[[GaussianState, DDRangeModel], object], probs: list, reps: int) -> float:
    """Median over problems of the best of ``reps`` calls (µs)."""
    best = []
    for st, model in probs:
        fn(st, model)
        b = math.inf
        for _ in range(reps):
            t0 = time.perf_counter()
            fn(st, model)
            b = min(b, time.perf_counter() - t0)
        best.append(b)
    return float(np.median(best)) * 1e6


def main() -> None:
    """Print the table."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--problems", type=int, default=50)
    ap.add_argument("--reps", type=int, default=200)
    args = ap.parse_args()
    rng = np.random.default_rng(7)
    probs = [problem(rng) for _ in range(args.problems)]
    k = filters.kernels()
    print(
        f"one measurement update, 7 states / 4 DD rows; median of {args.problems} problems' "
        f"best of {args.reps}"
    )
    print(
        f"{'filter':6s} {'fast µs':>9s} {'pure µs':>9s} {'kernel µs':>10s} "
        f"{'max |Δx|':>10s} {'max |ΔP|':>10s}"
    )
    for name, filt in (("UKF", UKF()), ("EKF", EKF())):
        fast = best_median_us(filt.update, probs, args.reps)
        filters._KERNELS[:] = [None]
        pure = best_median_us(filt.update, probs, max(1, args.reps // 10))
        ref = [filt.update(st, m) for st, m in probs]
        filters._KERNELS[:] = [k]
        got = [filt.update(st, m) for st, m in probs]
        dx = max(float(np.max(np.abs(a.state.x - b.state.x))) for a, b in zip(got, ref, strict=True))
        dP = max(float(np.max(np.abs(a.state.P - b.state.P))) for a, b in zip(got, ref, strict=True))
        kern = math.nan
        if k is not None:
            is_ukf = name == "UKF"

            n = probs[0][0].x.shape[0]
            xP, rows = np.empty((n + 1, n)), np.empty((5 + 2 * 4, 4))
            work = np.empty(k.work_size(n, 4, TX_M.shape[0]))

            def call(
                st: GaussianState,
                m: DDRangeModel,
                is_ukf: bool = is_ukf,
                xP: np.ndarray = xP,
                rows: np.ndarray = rows,
                work: np.ndarray = work,
            ) -> object:
                geo, idx = m.kernel_args  # type: ignore[misc]
                return k.dd_update_packed_k(
                    st.x, st.P, m.z, m.R, geo, idx, is_ukf, 1.0, 2.0, 0.0, xP, rows, work
                )

            kern = best_median_us(call, probs, args.reps)
        print(f"{name:6s} {fast:9.1f} {pure:9.1f} {kern:10.1f} {dx:10.2e} {dP:10.2e}")
    print(f"kernels: {'numba' if k is not None else 'off (pure path only)'}")


if __name__ == "__main__":
    with jit.use("on"):  # the compiled path from the first call, whatever the run length
        main()
