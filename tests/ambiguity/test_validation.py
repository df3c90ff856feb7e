"""Tests of the ratio test and the Monte Carlo fixed-failure-rate ratio threshold."""

from __future__ import annotations

import math

import numpy as np
import pytest

from robustrtk.ambiguity.lambda_ import lambda_search
from robustrtk.ambiguity.par import resolve_full
from robustrtk.ambiguity.validation import ffrt_threshold, ratio_of, ratio_test


def test_ratio_of_and_test() -> None:
    assert ratio_of([2.0, 6.0]) == 3.0
    assert ratio_of([0.0, 1.0]) == math.inf
    assert ratio_of([0.0, 0.0]) == 1.0
    assert ratio_test([2.0, 6.0]).accepted  # boundary: ratio == threshold accepted
    assert not ratio_test([2.0, 5.9]).accepted
    r = ratio_test([1.0, 2.5], threshold=2.0)
    assert r.accepted and r.ratio == 2.5 and r.threshold == 2.0
    with pytest.raises(ValueError):
        ratio_test([1.0, 2.0], threshold=0.5)
    with pytest.raises(ValueError):
        ratio_of([1.0])


def _weak_q(n: int, sigma: float, rho: float) -> np.ndarray:
    C = rho * np.ones((n, n)) + (1 - rho) * np.eye(n)
    return sigma**2 * C


def test_ffrt_strong_model_accepts_everything() -> None:
    Q = 0.01 * np.eye(4)  # σ = 0.1 cycle: failure rate ~ 1e-6
    thr = ffrt_threshold(Q, pf=1e-3, rng=np.random.default_rng(0), n_samples=2000)
    assert thr == 1.0


def test_ffrt_weak_model_controls_failure_rate() -> None:
    Q = _weak_q(3, 0.35, 0.6)
    pf = 0.01
    thr = ffrt_threshold(Q, pf=pf, rng=np.random.default_rng(1), n_samples=4000)
    assert thr > 1.0
    # independent simulation: accepted wrong fixes must stay near pf
    rng = np.random.default_rng(2)
    n_check = 3000
    Lc = np.linalg.cholesky(Q)
    wrong_acc = 0
    wrong = 0
    for _ in range(n_check):
        a = Lc @ rng.standard_normal(3)
        F, s = lambda_search(a, Q)
        bad = bool(np.any(F[:, 0] != 0))
        wrong += bad
        wrong_acc += bad and ratio_of(s) >= thr
    assert wrong / n_check > 5 * pf  # the test is meaningful: many ILS failures overall
    assert wrong_acc / n_check <= pf + 3 * math.sqrt(pf * (1 - pf) / n_check)


def test_ffrt_is_reproducible_and_needs_rng() -> None:
    Q = _weak_q(4, 0.3, 0.5)
    t1 = ffrt_threshold(Q, pf=0.01, rng=np.random.default_rng(7), n_samples=500)
    t2 = ffrt_threshold(Q, pf=0.01, rng=np.random.default_rng(7), n_samples=500)
    assert t1 == t2
    with pytest.raises(ValueError):
        ffrt_threshold(Q, pf=0.01)
    with pytest.raises(ValueError):
        ffrt_threshold(Q, pf=1.5, rng=np.random.default_rng(0))


def test_ffrt_threshold_decreases_with_tolerated_failure_rate() -> None:
    Q = _weak_q(3, 0.35, 0.6)
    strict = ffrt_threshold(Q, pf=0.002, rng=np.random.default_rng(3), n_samples=3000)
    loose = ffrt_threshold(Q, pf=0.05, rng=np.random.default_rng(3), n_samples=3000)
    assert strict > loose


def test_resolve_full_with_ffrt_uses_model_threshold() -> None:
    Q = _weak_q(3, 0.35, 0.6)
    a = np.array([10.1, -3.05, 7.2])
    res = resolve_full(a, Q, method="ffrt", pf=0.01, rng=np.random.default_rng(1), n_samples=4000)
    thr = ffrt_threshold(Q, pf=0.01, rng=np.random.default_rng(1), n_samples=4000)
    assert res.threshold == thr
    assert res.validated == (res.ratio >= thr)
    with pytest.raises(ValueError):
        resolve_full(a, Q, method="bogus")  # type: ignore[arg-type]
