"""Time-differenced carrier phase: arc tests, and the displacement it gives on synthetic phase."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.geometry.los import geometric_range
from robustrtk.io.rinex_nav import read_rinex_nav
from robustrtk.io.rinex_obs import read_rinex_obs
from robustrtk.measurement.tdcp import (
    ABSENT,
    CONTINUES,
    DOPPLER,
    GAP,
    GEOMETRY_FREE,
    LLI,
    ArcTests,
    arc_breaks,
    phase_deltas,
    solve_displacement,
)

GEONET = "geonet_0759_3040_static_3km"
L1, L5 = 0.190293672798, 0.254828048791


def _steady(T: int = 6, N: int = 3) -> tuple:
    """Phase of satellites moving away at 100 m/s, Doppler to match, two bands."""
    t = np.arange(T, dtype=float)
    lam = np.tile([L1, L5], (N, 1))
    rate = 100.0 + np.arange(N)[:, None] * 10.0  # m/s, same on both bands (no ionosphere)
    phase = (rate[None] * t[:, None, None]) / lam[None] + 1e6
    dop = np.broadcast_to(-rate / lam, phase.shape).copy()
    return t, phase, np.zeros_like(phase), dop, np.full_like(phase, 45.0), lam


def test_arc_breaks_name_each_reason() -> None:
    t, phase, lli, dop, cn0, lam = _steady()
    phase[2, 0, 0] = np.nan  # absent: deltas into and out of epoch 2
    lli[3, 1, 0] = 1  # loss of lock
    phase[4:, 2, 0] += 1.0  # one-cycle slip on L1 only: geometry-free
    phase[5:, 1, 1] += 20.0  # 20 L5 cycles (5 m): the Doppler test (GF also sees it)
    t[5] += 1.0  # a 2-s gap before epoch 5
    out = arc_breaks(t, phase, lli, dop, cn0, lam, ArcTests(lli_break=True, max_gap_s=1.5))
    assert np.all(out[0] == ABSENT)
    assert out[2, 0, 0] == ABSENT and out[3, 0, 0] == ABSENT
    assert out[3, 1, 0] == LLI
    assert out[4, 2, 0] == GEOMETRY_FREE and out[4, 2, 1] == GEOMETRY_FREE
    assert np.all(out[5] == GAP)
    assert out[1, 0, 0] == CONTINUES and out[4, 0, 1] == CONTINUES
    no_lli = arc_breaks(t, phase, lli, dop, cn0, lam, ArcTests(lli_break=False, max_gap_s=1.5))
    assert no_lli[3, 1, 0] == CONTINUES
    # single band: the 5-m jump is left to the Doppler test
    t2 = np.arange(6, dtype=float)
    one = arc_breaks(t2, phase[:, :, 1:], lli[:, :, 1:], dop[:, :, 1:], cn0[:, :, 1:], lam[:, 1:])
    assert one[5, 1, 0] == DOPPLER
    assert np.all(one[5, [0, 2], 0] == CONTINUES)


def test_tdcp_gives_the_true_displacement(shared_data: Path) -> None:
    """Noise-free phase (arbitrary integer offsets, a receiver clock running 300 m/s) of a
    receiver that moves 12 m between two epochs: the TDCP displacement is the true one to
    a millimetre from the true first position."""
    eph = EphemerisSource(read_rinex_nav(shared_data / GEONET / "30400920.05n"))
    b = read_rinex_obs(shared_data / GEONET / "07590920.05o")
    ids = [b.tx_ids[j] for j in np.flatnonzero(np.isfinite(b.code_m[0, :, 0]))]
    t0 = float(b.t_s[0])
    r0 = np.array([-3976219.1879, 3382371.6056, 3652511.1425])
    r1 = r0 + np.array([7.0, -9.0, 3.5])
    clk = (1000.0, 1300.0)
    rng = np.random.default_rng(3)
    offsets = rng.integers(-(10**7), 10**7, size=len(ids))
    phase, sat, sclk = [], [], []
    for k, (t, r) in enumerate(((t0, r0), (t0 + 1.0, r1))):
        pos, sat_clk = eph.positions(t, ids)
        rho, _ = geometric_range(pos, r)
        phase.append((rho + clk[k] - sat_clk) / L1 + offsets)
        sat.append(pos)
        sclk.append(sat_clk)
    ph = np.array(phase)[:, :, None]
    lam = np.full((len(ids), 1), L1)
    breaks = np.zeros(ph.shape, np.int8)
    breaks[0] = ABSENT
    d = phase_deltas(ph, lam, np.array(sclk), breaks)[1, :, 0]
    var = np.full(len(ids), 1e-4)
    dpos, dclk, cov = solve_displacement(d, var, sat[0], sat[1], r0, r0 + 30.0)
    np.testing.assert_allclose(dpos, r1 - r0, atol=1e-3)
    assert abs(dclk - 300.0) < 1e-3
    assert cov.shape == (4, 4)
    # an SPP-grade first position (30 m off) costs millimetres: |e| times the 1-s change of
    # the lines of sight (about 1e-4 rad)
    off, _, _ = solve_displacement(d, var, sat[0], sat[1], r0 + 30.0)
    assert 1e-4 < np.linalg.norm(off - (r1 - r0)) < 0.01
