"""Tests of the LAMBDA implementation against reference vectors and brute-force ILS."""

from __future__ import annotations

import itertools
import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.stats import norm

from robustrtk.ambiguity.lambda_ import (
    bootstrap_success_rate,
    decorrelate,
    lambda_search,
    ltdl,
    search,
)


def _vectors(shared_data: Path) -> dict:  # type: ignore[type-arg]
    with open(shared_data / "testvectors" / "testvectors.json") as fh:
        return json.load(fh)  # type: ignore[no-any-return]


def _sqnorm(a: np.ndarray, Q: np.ndarray, z: np.ndarray) -> float:
    e = a - z
    return float(e @ np.linalg.solve(Q, e))


def enumerate_ils(a: np.ndarray, Q: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """All integer z with (a−z)ᵀ Q⁻¹ (a−z) ≤ radius.

    Plain Fincke–Pohst enumeration on the Cholesky factor of Q⁻¹ (no decorrelation, no
    zig-zag, breadth first over whole levels): an independent reference for the search.
    """
    n = a.shape[0]
    W = np.linalg.inv(Q)
    R = np.linalg.cholesky(0.5 * (W + W.T)).T  # Q⁻¹ = Rᵀ R, R upper
    Zp = np.zeros((1, 0))
    part = np.zeros(1)
    for k in range(n - 1, -1, -1):
        c = (a[k + 1 :][None, :] - Zp) @ R[k, k + 1 :]
        centre = a[k] + c / R[k, k]
        half = np.sqrt(np.maximum(radius - part, 0.0)) / R[k, k]
        lo = np.ceil(centre - half).astype(np.int64)
        hi = np.floor(centre + half).astype(np.int64)
        cnt = np.maximum(hi - lo + 1, 0)
        rep = np.repeat(np.arange(Zp.shape[0]), cnt)
        offs = np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt)
        zk = (lo[rep] + offs).astype(float)
        part = part[rep] + (R[k, k] * (a[k] - zk) + c[rep]) ** 2
        Zp = np.column_stack([zk, Zp[rep]])
        keep = part <= radius
        Zp, part = Zp[keep], part[keep]
    order = np.argsort(part)
    return Zp[order], part[order]


def brute_force_box(a: np.ndarray, Q: np.ndarray, half_width: np.ndarray) -> tuple:  # type: ignore[type-arg]
    """Exhaustive ILS over the box round(a) ± half_width; returns candidates sorted by norm."""
    centre = np.round(a)
    axes = [np.arange(c - w, c + w + 1) for c, w in zip(centre, half_width, strict=True)]
    grid = np.array(list(itertools.product(*axes)), dtype=float)
    E = a[None, :] - grid
    s = np.einsum("ij,ij->i", E, np.linalg.solve(Q, E.T).T)
    order = np.argsort(s)
    return grid[order], s[order]


# --------------------------------------------------------------------------- reference vectors


@pytest.mark.parametrize("case", ["case1", "case2"])
def test_rtklib_cases(shared_data: Path, case: str) -> None:
    v = _vectors(shared_data)[case]
    F, s = lambda_search(v["a_float"], v["Q"], m=v["m"])
    expected = np.array(v["F_best_candidates_columns"]).T
    np.testing.assert_array_equal(F, expected)
    np.testing.assert_allclose(s, v["s_squared_residuals"], atol=v["tolerance"], rtol=0)


def test_tudelft_small_matches_bruteforce(shared_data: Path) -> None:
    v = _vectors(shared_data)["lambda3_small"]
    a = np.array(v["a_float"])
    Q = np.array(v["Q"])
    F, s = lambda_search(a, Q)
    ref = v["ils_best2_bruteforce_here"]
    np.testing.assert_array_equal(F.T, np.array(ref["z"], dtype=float))
    np.testing.assert_allclose(s, ref["sqnorm"], rtol=1e-6)
    grid, sb = brute_force_box(a, Q, np.full(3, 8))
    np.testing.assert_array_equal(F.T, grid[:2])
    np.testing.assert_allclose(s, sb[:2], rtol=1e-10)


def test_tudelft_sixdim_matches_enumeration(shared_data: Path) -> None:
    v = _vectors(shared_data)["lambda3_sixdim"]
    a = np.array(v["a_float"])
    Q = np.array(v["Q"])
    F, s = lambda_search(a, Q)
    # the enumeration in the original (strongly correlated) space is independent of Z
    Zp, part = enumerate_ils(a, Q, s[1] * (1 + 1e-9) + 1e-12)
    assert Zp.shape[0] == 2
    np.testing.assert_array_equal(F.T, Zp)
    np.testing.assert_allclose(s, part, rtol=1e-7)
    # pinned (computed by both methods)
    np.testing.assert_array_equal(F[:, 0], [-28506, 65833, 38880, 5008, -29210, -257])
    np.testing.assert_allclose(s, [0.18816915, 0.22739015], rtol=1e-6)


