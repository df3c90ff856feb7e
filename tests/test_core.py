"""Numerical helpers of ``robustrtk.core``."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk.core import Solution, identity, median_of, nan_to, replaced, row_norms, vector_norm
from robustrtk.geometry.frames import ecef2enu_rotation
from robustrtk.geometry.los import azimuth_elevation_rot, elevation_rot


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


_coords = st.floats(allow_nan=False, allow_infinity=False, min_value=-3e7, max_value=3e7)


@settings(max_examples=200, deadline=None)
@given(rows=st.lists(st.tuples(_coords, _coords, _coords), min_size=1, max_size=40))
def test_norms_are_numpys_bit_for_bit(rows: list[tuple[float, float, float]]) -> None:
    a = np.array(rows, float)
    assert row_norms(a).tobytes() == np.linalg.norm(a, axis=1).tobytes()
    assert row_norms(a[None]).tobytes() == np.linalg.norm(a[None], axis=-1).tobytes()
    v = a.ravel()
    assert np.float64(vector_norm(v)).tobytes() == np.float64(np.linalg.norm(v)).tobytes()


@settings(max_examples=100, deadline=None)
@given(
    sats=st.lists(st.tuples(_coords, _coords, _coords), min_size=1, max_size=30),
    lat=st.floats(-1.5, 1.5),
    lon=st.floats(-3.1, 3.1),
)
def test_elevations_alone_are_those_with_the_azimuths(
    sats: list[tuple[float, ...]], lat: float, lon: float
) -> None:
    rx = np.array([-3.96e6, 3.39e6, 3.67e6])
    rot = ecef2enu_rotation(lat, lon)
    sat = np.array(sats, float)
    sat[0] = rx  # a transmitter at the receiver: 0/0, NaN in both
    with np.errstate(invalid="ignore"):
        el = elevation_rot(sat, rx, rot)
        _, el_ref = azimuth_elevation_rot(sat, rx, rot)
    assert el.tobytes() == el_ref.tobytes()


def test_replaced_is_dataclasses_replace() -> None:
    sol = Solution(12.0, np.array([1.0, 2.0, 3.0]), np.eye(3), "float", n_used=7, ratio=2.5)
    for changes in ({}, {"n_sat": 9}, {"cov_m2": np.zeros((3, 3)), "status": "fixed"}):
        got, ref = replaced(sol, **changes), dataclasses.replace(sol, **changes)
        assert type(got) is Solution and got is not sol
        assert list(vars(got).items()).__repr__() == list(vars(ref).items()).__repr__()
    assert sol.n_sat == 0  # the original is untouched
    with pytest.raises(TypeError):
        replaced(sol, not_a_field=1)

    @dataclasses.dataclass(frozen=True)
    class Checked:
        a: float

        def __post_init__(self) -> None:
            if self.a < 0:
                raise ValueError("negative")

    # a class whose __init__ does more than store its fields goes through dataclasses.replace
    with pytest.raises(ValueError):
        replaced(Checked(1.0), a=-1.0)


@settings(max_examples=200, deadline=None)
@given(
    values=st.lists(st.floats(allow_nan=True, allow_infinity=True, width=64), min_size=0, max_size=30),
    fill=st.floats(allow_nan=False, allow_infinity=False),
)
def test_nan_to_is_numpys_nan_to_num_bit_for_bit(values: list[float], fill: float) -> None:
    a = np.array(values, float)
    out = nan_to(a, fill)
    assert out.tobytes() == np.nan_to_num(a, nan=fill).tobytes()
    assert out is not a


def test_identity_is_a_read_only_eye() -> None:
    for n in (0, 1, 5, 40):
        eye = identity(n)
        assert eye.tobytes() == np.eye(n).tobytes() and eye.shape == (n, n)
        assert identity(n) is eye and not eye.flags.writeable
        with pytest.raises(ValueError):
            eye[...] = 2.0
