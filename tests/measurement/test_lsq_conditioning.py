"""The least squares' conditioning test without singular values where a bound settles it:
the same verdict as ``cond₂(N) > 1e14`` and the same inverse; and the C/N0 variance terms
with NaN replaced by the reference without clamping infinities: the same numbers."""

from __future__ import annotations

import numpy as np
import pytest

from robustrtk.measurement.undifferenced import _inverse_if_conditioned, cn0_variance, elevation_cn0_variance


@pytest.mark.parametrize("seed", range(6))
def test_verdict_and_inverse_as_the_condition_number(seed: int) -> None:
    rng = np.random.default_rng(seed)
    for k in (4, 5, 7):
        for log_cond in np.linspace(0.0, 17.0, 35):
            q, _ = np.linalg.qr(rng.normal(size=(k, k)))
            s = np.logspace(0.0, -log_cond, k) * float(rng.uniform(1e-3, 1e6))
            N = (q * s) @ q.T
            N = 0.5 * (N + N.T)
            got = _inverse_if_conditioned(N)
            if np.linalg.cond(N) > 1e14:
                assert got is None
            else:
                assert got is not None
                np.testing.assert_array_equal(got, np.linalg.inv(N))


def test_singular_and_nan_matrices() -> None:
    N = np.ones((4, 4))
    assert _inverse_if_conditioned(N) is None
    N = np.eye(4)
    N[0, 0] = np.nan
    with pytest.raises(np.linalg.LinAlgError):  # as the condition number itself
        np.linalg.cond(N)
    with pytest.raises(np.linalg.LinAlgError):
        _inverse_if_conditioned(N)


def test_cn0_terms_equal_the_clamped_form() -> None:
    cn0 = np.array([np.nan, np.inf, -np.inf, 10.0, 45.0, 60.0, 1e300, -1e300])
    el = np.full(cn0.size, 0.5)
    with np.errstate(over="ignore"):
        want_e = (
            0.3**2 / np.sin(0.5) ** 2 * 10.0 ** (np.maximum(0.0, 45.0 - np.nan_to_num(cn0, nan=45.0)) / 10.0)
        )
        want_c = 0.1**2 * 10.0 ** ((45.0 - np.nan_to_num(cn0, nan=45.0)) / 10.0)
        got_e = elevation_cn0_variance(0.3, el, cn0, cn0_ref_dbhz=45.0)
        got_c = cn0_variance(0.1, cn0, 45.0)
    np.testing.assert_array_equal(got_e, want_e)
    np.testing.assert_array_equal(got_c, want_c)
    assert cn0_variance(0.1, float("nan"), 45.0) == pytest.approx(0.01)
