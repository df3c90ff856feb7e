"""GLONASS FDMA double differences: per-channel wavelengths, receiver clocks cancelled."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk.core import CLIGHT
from robustrtk.gnss import wavelength_m
from robustrtk.measurement.base_propagation import complete_epochs
from robustrtk.measurement.dd import form_dd
from robustrtk.measurement.glonass import SdAmbiguityMeans, fdma_phase_dd, receiver_make, same_make

CHANNELS = np.array([-7, 0, 6, 3, -4])
LAM = np.array([wavelength_m("R", "1C", int(k)) for k in CHANNELS])
IDS = tuple(f"R{i:02d}:L1" for i in range(1, 6))
GROUPS = ("R:L1",) * 5


def _receiver(rho_m: np.ndarray, clock_s: float, n_cyc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Phase (cycles) and code (m) of one receiver: ``φ = (ρ + c δt)/λ + N``, ``P = ρ + c δt``."""
    return (rho_m + CLIGHT * clock_s) / LAM + n_cyc, rho_m + CLIGHT * clock_s


@settings(max_examples=40, deadline=None)
@given(
    clk_r=st.floats(-1e-3, 1e-3),
    clk_b=st.floats(-1e-3, 1e-3),
    seed=st.integers(0, 2**31 - 1),
)
def test_dd_phase_cancels_receiver_clocks(clk_r: float, clk_b: float, seed: int) -> None:
    """With the SD ambiguities from phase minus code, every DD (per-satellite wavelengths)
    equals ρ_DD/λ_i + the integer N_i − N_k, whatever the receiver clocks (up to a
    millisecond: 300 km, 1.6 million cycles of clock term in a cycle-domain DD)."""
    rng = np.random.default_rng(seed)
    rho_r = rng.uniform(19e6, 25e6, 5)
    rho_b = rho_r + rng.uniform(-50.0, 50.0, 5)
    n_r = rng.integers(-(10**6), 10**6, 5).astype(float)
    n_b = rng.integers(-(10**6), 10**6, 5).astype(float)
    ph_r, p_r = _receiver(rho_r, clk_r, n_r)
    ph_b, p_b = _receiver(rho_b, clk_b, n_b)
    refs = {"R:L1": IDS[1]}
    var = np.full(5, 1e-6)
    dd = form_dd(IDS, GROUPS, ph_r, ph_b, var / LAM**2, var / LAM**2, refs)
    sd_amb, var_n = SdAmbiguityMeans().update(
        0.0, IDS, (ph_r - ph_b) - (p_r - p_b) / LAM, np.ones(5), np.zeros(5, bool)
    )
    out = fdma_phase_dd(dd, ph_r, ph_b, var, var, LAM, sd_amb, var_n)
    sd_rho = rho_r - rho_b
    expect = (
        (sd_rho[dd.i_tx] - sd_rho[dd.i_ref]) / LAM[dd.i_tx] + (n_r - n_b)[dd.i_tx] - (n_r - n_b)[dd.i_ref]
    )
    np.testing.assert_allclose(out.z, expect, atol=2e-3)
    # the cycle-domain DD keeps the clock term and is off by whole metres
    if abs(clk_r - clk_b) > 1e-6:
        assert np.max(np.abs(dd.z - expect)) > 0.5


def test_equal_wavelength_rows_untouched() -> None:
    lam = np.full(5, 0.19)
    ph = np.arange(5.0) * 1e6
    dd = form_dd(IDS, GROUPS, ph, ph * 0.5, np.ones(5), np.ones(5), {"R:L1": IDS[0]})
    out = fdma_phase_dd(dd, ph, ph * 0.5, np.ones(5), np.ones(5), lam, np.zeros(5), np.zeros(5))
    assert out is dd


def test_sd_ambiguity_mean_restarts_on_slip() -> None:
    means = SdAmbiguityMeans()
    one = np.ones(1)
    for v in (10.0, 12.0, 14.0):
        m, var = means.update(0.0, ("R01:L1",), np.array([v]), one * 4.0, np.zeros(1, bool))
    assert m[0] == pytest.approx(12.0) and var[0] == pytest.approx(4.0 / 3.0)
    m, _ = means.update(1.0, ("R01:L1",), np.array([500.0]), one * 4.0, np.zeros(1, bool))
    assert m[0] == 500.0  # 6 σ away: a new arc
    m, _ = means.update(2.0, ("R01:L1",), np.array([502.0]), one * 4.0, np.array([True]))
    assert m[0] == 502.0


@pytest.mark.parametrize(
    ("a", "b", "same"),
    [
        ("u-blox", "UBLOX NEO-M8P", True),
        ("LEICA GR30", "u-blox", False),
        ("", "", False),
        ("TRIMBLE NETR9", "Trimble R10", True),
    ],
)
def test_same_make(a: str, b: str, same: bool) -> None:
    assert same_make({"receiver_type": a}, {"receiver_type": b}) is same
    assert receiver_make({}) == ""


def test_complete_epochs_skip_single_system_epochs() -> None:
    """A base sending GPS and GLONASS in separate messages: the epochs that lost one serve no rover."""
    system = ("G", "G", "R", "R")
    v = np.ones((6, 4))
    v[2, :2] = np.nan  # GLONASS only
    v[4, 2:] = np.nan  # GPS only
    v[5, :] = np.nan
    np.testing.assert_array_equal(complete_epochs(v, system), [True, True, False, True, False, False])
    # a system present in fewer than half the epochs is not required
    w = np.ones((4, 4))
    w[:3, 2:] = np.nan
    assert complete_epochs(w, system).all()
