"""The TDCP displacement of the DGNSS carry (algorithms.md §45) on constructed epochs."""

from __future__ import annotations

import numpy as np

from robustrtk.geometry.los import geometric_range
from robustrtk.measurement.tdcp_carry import (
    FLOOR_M,
    Displacement,
    PhaseEpoch,
    TdcpTracker,
    displacement,
    tdcp_prediction,
)

LAM = 0.19029367
RX0 = np.array([-3959400.631, 3385704.533, 3667523.111]) + np.array([2000.0, -1500.0, 800.0])


def _sats(t_s: float, n: int) -> np.ndarray:
    """``n`` satellites about 20 000 km above, spread over the sky, moving ~3 km/s."""
    up = RX0 / np.linalg.norm(RX0)
    e = np.cross([0.0, 0.0, 1.0], up)
    e /= np.linalg.norm(e)
    nn = np.cross(up, e)
    out = []
    for i in range(n):
        az = 2 * np.pi * i / n + 0.3
        el = np.deg2rad(20.0 + 60.0 * ((i * 7) % n) / n)
        los = np.cos(el) * (np.sin(az) * e + np.cos(az) * nn) + np.sin(el) * up
        vel = 3000.0 * np.cross(los, up)
        out.append(RX0 + 2.2e7 * los + vel * t_s)
    return np.array(out)


def _epoch(t_s: float, rx: np.ndarray, ids: tuple[str, ...], clk_rx_m: dict[str, float]) -> PhaseEpoch:
    n = len(ids)
    sat = _sats(t_s, n)
    tx_clk = 1e-4 * 299792458.0 * np.linspace(-1, 1, n) + 0.3 * t_s * np.arange(n)  # drifting clocks
    rng, _ = geometric_range(sat, rx)
    amb = np.arange(n) * 1234.0
    clk = np.array([clk_rx_m[s[0]] for s in ids])
    phase = ((rng + clk - tx_clk) / LAM + amb)[:, None]
    full = np.full((n, 1), np.nan)
    return PhaseEpoch(
        t_s, ids, phase, np.zeros((n, 1), np.int8), full, np.full((n, 1), 45.0),
        np.full((n, 1), LAM), sat, tx_clk, np.full(n, 0.003**2),
    )  # fmt: skip


IDS = ("G01", "G02", "G03", "G04", "G05", "E01", "E02", "E03", "E04")
D_TRUE = np.array([12.3, -4.5, 1.7])


def test_noise_free_phase_gives_the_true_displacement() -> None:
    a = _epoch(100.0, RX0, IDS, {"G": 10.0, "E": -3.0})
    b = _epoch(101.0, RX0 + D_TRUE, IDS, {"G": 250.0, "E": 40.0})  # clocks jump per system
    # the earlier position known only to metres (a DGNSS posterior)
    disp = displacement(a, b, RX0 + np.array([1.5, -2.0, 3.0]), 0)
    assert disp is not None
    assert np.allclose(disp.d_pos_m, D_TRUE, atol=2e-3)
    assert disp.n_rows == len(IDS) and not disp.standing
    # the floor is in the covariance: at least FLOOR_M per axis
    assert np.all(np.sqrt(np.diag(disp.cov_m2)) >= FLOOR_M)


def test_a_slipped_arc_does_not_enter() -> None:
    a = _epoch(100.0, RX0, IDS, {"G": 0.0, "E": 0.0})
    b = _epoch(101.0, RX0 + D_TRUE, IDS, {"G": 5.0, "E": 5.0})
    phase = b.phase_cyc.copy()
    phase[2, 0] += 3.0  # three cycles, no loss-of-lock bit
    slipped = PhaseEpoch(**{**b.__dict__, "phase_cyc": phase})
    disp = displacement(a, slipped, RX0, 0)
    assert disp is not None
    assert disp.n_rows == len(IDS) - 1
    assert np.allclose(disp.d_pos_m, D_TRUE, atol=2e-3)
    # a loss-of-lock bit breaks the arc before any fit
    lli = b.lli.copy()
    lli[4, 0] = 1
    disp = displacement(a, PhaseEpoch(**{**b.__dict__, "lli": lli}), RX0, 0)
    assert disp is not None and disp.n_rows == len(IDS) - 1


def test_too_few_arcs_or_too_long_a_step_give_none() -> None:
    ids = IDS[:5]  # two systems: 5 unknowns, no redundancy
    a = _epoch(100.0, RX0, ids, {"G": 0.0, "E": 0.0})
    b = _epoch(101.0, RX0 + D_TRUE, ids, {"G": 0.0, "E": 0.0})
    assert displacement(a, b, RX0, 0) is None
    a = _epoch(100.0, RX0, IDS, {"G": 0.0, "E": 0.0})
    b = _epoch(110.0, RX0 + D_TRUE, IDS, {"G": 0.0, "E": 0.0})
    assert displacement(a, b, RX0, 0) is None


def test_many_slips_give_no_snapshot() -> None:
    """When half the arcs disagree the fit cannot tell which: no carry (not a wrong one)."""
    a = _epoch(100.0, RX0, IDS, {"G": 0.0, "E": 0.0})
    b = _epoch(101.0, RX0 + D_TRUE, IDS, {"G": 0.0, "E": 0.0})
    phase = b.phase_cyc.copy()
    rng = np.random.default_rng(3)
    phase[:5, 0] += rng.integers(2, 40, 5) * rng.choice([-1, 1], 5)
    disp = displacement(a, PhaseEpoch(**{**b.__dict__, "phase_cyc": phase}), RX0, 0)
    assert disp is None or np.all(np.abs(disp.d_pos_m - D_TRUE) <= 3 * np.sqrt(np.diag(disp.cov_m2)))


def test_standing_receiver_is_standing() -> None:
    tr = TdcpTracker()
    assert tr.step(_epoch(100.0, RX0, IDS, {"G": 0.0, "E": 0.0}), RX0, 0) is None
    disp = tr.step(_epoch(101.0, RX0, IDS, {"G": 7.0, "E": 1.0}), RX0, 0)
    assert disp is not None and disp.standing
    assert np.linalg.norm(disp.d_pos_m) < 1e-3


def test_prediction_adds_the_displacement_and_its_covariance() -> None:
    n = 7
    pos, vel = slice(0, 3), slice(3, 6)
    rng = np.random.default_rng(1)
    x = rng.normal(size=n)
    L = rng.normal(size=(n, n))
    P = L @ L.T + np.eye(n)
    C = np.diag([1e-4, 2e-4, 4e-4])
    disp = Displacement(D_TRUE, C, 0.5, 9, False)
    xn, Pn, T = tdcp_prediction(x, P, pos, vel, disp, 2.0)
    assert np.allclose(xn[pos], x[pos] + D_TRUE)
    assert np.allclose(xn[vel], D_TRUE / 0.5)
    assert np.allclose(xn[6], x[6])
    assert np.allclose(Pn[pos, pos], P[pos, pos] + C)
    assert np.allclose(Pn[vel, vel], C / 0.25 + np.eye(3) * 0.5**2)
    assert np.allclose(Pn, Pn.T) and np.all(np.linalg.eigvalsh(Pn) > 0)
    assert np.allclose(T @ x + np.r_[D_TRUE, D_TRUE / 0.5, 0.0], xn)
