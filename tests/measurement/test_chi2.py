"""The plain-Python chi-square quantile against scipy (the oracle it replaces)."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk.measurement.chi2 import chi2_ppf, gamma_p, gamma_q

stats = pytest.importorskip("scipy.stats")
special = pytest.importorskip("scipy.special")


@pytest.mark.parametrize("dof", [1, 2, 3, 5, 10, 30, 100, 300])
@pytest.mark.parametrize("q", [1e-9, 1e-4, 0.05, 0.5, 0.9, 0.95, 0.99, 0.999, 1 - 1e-6, 1 - 1e-10])
def test_chi2_ppf_matches_scipy(q: float, dof: int) -> None:
    assert chi2_ppf(q, dof) == pytest.approx(stats.chi2.ppf(q, dof), rel=1e-12)


@settings(max_examples=300, derandomize=True, deadline=None)
@given(st.floats(1e-8, 1 - 1e-8), st.integers(1, 400))
def test_chi2_ppf_matches_scipy_everywhere(q: float, dof: int) -> None:
    assert chi2_ppf(q, dof) == pytest.approx(stats.chi2.ppf(q, dof), rel=1e-11)


@settings(max_examples=200, derandomize=True, deadline=None)
@given(st.floats(0.05, 200.0), st.floats(0.0, 600.0))
def test_incomplete_gamma_matches_scipy(a: float, x: float) -> None:
    assert gamma_p(a, x) == pytest.approx(special.gammainc(a, x), rel=1e-12, abs=1e-300)
    assert gamma_q(a, x) == pytest.approx(special.gammaincc(a, x), rel=1e-10, abs=1e-300)


def test_chi2_ppf_inverts_the_cdf() -> None:
    for dof in (1, 4, 17):
        for q in (0.01, 0.5, 0.999):
            assert gamma_p(dof / 2, chi2_ppf(q, dof) / 2) == pytest.approx(q, rel=1e-13)


def test_chi2_ppf_closed_form_two_dof() -> None:
    # k = 2 is exponential with mean 2: x = -2 ln(1 - q)
    for q in (1e-6, 0.3, 0.99, 1 - 1e-9):
        assert chi2_ppf(q, 2) == pytest.approx(-2.0 * math.log1p(-q), rel=1e-13)


@pytest.mark.parametrize(("q", "dof"), [(0.0, 3), (1.0, 3), (0.5, 0), (math.nan, 2)])
def test_chi2_ppf_refuses_bad_arguments(q: float, dof: int) -> None:
    with pytest.raises(ValueError):
        chi2_ppf(q, dof)
