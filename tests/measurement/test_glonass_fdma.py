"""GLONASS FDMA double differences: per-channel wavelengths, receiver clocks cancelled."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk.core import CLIGHT, ObsBatch
from robustrtk.gnss import wavelength_m
from robustrtk.measurement.base_propagation import SystemFill
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


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), ref=st.integers(0, 5))
def test_dd_variance_in_metres_from_single_differences(seed: int, ref: int) -> None:
    """The FDMA DD covariance, in m² (``R_ij λ_i λ_j``), equals the brute-force one of the
    metre-domain DDs ``SD_i − SD_k − (λ_i − λ_k) N̂_k``: ``var SD_i + var SD_k`` on the
    diagonal, ``var SD_k`` between rows of one reference, plus the reference's SD-ambiguity
    term; the undifferenced variances are m² and take no wavelength."""
    rng = np.random.default_rng(seed)
    ch = np.array([-7, 0, 6, 3, -4, 0])  # R06 shares R02's channel: one row of equal wavelengths
    lam = np.array([wavelength_m("R", "1C", int(k)) for k in ch])
    ids = tuple(f"R{i:02d}:L1" for i in range(1, 7))
    var_r = rng.uniform(1e-6, 4e-4, 6)  # m²: σ from 1 to 20 mm
    var_b = rng.uniform(1e-6, 4e-4, 6)
    var_n = rng.uniform(0.0, 2.0, 6)  # cycles² of the SD ambiguities' means
    ph = rng.uniform(-1e6, 1e6, 6)
    dd = form_dd(ids, ("R:L1",) * 6, ph, 0.5 * ph, var_r / lam**2, var_b / lam**2, {"R:L1": ids[ref]})
    out = fdma_phase_dd(dd, ph, 0.5 * ph, var_r, var_b, lam, np.zeros(6), var_n)
    sd = var_r + var_b  # single-difference variances (m²)
    brute = np.empty((dd.m, dd.m))
    for a in range(dd.m):
        for b in range(dd.m):
            i, j, k = dd.i_tx[a], dd.i_tx[b], dd.i_ref[a]
            dl_i, dl_j = lam[i] - lam[k], lam[j] - lam[k]
            brute[a, b] = sd[k] + dl_i * dl_j * var_n[k] + (sd[i] if i == j else 0.0)
    lam_rows = lam[dd.i_tx]
    np.testing.assert_allclose(out.R * np.outer(lam_rows, lam_rows), brute, rtol=1e-9, atol=0.0)
    # a mixed row's σ is millimetres (not the ~0.2 × smaller a second λ² would give)
    mixed = lam[dd.i_tx] != lam[dd.i_ref]
    assert np.all(np.sqrt(np.diag(out.R) * lam_rows**2)[mixed] >= np.sqrt(2e-6))


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


class _MovingSats:
    """Satellites moving along x at 1 km/s, no clock: ranges change by a known amount."""

    def positions(
        self, t_s: float, tx_ids: tuple[str, ...], code_m: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        n = len(tx_ids)
        p = np.tile([2e7, 0.0, 0.0], (n, 1)) + np.arange(n)[:, None] * [0.0, 1e6, 0.0]
        p[:, 0] += 1000.0 * t_s
        return p, np.zeros(n)


def test_system_fill_completes_single_system_epochs() -> None:
    """A base sending GPS and GLONASS in separate messages: an epoch that lost its GPS message
    gets GPS from the latest earlier epoch, carried to its tag; loss-of-lock not repeated."""
    t = np.array([0.0, 1.0, 2.0, 3.0])
    n = 4
    phase = np.full((4, n, 1), 1e7)
    code = np.full((4, n, 1), 2e7)
    phase[2, :2] = np.nan  # epoch 2: GLONASS only
    code[2, :2] = np.nan
    lli = np.zeros((4, n, 1), np.int8)
    lli[1, 0] = 3
    wl = np.full((n, 1), 0.19)
    b = ObsBatch(
        t_s=t, tx_ids=("G01:L1", "G02:L1", "R01:L1", "R02:L1"), system=("G", "G", "R", "R"), signals=("f",),
        code_m=code, phase_cyc=phase, doppler_hz=np.full((4, n, 1), np.nan),
        cn0_dbhz=np.full((4, n, 1), 45.0),
        lli=lli, wavelength_m=wl,
    )  # fmt: skip
    pos = np.zeros(3)
    fill = SystemFill(b, _MovingSats(), pos, 30.0, sagnac=False, troposphere=False)
    ep = fill.epoch(2)
    y = np.array([0.0, 1e6])
    moved = np.hypot(2e7 + 2000.0, y) - np.hypot(2e7 + 1000.0, y)  # range change from t = 1 s to 2 s
    np.testing.assert_allclose(ep.code_m[:2, 0], 2e7 + moved, rtol=0, atol=1e-3)
    np.testing.assert_allclose(ep.phase_cyc[:2, 0], 1e7 + moved / 0.19, rtol=0, atol=1e-2)
    assert ep.lli[0, 0] == 2  # half-cycle bit kept, loss of lock reported once (epoch 1)
    assert np.array_equal(fill.epoch(1).phase_cyc, b.phase_cyc[1])
    # too old: no fill
    assert np.isnan(
        SystemFill(b, _MovingSats(), pos, 0.5, sagnac=False, troposphere=False).epoch(2).code_m[0, 0]
    )
