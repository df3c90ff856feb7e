"""Numerical helpers of ``robustrtk.core``."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk.core import median_of


@settings(max_examples=200, deadline=None)
@given(
    values=st.lists(
        st.floats(allow_nan=False, allow_infinity=False, min_value=-1e12, max_value=1e12),
        min_size=1,
        max_size=60,
    )
)
def test_median_of_is_numpys_median_bit_for_bit(values: list[float]) -> None:
    a = np.array(values)
    assert np.float64(median_of(a)).tobytes() == np.float64(np.median(a)).tobytes()


def test_median_of_nan_and_empty() -> None:
    assert np.isnan(median_of(np.array([1.0, np.nan, 2.0])))
    assert np.isnan(median_of(np.zeros(0)))
    assert median_of(np.array([3.0, 1.0, 2.0, 10.0])) == 2.5
    assert median_of(np.array([[5.0, 1.0, 3.0]])) == 3.0  # any shape: its values
    # the sign of a zero median as numpy gives it (+0.0)
    for v in ([-0.0], [-0.0, -0.0], [-0.0, 1.0, -1.0], [-0.0, 0.0]):
        assert np.float64(median_of(np.array(v))).tobytes() == np.float64(np.median(v)).tobytes()
