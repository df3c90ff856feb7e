"""The age of the base in the DD weights and the age-free share of a position's variance."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk.measurement.base_propagation import age_dd_covariance_m2, age_free_fraction
from robustrtk.measurement.dd import form_dd

IDS = ("G01", "G02", "G03", "G04", "G05", "E01", "E02", "E03")
GROUPS = ("G",) * 5 + ("E",) * 3


def _geometry(rng: np.random.Generator, m: int) -> np.ndarray:
    """DD-like position rows: differences of unit line-of-sight vectors."""
    u = rng.normal(size=(m + 1, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    return np.asarray(u[1:] - u[0], float)


def _whitened_trace(H: np.ndarray, R: np.ndarray) -> float:
    """tr (Hᵀ R⁻¹ H)⁻¹ by whitening with R's Cholesky factor and a QR of the whitened rows."""
    L = np.linalg.cholesky(R)
    A = np.linalg.solve(L, H)
    _, r = np.linalg.qr(A)
    rinv = np.linalg.inv(r)
    return float(np.sum(rinv**2))


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), age_var=st.floats(1e-8, 1e-2))
def test_age_covariance_is_the_base_side_of_the_dd(seed: int, age_var: float) -> None:
    """``age_var · D_b D_bᵀ`` is the DD covariance of zero rover variances and ``age_var`` on
    every base row (form_dd's own ``D diag(var) Dᵀ``)."""
    rng = np.random.default_rng(seed)
    obs = rng.normal(size=8)
    refs = {"G": IDS[int(rng.integers(0, 5))], "E": IDS[5 + int(rng.integers(0, 3))]}
    dd = form_dd(IDS, GROUPS, obs, obs, np.zeros(8), np.full(8, age_var), refs)
    np.testing.assert_allclose(age_dd_covariance_m2(dd.D, 8, age_var), dd.R, rtol=1e-12, atol=0.0)


def test_no_age_no_share_taken() -> None:
    rng = np.random.default_rng(1)
    H = _geometry(rng, 6)
    R = np.eye(6) * 1e-4 + 1e-4
    assert age_free_fraction(H, R, np.zeros((6, 6))) == 1.0
    assert age_free_fraction(H[:2], R[:2, :2], R[:2, :2] * 0.5) == 1.0  # no position from 2 rows


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), c=st.floats(0.01, 100.0))
def test_proportional_age_share(seed: int, c: float) -> None:
    """An age part proportional to the rest, ``R_age = c R₀``, scales the covariance by
    ``1 + c``: the age-free share is exactly ``1 / (1 + c)``."""
    rng = np.random.default_rng(seed)
    m = int(rng.integers(4, 10))
    H = _geometry(rng, m)
    A = rng.normal(size=(m, m))
    R0 = A @ A.T * 1e-5 + np.eye(m) * 1e-5
    f = age_free_fraction(H, (1.0 + c) * R0, c * R0)
    assert abs(f - 1.0 / (1.0 + c)) <= 1e-9


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), age_var=st.floats(1e-7, 1e-3))
def test_share_against_whitened_least_squares(seed: int, age_var: float) -> None:
    """The share equals the trace ratio computed independently (Cholesky whitening, QR), lies
    in (0, 1] and falls as the age variance grows."""
    rng = np.random.default_rng(seed)
    m = int(rng.integers(4, 10))
    H = _geometry(rng, m)
    sd = rng.uniform(1e-6, 1e-4, m + 1)  # single-difference variances, the reference last
    R0 = np.diag(sd[:m]) + sd[m]
    R_age = age_var * (np.eye(m) + 1.0)  # a base row per satellite, the reference shared
    f = age_free_fraction(H, R0 + R_age, R_age)
    expect = _whitened_trace(H, R0) / _whitened_trace(H, R0 + R_age)
    assert abs(f - expect) <= 1e-9 * max(1.0, expect)
    assert 0.0 < f <= 1.0
    assert age_free_fraction(H, R0 + 4.0 * R_age, 4.0 * R_age) < f
