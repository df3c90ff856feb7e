"""Numerical guards: a non-finite prior or measurement, or an innovation covariance that is
not positive definite, rejects the update (state unchanged, rows rejected) — no NaN out."""

from __future__ import annotations

import numpy as np
import pytest

from robustrtk.estimation.filters import EKF, UKF
from robustrtk.estimation.models import LinearMeasurement
from robustrtk.estimation.state import GaussianState


def _case(P: np.ndarray, R: np.ndarray, z: np.ndarray) -> tuple[GaussianState, LinearMeasurement]:
    H = np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
    return GaussianState(x=np.zeros(2), P=P, t_s=0.0), LinearMeasurement(z=z, H=H, R=R)


GOOD_P = np.eye(2)
GOOD_R = np.eye(3) * 0.1
GOOD_Z = np.array([0.1, -0.2, 0.0])


@pytest.mark.parametrize("flt", [EKF(), UKF()])
@pytest.mark.parametrize(
    "P, R, z",
    [
        (np.full((2, 2), np.nan), GOOD_R, GOOD_Z),
        (GOOD_P, GOOD_R, np.array([0.1, np.inf, 0.0])),
        (GOOD_P, np.diag([0.1, np.nan, 0.1]), GOOD_Z),
        (-np.eye(2), -np.eye(3), GOOD_Z),
        (np.zeros((2, 2)), np.zeros((3, 3)), GOOD_Z),
    ],
)
def test_bad_update_is_rejected_not_nan(flt: object, P: np.ndarray, R: np.ndarray, z: np.ndarray) -> None:
    state, meas = _case(P, R, z)
    res = flt.update(state, meas)  # type: ignore[attr-defined]
    assert res.state is state
    assert res.n_used == 0
    assert np.all(np.isinf(res.factors)) and np.all(res.situation == 3)


@pytest.mark.parametrize("flt", [EKF(), UKF()])
def test_good_update_still_updates(flt: object) -> None:
    state, meas = _case(GOOD_P, GOOD_R, GOOD_Z)
    res = flt.update(state, meas)  # type: ignore[attr-defined]
    assert res.n_used == 3 and np.all(np.isfinite(res.state.x)) and np.all(np.isfinite(res.state.P))
