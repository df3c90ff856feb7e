"""The post-fit loop's row test in floats gives the numbers of its array expression."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk.estimation.robust import _nan_to_zero, standardize, worst_kept_row

_vals = st.floats(allow_nan=True, allow_infinity=True, width=64)
_pos = st.one_of(st.floats(1e-12, 1e6), st.just(0.0), st.floats(-1.0, 0.0), st.just(np.inf), st.just(np.nan))


@settings(max_examples=3000, deadline=None)
@given(st.data(), st.integers(1, 30))
def test_worst_kept_row_is_the_array_expression(data: st.DataObject, m: int) -> None:
    v = np.array(data.draw(st.lists(_vals, min_size=m, max_size=m)))
    c = np.array(data.draw(st.lists(_pos, min_size=m, max_size=m)))
    r = np.array(data.draw(st.lists(st.floats(1e-12, 1e6), min_size=m, max_size=m)))
    keep = np.array(data.draw(st.lists(st.booleans(), min_size=m, max_size=m)))
    Cvv, R = np.diag(c), np.diag(r)
    Cvv[0, -1] = Cvv[-1, 0] = 0.5 if m > 1 else Cvv[0, 0]  # off-diagonal terms play no part
    u = standardize(v, Cvv, R)
    u = np.where(keep, np.abs(_nan_to_zero(u)), 0.0)
    i_ref = int(np.argmax(u))
    i, u_i = worst_kept_row(v, Cvv, (1e-4 * R.diagonal()).tolist(), keep)
    assert i == i_ref
    assert np.float64(u_i).tobytes() == np.float64(u[i_ref]).tobytes()


def test_worst_kept_row_of_no_rows_raises_as_argmax() -> None:
    with pytest.raises(ValueError):
        worst_kept_row(np.zeros(0), np.zeros((0, 0)), [], np.zeros(0, bool))
