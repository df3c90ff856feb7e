"""Cooperative-positioning filter timings: particle-filter epochs/s with 10⁴ particles for one
node with eight rows (seven pseudoranges and one range to a peer), and one UKF and EKF step
(predict + update) on the same rows (:class:`~robustrtk.measurement.coop.NodeRows`, as
the cooperative loop passes them), both the project's one Kalman update
(:mod:`robustrtk.estimation.filters`, pure numpy).

Targets (cooperative-positioning issue): PF ≥ 200 epochs/s, one UKF step ≤ 50 µs (set for a
compiled kernel; the pure update does not reach it, docs/coop.md gives the figures).

Run: ``python bench/bench_coop.py``. Prints medians over repeated runs.
"""

from __future__ import annotations

import os
import time

import numpy as np

from robustrtk.estimation.coop import (
    KalmanNode,
    LocationTimeModel,
    ParticleNode,
    PeerBroadcast,
    RangeObservation,
    node_layout,
    peer_range_model,
)
from robustrtk.estimation.state import GaussianState
from robustrtk.measurement.coop import NodeRows, PseudorangeModel

RX = np.array([-3976219.19, 3382371.61, 3652511.14])
PEER = np.array([-3978241.958, 3382840.234, 3649900.853])


def _rows(rng: np.random.Generator, truth: np.ndarray) -> NodeRows:
    up = RX / np.linalg.norm(RX)
    sats = []
    while len(sats) < 7:
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        if d @ up > 0.3:
            sats.append(RX + 2.2e7 * d)
    s = np.array(sats)
    pr0 = PseudorangeModel(np.zeros(7), s, np.full(7, 9.0), np.full(7, 3), 0, 4)
    pr = PseudorangeModel(pr0.h(truth) + rng.normal(0, 3.0, 7), s, np.full(7, 9.0), np.full(7, 3), 0, 4)
    bc = {"n1": PeerBroadcast("n1", 0.0, np.r_[PEER, 0.0], np.eye(4))}
    obs = [RangeObservation("n1", float(np.linalg.norm(truth[:3] - PEER)), 0.01)]
    rm = peer_range_model(obs, bc, "improved", "pf")
    return NodeRows(pr, rm)


def _median_s(fn, n: int) -> float:  # type: ignore[no-untyped-def]
    times = []
    for _ in range(n):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def main() -> None:
    rng = np.random.default_rng(0)
    truth = np.r_[RX, 1000.0]
    lay = node_layout(1)
    proc = LocationTimeModel(sigma_pos_m_s=0.01, sigma_clk_m_s=100.0)
    rows = [_rows(rng, truth) for _ in range(50)]
    prior = GaussianState(truth + np.r_[rng.normal(0, 2.0, 3), 0.0], np.diag([4.0, 4.0, 4.0, 1e4]), 0.0, lay)
    out = []

    pf = ParticleNode(n_particles=10_000, seed=1, linear_idx=(3,))
    belief = pf.init(prior)
    state = {"b": belief, "k": 0}

    def pf_epoch() -> None:
        k = state["k"]
        b = pf.predict(state["b"], proc, float(k + 1))
        state["b"] = pf.update(b, rows[k % len(rows)]).belief
        state["k"] = k + 1

    for _ in range(5):
        pf_epoch()
    t_pf = _median_s(pf_epoch, 200)
    out.append(("PF 10⁴ particles, 8 rows: predict + update", t_pf * 1e6, 1.0 / t_pf, "≥ 200 epochs/s"))

    for kind in ("ukf", "ekf"):
        f = KalmanNode(kind)  # type: ignore[arg-type]
        g = {"b": prior, "k": 0}

        def kf_epoch(f: KalmanNode = f, g: dict = g) -> None:  # type: ignore[type-arg]
            k = g["k"]
            b = f.predict(g["b"], proc, float(k + 1))
            g["b"] = f.update(b, rows[k % len(rows)]).belief
            g["k"] = k + 1

        for _ in range(20):
            kf_epoch()
        t = _median_s(kf_epoch, 2000)
        target = "≤ 50 µs" if kind == "ukf" else ""
        out.append((f"{kind.upper()} step (predict + update), 8 rows", t * 1e6, 1.0 / t, target))

    A = np.eye(4) * 2.0
    bvec = np.ones(4)
    t_ref = _median_s(lambda: np.linalg.solve(A, bvec), 5000)
    out.append(("reference: one numpy 4×4 solve (machine speed / load)", t_ref * 1e6, 1.0 / t_ref, ""))
    for kind in ("ukf", "ekf"):
        f = KalmanNode(kind)  # type: ignore[arg-type]
        b0 = f.predict(prior, proc, 1.0)
        t_u = _median_s(lambda f=f, b0=b0: f.update(b0, rows[0]), 2000)
        t_p = _median_s(lambda f=f: f.predict(prior, proc, 1.0), 2000)
        out.append((f"  {kind.upper()} predict only", t_p * 1e6, 1.0 / t_p, ""))
        out.append((f"  {kind.upper()} update only", t_u * 1e6, 1.0 / t_u, ""))
    try:
        load = open("/proc/loadavg").read().split()[0]
    except OSError:
        load = "?"
    print(f"load average (1 min): {load} on {os.cpu_count()} cores")
    print(f"{'what':58s} {'median µs':>10s} {'per s':>10s}  target")
    for name, us, rate, target in out:
        print(f"{name:58s} {us:10.1f} {rate:10.0f}  {target}")


if __name__ == "__main__":
    main()
