"""The code σ a receiver's own code minus carrier shows, per sample and at a time scale."""

from __future__ import annotations

from pathlib import Path

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


def _reference_sigma(
    t: np.ndarray, cmc: np.ndarray, lli: np.ndarray, s: np.ndarray, block: int
) -> float | None:
    """The statistic of :func:`zenith_code_sigma_m` cell by cell: arcs, stretches and blocks
    found by walking each row in time."""
    from robustrtk.measurement.code_noise import MAX_GAP_S, MIN_SAMPLES, MIN_STRETCH, STRETCH_S

    groups: dict[tuple[int, int, int], list[tuple[float, float]]] = {}
    T, R = cmc.shape
    for r in range(R):
        arc = 0
        for i in range(T):
            ok = np.isfinite(cmc[i, r]) and np.isfinite(s[i, r]) and s[i, r] >= 0.26
            if (lli[i, r] & 1) or not ok or (i > 0 and t[i] - t[i - 1] > MAX_GAP_S):
                arc += 1
            if ok:
                key = (r, arc, int(np.floor((t[i] - t[0]) / STRETCH_S)))
                groups.setdefault(key, []).append((cmc[i, r], s[i, r]))
    if sum(len(g) for g in groups.values()) < MIN_SAMPLES:
        return None
    devs: list[list[float]] = []
    for g in groups.values():
        if len(g) >= MIN_STRETCH:
            med = float(np.median([v for v, _ in g]))
            devs.append([(v - med) * sin_el for v, sin_el in g])
    if block <= 1:
        dev = np.array([d for g in devs for d in g])
        if dev.size < MIN_SAMPLES:
            return None
        return float(1.4826 * np.median(np.abs(dev - np.median(dev))))
    means = []
    for g in devs:
        for k in range(len(g) // block):
            acc = 0.0
            for d in g[k * block : (k + 1) * block]:
                acc += d
            means.append(acc / block)
    if len(means) * block < MIN_SAMPLES:
        return None
    m = np.array(means)
    return float(np.sqrt(block) * 1.4826 * np.median(np.abs(m - np.median(m))))


@given(st.integers(0, 2**32 - 1), st.sampled_from([1, 7, 30]))
def test_arcs_stretches_and_blocks_as_walked_cell_by_cell(seed: int, block: int) -> None:
    """Loss of lock, gaps, missing cells and low rows cut the arcs as a walk through each
    row does, and the estimate (per sample or per block) is the walk's."""
    rng = np.random.default_rng(seed)
    T, R = 700, 5
    t = np.cumsum(np.where(rng.random(T) < 0.01, 25.0, 1.0))  # a few gaps over MAX_GAP_S
    cmc = rng.normal(0.0, 0.5, (T, R)) + rng.integers(0, 3, R) * 7.0
    cmc[rng.random((T, R)) < 0.03] = np.nan
    lli = (rng.random((T, R)) < 0.01).astype(np.int8)
    s = rng.uniform(0.2, 1.0, (T, R))
    got = zenith_code_sigma_m(t, cmc, np.zeros((T, R)), np.ones((T, R)), lli, s, block=block)
    want = _reference_sigma(t, cmc, lli, s, block)
    if want is None:
        assert got is None
    else:
        assert got == pytest.approx(want, rel=1e-12)


def test_sampled_elevations_are_those_of_one_call_per_sample_epoch(shared_data: Path) -> None:
    """One vectorised ephemeris pass over the sample epochs gives the elevations of one
    ``positions`` call per sample epoch, held until the next sample."""
    from robustrtk.measurement.code_noise import row_sin_elevations
    from robustrtk.measurement.signals import RowSource, parse_slots, signal_rows
    from robustrtk.pipeline.gnss_inputs import load_obs, nav_source

    d = shared_data / "kamakura_kinematic_5km"
    if not d.is_dir():
        pytest.skip(f"kamakura_kinematic_5km not found in {shared_data}")
    rows = signal_rows(load_obs(d / "SEPT265G.21O", None), parse_slots("L1+L2"), "GEJ")
    eph = nav_source([d / "SEPT2650.21P"])
    pos = np.array([-3961905.0, 3348994.0, 3698212.0])

    class OneEpochAtATime:  # the source without its prefetch
        def __init__(self) -> None:
            self.src = RowSource(eph)

        def positions(
            self, t_s: float, ids: tuple[str, ...], code: np.ndarray
        ) -> tuple[np.ndarray, np.ndarray]:
            return self.src.positions(t_s, ids, code)

    batched = row_sin_elevations(rows, RowSource(eph), pos)
    single = row_sin_elevations(rows, OneEpochAtATime(), pos)  # type: ignore[arg-type]
    assert np.isfinite(batched).sum() > 1000
    np.testing.assert_array_equal(batched, single)
