"""The code σ a receiver's own code minus carrier shows, per sample and at a time scale."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from robustrtk.measurement.code_noise import group_medians, zenith_code_sigma_m


def _series(noise: np.ndarray, el_sin: float = 0.5) -> tuple[np.ndarray, ...]:
    T, R = noise.shape
    t = np.arange(T, dtype=float)
    lam = 0.19
    phase = (2.0e7 + 100.0 * t[:, None]) / lam + 1234.0  # geometry + an ambiguity per row
    code = phase * lam - 1234.0 * lam + 3.0 + noise / el_sin  # + ionosphere, elevation-scaled noise
    return t, code, phase, np.full((T, R), lam), np.zeros((T, R), np.int8), np.full((T, R), el_sin)


def test_white_code_noise_is_recovered_at_any_time_scale() -> None:
    rng = np.random.default_rng(1)
    t, code, phase, lam, lli, s = _series(rng.normal(0.0, 0.4, (1200, 8)))
    for block in (1, 30):
        assert zenith_code_sigma_m(t, code, phase, lam, lli, s, block=block) == pytest.approx(0.4, rel=0.15)


def test_correlated_multipath_needs_a_larger_sigma_at_the_filter_time_scale() -> None:
    rng = np.random.default_rng(2)
    # first-order Gauss-Markov multipath, 60-s correlation time, 0.4 m steady σ
    a = np.exp(-1.0 / 60.0)
    e = np.zeros((1200, 8))
    w = rng.normal(0.0, 0.4 * np.sqrt(1 - a * a), e.shape)
    e[0] = rng.normal(0.0, 0.4, 8)
    for k in range(1, e.shape[0]):
        e[k] = a * e[k - 1] + w[k]
    t, code, phase, lam, lli, s = _series(e)
    per_sample = zenith_code_sigma_m(t, code, phase, lam, lli, s)
    at_30s = zenith_code_sigma_m(t, code, phase, lam, lli, s, block=30)
    assert per_sample is not None and at_30s is not None
    assert per_sample < 0.45 and at_30s > 2.0 * per_sample  # averaging 30 epochs as white lies


def test_too_few_samples_tell_nothing() -> None:
    t, code, phase, lam, lli, s = _series(np.zeros((10, 3)))
    assert zenith_code_sigma_m(t, code, phase, lam, lli, s) is None


@given(
    st.lists(
        st.tuples(st.integers(0, 6), st.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False)),
        min_size=1,
        max_size=60,
    )
)
def test_group_medians_equal_numpy_median_per_group(pairs: list[tuple[int, float]]) -> None:
    """The vectorised per-group median is numpy's median of each group."""
    raw = np.asarray([g for g, _ in pairs])
    _, group = np.unique(raw, return_inverse=True)
    vals = np.asarray([v for _, v in pairs])
    counts = np.bincount(group)
    got = group_medians(group, vals, counts)
    want = [np.median(vals[group == k]) for k in range(counts.size)]
    np.testing.assert_array_equal(got, want)
