"""Cycle-slip detectors on synthetic series with known slips."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from robustrtk.core import InputError
from robustrtk.cycleslip import (
    PolyFitDetector,
    doppler_phase_residual_cyc,
    doppler_phase_slips,
    gf_slips,
    half_cycle_flags,
    lli_slips,
    polyfit_slips,
    reset_mask,
)

LAM_M = 0.19
NOISE_M = 0.003
NOISE_CYC = NOISE_M / LAM_M


def rail_dd_cyc(t_s: np.ndarray) -> np.ndarray:
    """Noise-free DD phase (cycles) of a rover moving back and forth along a 6 m rail.

    Five ceiling pseudolites (the last is the reference), static base; the rover's
    position follows x = -3 + 3 (1 - cos(2 pi t / 20 s)) m (peak 0.94 m/s).
    """
    pls = np.array([[-4, -3, 4.0], [4, -3, 3.9], [4, 3, 4.0], [-4, 3, 3.8], [0, 0, 4.0]], dtype=float)
    base = np.array([-2.0, -1.0, 1.0])
    x = -3.0 + 3.0 * (1.0 - np.cos(2.0 * np.pi * (t_s - t_s[0]) / 20.0))
    rov = np.stack([x, np.full_like(x, 0.5), np.full_like(x, 1.2)], axis=1)
    sd = np.linalg.norm(rov[:, None, :] - pls[None], axis=2) - np.linalg.norm(base - pls, axis=1)
    return (sd[:, :4] - sd[:, 4:5]) / LAM_M


def noisy_dd(rng: np.random.Generator, t_s: np.ndarray) -> np.ndarray:
    clean = rail_dd_cyc(t_s) + rng.integers(-50, 50, 4)
    return clean + rng.normal(0.0, NOISE_CYC, clean.shape)


# ----------------------------------------------------------------------------- LLI
def test_lli_bits() -> None:
    lli = np.arange(8, dtype=np.int8).reshape(2, 4)
    np.testing.assert_array_equal(lli_slips(lli), (np.arange(8) % 2 == 1).reshape(2, 4))
    np.testing.assert_array_equal(half_cycle_flags(lli), np.isin(np.arange(8), [2, 3, 6, 7]).reshape(2, 4))


# ------------------------------------------------------------------ polynomial fit
def test_polyfit_no_false_alarm_on_10000_clean_epochs() -> None:
    rng = np.random.default_rng(20190101)
    t = 1000.0 + np.arange(10_000) / 10.0
    ph = noisy_dd(rng, t)
    slip, rep, jump = polyfit_slips(t, ph, window=10, degree=2, noise_cyc=NOISE_CYC)
    assert slip.sum() == 0
    np.testing.assert_array_equal(rep, ph)
    assert np.all(jump == 0)


def test_polyfit_detects_and_repairs_one_cycle_slips() -> None:
    rng = np.random.default_rng(7)
    T = 12_000
    t = 50.0 + np.arange(T) / 10.0
    clean = noisy_dd(rng, t)
    # 300 slips: every 40 epochs, random series, sizes mostly +-1 cycle, some larger.
    at = np.arange(100, T - 10, 40)[:300]
    which = rng.integers(0, 4, at.size)
    size = rng.choice([-1, 1, -1, 1, 2, -3, 17], at.size)
    steps = np.zeros_like(clean)
    steps[at, which] = size
    ph = clean + np.cumsum(steps, axis=0)

    slip, rep, jump = polyfit_slips(t, ph, window=10, degree=2, noise_cyc=NOISE_CYC)
    truth = steps != 0
    detected = slip[truth].mean()
    assert detected >= 0.99
    assert slip[~truth].sum() == 0  # no false alarm between the slips
    # Every detected slip is repaired to the injected integer ...
    np.testing.assert_array_equal(jump[truth & slip], steps[truth & slip])
    assert not reset_mask(slip, jump).any()
    # ... so the repaired series is the clean one plus the (zero) initial offset.
    np.testing.assert_allclose(rep, clean, atol=1e-9)


def test_polyfit_half_cycle_jump_is_reset_not_repaired() -> None:
    rng = np.random.default_rng(3)
    t = np.arange(200) / 10.0
    ph = noisy_dd(rng, t)[:, 0]
    ph[120:] += 0.5
    slip, rep, jump = polyfit_slips(t, ph, noise_cyc=NOISE_CYC)
    assert np.flatnonzero(slip).tolist() == [120]
    assert np.isnan(jump[120])
    assert reset_mask(slip, jump)[120]
    # After a reset the new arc is the raw phase (no correction carried over).
    np.testing.assert_array_equal(rep[120:], ph[120:])


def test_polyfit_nan_gap_late_start_and_nonuniform_steps() -> None:
    rng = np.random.default_rng(11)
    dt = rng.uniform(0.05, 0.15, 3000)
    t = 10.0 + np.cumsum(dt)
    ph = noisy_dd(rng, t)
    ph[:500, 1] = np.nan  # series 1 starts late
    ph[1000:1003, 2] = np.nan  # series 2 has a 3-epoch gap
    ph[2000:, 3] += 1.0  # a slip on series 3 with irregular epochs
    slip, rep, jump = polyfit_slips(t, ph, noise_cyc=NOISE_CYC)
    assert np.flatnonzero(slip[:, 0]).size == 0
    assert np.flatnonzero(slip[:, 1]).size == 0  # a late start is not a slip
    assert np.flatnonzero(slip[:, 2]).tolist() == [1003]  # return after the gap
    assert np.isnan(jump[1003, 2])
    assert np.isnan(rep[1000:1003, 2]).all()
    assert np.flatnonzero(slip[:, 3]).tolist() == [2000]
    assert jump[2000, 3] == 1.0

    # Without gap flagging, the window simply restarts.
    slip2, _, _ = polyfit_slips(t, ph, noise_cyc=NOISE_CYC, flag_after_gap=False)
    assert slip2[:, 2].sum() == 0


def test_polyfit_streaming_matches_batch_and_rejects_bad_input() -> None:
    rng = np.random.default_rng(5)
    t = np.arange(300) / 10.0
    ph = noisy_dd(rng, t)
    ph[150:, 0] -= 2.0
    batch = polyfit_slips(t, ph, noise_cyc=NOISE_CYC)
    det = PolyFitDetector(noise_cyc=NOISE_CYC)
    for i in range(t.size):
        s, r, j = det.step(t[i], ph[i])
        np.testing.assert_array_equal(s, batch[0][i])
        np.testing.assert_array_equal(r, batch[1][i])
    with pytest.raises(InputError):
        det.step(t[-1], ph[-1])  # time not increasing
    with pytest.raises(InputError):
        det.step(t[-1] + 1.0, ph[-1, :3])  # wrong number of series
    with pytest.raises(InputError):
        PolyFitDetector(window=3, degree=2)


@settings(max_examples=40, deadline=None)
@given(
    k=st.integers(-1000, 1000).filter(lambda v: v != 0),
    at=st.integers(20, 70),
    seed=st.integers(0, 2**32 - 1),
)
@example(k=1, at=20, seed=224)  # the noise puts the float jump 0.099 cycles off: refused
def test_polyfit_repairs_any_integer(k: int, at: int, seed: int) -> None:
    """Any integer jump is found at its epoch and repaired exactly — unless the noise of
    that epoch put the detector's own float estimate beyond its repair tolerance
    (``repair_sigma`` σ_d from the integer), where it must refuse and reset instead of
    guessing (a few seeds in ten thousand)."""
    rng = np.random.default_rng(seed)
    t = np.arange(90) / 10.0
    clean = noisy_dd(rng, t)[:, 1]
    ph = clean.copy()
    ph[at:] += k
    slip, rep, jump = polyfit_slips(t, ph, noise_cyc=NOISE_CYC)
    assert np.flatnonzero(slip).tolist() == [at]
    det = PolyFitDetector(noise_cyc=NOISE_CYC)
    for i in range(at + 1):
        det.step(t[i], ph[i : i + 1])
    d = float(det.last_jump_float_cyc[0])
    sigma_d = abs(d) / float(det.last_test_stat[0])
    if abs(d - k) <= det.repair_sigma * sigma_d:
        assert jump[at] == k
        np.testing.assert_allclose(rep, clean, atol=1e-9)
    else:
        assert np.isnan(jump[at])


# ----------------------------------------------------------------- geometry free
F1, F2 = 1575.42e6, 1227.60e6
L1, L2 = 299_792_458.0 / F1, 299_792_458.0 / F2


def two_freq(rng: np.random.Generator, T: int, N: int) -> tuple[np.ndarray, ...]:
    t = 3.0e5 + np.arange(T, dtype=float)  # 1 Hz
    tt = (t - t[0])[:, None]
    rng0 = rng.uniform(2.0e7, 2.5e7, N)
    rate = rng.uniform(-700, 700, N)
    acc = rng.uniform(-0.1, 0.1, N)
    r = rng0 + rate * tt + 0.5 * acc * tt**2
    iono1 = 3.0 + 0.5 * np.sin(2 * np.pi * tt / 7200.0 + rng.uniform(0, 6, N))
    clk = 30.0 * tt  # receiver clock drift, common to all
    noise = 0.002
    p1 = (r + clk - iono1) / L1 + rng.integers(-1e6, 1e6, N) + rng.normal(0, noise / L1, r.shape)
    iono2 = iono1 * (F1 / F2) ** 2
    p2 = (r + clk - iono2) / L2 + rng.integers(-1e6, 1e6, N) + rng.normal(0, noise / L2, r.shape)
    return t, p1, p2, r


def test_gf_detects_injected_slips_and_no_false_alarm() -> None:
    rng = np.random.default_rng(42)
    T, N = 3000, 8
    t, p1, p2, _ = two_freq(rng, T, N)
    assert gf_slips(t, p1, p2, L1, L2).sum() == 0  # clean
    steps1 = np.zeros((T, N))
    steps2 = np.zeros((T, N))
    at = rng.choice(np.arange(1, T), 200, replace=False)
    col = rng.integers(0, N, at.size)
    pairs = np.array([[1, 0], [0, 1], [-1, 0], [0, -1], [1, 1], [2, 1], [-5, 3], [4, 4]])
    pick = pairs[rng.integers(0, len(pairs), at.size)]
    steps1[at, col] = pick[:, 0]
    steps2[at, col] = pick[:, 1]
    s1 = p1 + np.cumsum(steps1, axis=0)
    s2 = p2 + np.cumsum(steps2, axis=0)
    slip = gf_slips(t, s1, s2, L1, L2)
    truth = (steps1 != 0) | (steps2 != 0)
    np.testing.assert_array_equal(slip, truth)


def test_gf_compares_across_nan_and_flags_long_gaps() -> None:
    rng = np.random.default_rng(1)
    t, p1, p2, _ = two_freq(rng, 100, 2)
    p1[40:45, 0] = np.nan
    p1[45:, 0] += 1.0  # slip hidden in the gap
    slip = gf_slips(t, p1, p2, L1, L2)
    assert np.flatnonzero(slip[:, 0]).tolist() == [45]
    assert slip[:, 1].sum() == 0
    p1[60:70, 1] = np.nan
    slip = gf_slips(t, p1, p2, L1, L2, max_gap_s=5.0)
    assert np.flatnonzero(slip[:, 1]).tolist() == [70]


# ----------------------------------------------------------------------- Doppler
def test_doppler_phase_detects_slips_with_rinex_sign() -> None:
    rng = np.random.default_rng(9)
    T, N = 2000, 6
    t, p1, _, r = two_freq(rng, T, N)
    # Range rate of the generator (+ 30 m/s clock drift); Doppler is its negative / lambda.
    rdot = np.gradient(r, t, axis=0) + 30.0
    dop = -rdot / L1 + rng.normal(0, 0.05, rdot.shape)
    resid = doppler_phase_residual_cyc(t, p1, dop)
    assert np.nanmax(np.abs(resid)) < 0.5
    assert doppler_phase_slips(t, p1, dop).sum() == 0
    # The opposite sign convention is loud: it fails wherever the Doppler exceeds 1 Hz.
    wrong = doppler_phase_slips(t, p1, dop, sign=+1.0)
    moving = np.abs(dop) > 1.0
    moving[0] = False
    assert moving.sum() > 0.9 * moving.size
    assert wrong[moving].all()

    steps = np.zeros((T, N))
    at = rng.choice(np.arange(1, T), 100, replace=False)
    steps[at, rng.integers(0, N, at.size)] = rng.choice([-3, -2, -1, 1, 2, 5], at.size)
    slip = doppler_phase_slips(t, p1 + np.cumsum(steps, axis=0), dop)
    np.testing.assert_array_equal(slip, steps != 0)


def test_series_validation() -> None:
    with pytest.raises(InputError):
        gf_slips([0.0, 0.0], [1.0, 2.0], [1.0, 2.0], L1, L2)
    with pytest.raises(InputError):
        doppler_phase_slips([0.0, 1.0], [1.0, 2.0, 3.0], [1.0, 2.0])


def test_half_cycle_transitions_flag_each_change_of_the_bit_on_a_running_arc() -> None:
    from robustrtk.cycleslip.lli import half_cycle_transitions

    nan = np.nan
    phase = np.array([[1.0, nan], [2.0, 5.0], [nan, 6.0], [4.0, 7.0], [5.0, 8.0]])
    lli = np.array([[2, 0], [2, 2], [0, 2], [0, 2], [2, 0]])
    got = half_cycle_transitions(phase, lli)
    # column 0: set, set, (absent: its bit ignored), cleared -> jump, set again -> jump
    # column 1: first phase carries the bit (no earlier phase), kept, kept, cleared -> jump
    want = np.array([[0, 0], [0, 0], [0, 0], [1, 0], [1, 1]], dtype=bool)
    np.testing.assert_array_equal(got, want)


def test_gf_drift_flags_a_slow_drift_that_the_epoch_test_misses() -> None:
    from robustrtk.cycleslip.geometry_free import gf_drift_slips, gf_slips

    lam1, lam2 = 0.1903, 0.2548
    t = np.arange(60.0)
    rng = np.random.default_rng(3)
    geo_m = 2.0e7 + 500.0 * t  # common range: cancels in the geometry-free combination
    iono_m = 0.0005 * t  # 0.5 mm/s of ionosphere, far below the thresholds
    drift_m = np.where(t >= 30, 0.02 * (t - 30), 0.0)  # 2 cm/s on frequency 1 from epoch 30
    p1 = (geo_m - iono_m + drift_m + rng.normal(0, 0.003, t.size)) / lam1
    p2 = (geo_m - iono_m * (lam2 / lam1) ** 2 + rng.normal(0, 0.003, t.size)) / lam2
    p1, p2 = p1[:, None], p2[:, None]
    lli = np.zeros((t.size, 1), dtype=np.int8)
    assert not gf_slips(t, p1, p2, lam1, lam2).any()  # each epoch moves 2 cm < 5 cm
    got = gf_drift_slips(t, p1, p2, lam1, lam2, lli, lli, window_s=10.0, threshold_m=0.1)[:, 0]
    # flagged once the drift over the window exceeds 10 cm (5 s after its start), never before
    assert not got[:33].any()
    assert got[37:].all()
    # a loss of lock restarts the arc: the window does not reach across it
    lli2 = lli.copy()
    lli2[45, 0] = 1
    got2 = gf_drift_slips(t, p1, p2, lam1, lam2, lli2, lli, window_s=10.0, threshold_m=0.1)[:, 0]
    assert not got2[45:50].any() and got2[52:].all()
