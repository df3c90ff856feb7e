"""Filter step timings: µs per EKF / UKF / RUKF epoch with 5 pseudolites (4 DDs), and
end-to-end epochs/s of the DPL and RTK pipelines on a simulated room.

Run: ``python bench/bench_filters.py``. Prints medians over repeated runs.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from robustrtk.estimation.filters import EKF, UKF
from robustrtk.estimation.robust import DeltaVIGG3, NoRobust
from robustrtk.estimation.state import GaussianState, StateLayout
from robustrtk.measurement.dd import DDRangeModel, form_dd, ranges
from robustrtk.pipeline.config import Config
from robustrtk.pipeline.solve import solve_pseudolite
from robustrtk.sim.files import run_simulate

TX = np.array([[-3.6, -2.4, 1.9], [3.8, -2.5, 1.85], [3.5, 2.6, 1.92], [0.2, 0.3, 1.95], [-3.4, 2.7, 1.88]])
IDS = ("PL1", "PL4", "PL5", "PL6", "PL8")


def _problem(rng: np.random.Generator, err: float) -> tuple[GaussianState, DDRangeModel]:
    rover, base = np.array([1.5, 1.0, -1.55]), np.array([-1.2, -0.6, -1.6])
    rr, rb = ranges(rover, TX), ranges(base, TX)
    code_r = rr + rng.normal(0, 0.25, 5)
    code_r[1] += err
    code_b = rb + rng.normal(0, 0.25, 5)
    var = np.full(5, 0.0625)
    dd = form_dd(IDS, ["P:L1"] * 5, code_r, code_b, var, var, {"P:L1": "PL6"})
    st = GaussianState(rover + rng.normal(0, 0.1, 3), np.eye(3) * 0.01, 0.0, StateLayout())
    model = DDRangeModel(
        TX, rb, dd.i_tx, dd.i_ref, slice(0, 3), np.full(4, -1), np.zeros(4), dd.z, dd.R, dd.labels
    )
    return st, model


def step_us(filt: object, policy: object, err: float, n: int = 2000) -> float:
    rng = np.random.default_rng(0)
    probs = [_problem(rng, err) for _ in range(n)]
    times = []
    for st, model in probs:
        t0 = time.perf_counter()
        filt.update(st, model, policy)  # type: ignore[attr-defined]
        times.append(time.perf_counter() - t0)
    return float(np.median(times) * 1e6)


def main() -> None:
    rows = [
        ("EKF", step_us(EKF(), NoRobust(), 0.0)),
        ("UKF", step_us(UKF(), NoRobust(), 0.0)),
        ("RUKF (clean epoch)", step_us(UKF(), DeltaVIGG3(), 0.0)),
        ("RUKF (10 m error)", step_us(UKF(), DeltaVIGG3(), 10.0)),
        ("REKF (10 m error)", step_us(EKF(), DeltaVIGG3(), 10.0)),
    ]
    print("Measurement update, 5 pseudolites / 4 DD code rows (median of 2000)")
    print(f"{'filter':22s} {'µs/epoch':>10s}")
    for name, us in rows:
        print(f"{name:22s} {us:10.1f}")
    with tempfile.TemporaryDirectory() as d:
        run_simulate("dpl_static", 1, d)
        print("\nEnd to end (3000-epoch room, read + solve; median of 3 runs)")
        print(f"{'pipeline':28s} {'epochs/s':>10s}")
        for label, cfg in [
            ("DPL SUKF kinematic", Config.of(robust="none", dynamics="kinematic")),
            ("DPL RUKF kinematic", Config.of(robust="igg3", dynamics="kinematic")),
            ("DPL REKF kinematic", Config.of(robust="igg3", filter="ekf", dynamics="kinematic")),
            ("RTK RUKF+PAR static", Config.of(mode="rtk", robust="igg3", ar="par")),
        ]:
            rates = []
            for _ in range(3):
                t0 = time.perf_counter()
                res = solve_pseudolite(Path(d) / "obs.csv", Path(d) / "site.toml", cfg)
                rates.append(len(res.solutions) / (time.perf_counter() - t0))
            print(f"{label:28s} {np.median(rates):10.0f}")


if __name__ == "__main__":
    main()