@pytest.mark.parametrize("case", ["lambda3_large", "case2"])
def test_large_cases_match_enumeration_in_z_space(shared_data: Path, case: str) -> None:
    """Too big to enumerate in the original space: enumerate the equivalent problem
    ``(Zᵀâ, ZᵀQZ)`` with the plain enumerator (Z checked unimodular) and map back."""
    v = _vectors(shared_data)[case]
    a = np.array(v["a_float"])
    Q = np.array(v["Q"])
    F, s = lambda_search(a, Q)
    Z, _, _, z_hat = decorrelate(Q, a - np.round(a))
    assert abs(round(np.linalg.det(Z))) == 1
    Zp, part = enumerate_ils(z_hat, Z.T @ Q @ Z, s[1] * (1 + 1e-7))
    assert Zp.shape[0] == 2
    back = np.round(np.linalg.solve(Z.T, Zp.T)) + np.round(a)[:, None]
    np.testing.assert_array_equal(F, back)
    np.testing.assert_allclose(s, part, rtol=1e-6)
    for j in range(2):
        assert _sqnorm(a, Q, F[:, j]) == pytest.approx(s[j], rel=1e-6)


def test_large_pinned(shared_data: Path) -> None:
    v = _vectors(shared_data)["lambda3_large"]
    F, s = lambda_search(v["a_float"], v["Q"])
    np.testing.assert_array_equal(
        F[:, 0],
        [-28451, 65749, 38814, 5025, -29165, -278, -22170, 51233, 30245, 3916, -22725, -144],
    )
    np.testing.assert_allclose(s, [15.01656, 31.634829], rtol=1e-6)


# --------------------------------------------------------------------------- factorisation


def _random_spd(rng: np.random.Generator, n: int, sigma: float, rho: float) -> np.ndarray:
    """SPD covariance with a common correlated part (DD-like) plus random structure."""
    B = rng.standard_normal((n, n + 2))
    C = B @ B.T / (n + 2)
    C = rho * np.ones((n, n)) + (1 - rho) * (C / np.sqrt(np.outer(np.diag(C), np.diag(C))))
    s = sigma * np.exp(rng.uniform(-0.5, 0.5, n))
    return C * np.outer(s, s)


def test_ltdl_reconstructs_and_conditional_variances() -> None:
    rng = np.random.default_rng(3)
    Q = _random_spd(rng, 6, 1.0, 0.7)
    L, d = ltdl(Q)
    np.testing.assert_allclose(L.T @ np.diag(d) @ L, Q, atol=1e-12)
    np.testing.assert_array_equal(np.triu(L, 1), 0.0)
    np.testing.assert_array_equal(np.diag(L), 1.0)
    # d[0] is the variance of a0 given all others; d[-1] the unconditional variance of a[-1]
    assert d[0] == pytest.approx(1.0 / np.linalg.inv(Q)[0, 0], rel=1e-10)
    assert d[-1] == pytest.approx(Q[-1, -1], rel=1e-14)


@pytest.mark.parametrize(
    "Q",
    [
        np.array([[1.0, 2.0], [2.0, 1.0]]),
        np.array([[-1.0]]),
        np.array([[1.0, 1.0], [1.0, 1.0]]),
        np.array([[1.0, 0.2], [0.1, 1.0]]),
        np.array([[1.0, np.nan], [np.nan, 1.0]]),
    ],
)
def test_non_positive_definite_raises(Q: np.ndarray) -> None:
    with pytest.raises(ValueError):
        lambda_search(np.zeros(Q.shape[0]), Q)


def test_bad_shapes_raise() -> None:
    with pytest.raises(ValueError):
        lambda_search(np.zeros(3), np.eye(2))
    with pytest.raises(ValueError):
        lambda_search(np.array([np.nan, 0.0]), np.eye(2))
    with pytest.raises(ValueError):
        lambda_search(np.zeros(2), np.eye(2), m=0)


def test_n1_is_rounding() -> None:
    F, s = lambda_search([2.3], [[0.04]], m=3)
    np.testing.assert_array_equal(F, [[2.0, 3.0, 1.0]])
    np.testing.assert_allclose(s, [0.09 / 0.04, 0.49 / 0.04, 1.69 / 0.04])
    F, s = lambda_search([-7.8], [[1.0]])
    np.testing.assert_array_equal(F[0], [-8.0, -7.0])


def test_decorrelation_reduces_correlation() -> None:
    rng = np.random.default_rng(11)
    Q = _random_spd(rng, 8, 3.0, 0.95)
    Z, L, d, _ = decorrelate(Q, np.zeros(8))
    Qz = Z.T @ Q @ Z
    sd = np.sqrt(np.diag(Qz))
    corr_before = np.abs(Q / np.sqrt(np.outer(np.diag(Q), np.diag(Q))) - np.eye(8)).max()
    corr_after = np.abs(Qz / np.outer(sd, sd) - np.eye(8)).max()
    assert corr_after < corr_before
    assert np.all(np.abs(np.tril(L, -1)) <= 0.5 + 1e-12)
    # no remaining swap condition is violated
    for j in range(7):
        assert d[j] + L[j + 1, j] ** 2 * d[j + 1] >= d[j + 1] - 1e-6


# --------------------------------------------------------------------------- properties

spd_params = st.tuples(
    st.integers(min_value=0, max_value=2**32 - 1),
    st.integers(min_value=1, max_value=4),
    st.floats(min_value=0.05, max_value=1.5),
    st.floats(min_value=0.0, max_value=0.97),
)


@settings(max_examples=60, deadline=None)
@given(spd_params)
def test_z_unimodular_and_reconstruction(params: tuple[int, int, float, float]) -> None:
    seed, n, sigma, rho = params
    rng = np.random.default_rng(seed)
    Q = _random_spd(rng, n, sigma, rho)
    a = rng.normal(0.0, 50.0, n)
    Z, L, d, z_hat = decorrelate(Q, a)
    np.testing.assert_array_equal(Z, np.round(Z))
    assert abs(np.linalg.det(Z)) == pytest.approx(1.0, abs=1e-9)
    np.testing.assert_allclose(Z.T @ Q @ Z, L.T @ np.diag(d) @ L, atol=1e-9 * np.abs(Q).max())
    np.testing.assert_allclose(z_hat, Z.T @ a, atol=1e-9)
    assert np.all(d > 0)


@settings(max_examples=80, deadline=None)
@given(spd_params, st.floats(min_value=-1e6, max_value=1e6))
def test_lambda_search_matches_brute_force(params: tuple[int, int, float, float], offset: float) -> None:
    seed, n, sigma, rho = params
    rng = np.random.default_rng(seed)
    Q = _random_spd(rng, n, sigma, rho)
    a = offset + rng.normal(0.0, 3.0, n)
    F, s = lambda_search(a, Q, m=2)
    for j in range(2):
        assert _sqnorm(a, Q, F[:, j]) == pytest.approx(s[j], rel=1e-7, abs=1e-9)
    # every point with norm ≤ s2 lies within |a_i − z_i| ≤ √(s2 Q_ii): the box is complete
    half = np.ceil(np.sqrt(s[1] * np.diag(Q))).astype(int) + 1
    grid, sb = brute_force_box(a, Q, half)
    np.testing.assert_allclose(s, sb[:2], rtol=1e-7, atol=1e-9)
    if sb[1] - sb[0] > 1e-7 * max(sb[1], 1.0):
        np.testing.assert_array_equal(F[:, 0], grid[0])
    if sb.shape[0] > 2 and sb[2] - sb[1] > 1e-7 * max(sb[2], 1.0):
        np.testing.assert_array_equal(F[:, 1], grid[1])


@settings(max_examples=30, deadline=None)
@given(spd_params)
def test_search_returns_sorted_distinct_candidates(params: tuple[int, int, float, float]) -> None:
    seed, n, sigma, rho = params
    rng = np.random.default_rng(seed)
    Q = _random_spd(rng, n, sigma, rho)
    Z, L, d, z_hat = decorrelate(Q, rng.normal(0.0, 2.0, n))
    Zfix, s = search(L, d, z_hat, m=5)
    assert np.all(np.diff(s) >= 0)
    assert len({tuple(c) for c in Zfix.T}) == 5
    Qz = L.T @ np.diag(d) @ L
    for j in range(5):
        assert _sqnorm(z_hat, Qz, Zfix[:, j]) == pytest.approx(s[j], rel=1e-7, abs=1e-9)


# --------------------------------------------------------------------------- success rate


def test_bootstrap_success_rate_formula() -> None:
    d = np.array([0.01, 0.04, 0.25])
    expected = np.prod(2 * norm.cdf(1 / (2 * np.sqrt(d))) - 1)
    assert bootstrap_success_rate(d) == pytest.approx(expected, rel=1e-12)
    assert bootstrap_success_rate([]) == 1.0
    with pytest.raises(ValueError):
        bootstrap_success_rate([0.1, 0.0])


def test_bootstrap_success_rate_matches_monte_carlo() -> None:
    """For a diagonal Q, bootstrapping is rounding: compare with simulated rounding."""
    rng = np.random.default_rng(5)
    sd = np.array([0.2, 0.3, 0.25])
    x = rng.standard_normal((200_000, 3)) * sd
    p_mc = np.mean(np.all(np.round(x) == 0, axis=1))
    p = bootstrap_success_rate(sd**2)
    assert p == pytest.approx(p_mc, abs=4 * math.sqrt(p * (1 - p) / 200_000))
