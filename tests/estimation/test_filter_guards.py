"""Numerical guards: a non-finite prior or measurement, or an innovation covariance that is
not positive definite, rejects the update (state unchanged, rows rejected) — no NaN out."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

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


# ----------------------------------------------------------------- invalid inputs refused
BAD_R = {
    "negative variance": np.diag([0.1, -0.1, 0.1]),
    "asymmetric": np.array([[0.1, 0.05, 0.0], [0.0, 0.1, 0.0], [0.0, 0.0, 0.1]]),
    "indefinite": np.array([[0.1, 0.2, 0.0], [0.2, 0.1, 0.0], [0.0, 0.0, 0.1]]),
}
BAD_P = {
    "negative variance": np.diag([1.0, -1.0]),
    "asymmetric": np.array([[1.0, 0.5], [0.0, 1.0]]),
    "indefinite": np.array([[1.0, 2.0], [2.0, 1.0]]),
}


@pytest.mark.parametrize("flt", [EKF(), UKF()])
@pytest.mark.parametrize("what", sorted(BAD_R))
def test_invalid_R_is_a_value_error(flt: object, what: str) -> None:
    state, meas = _case(GOOD_P, BAD_R[what], GOOD_Z)
    with pytest.raises(ValueError, match=r"^R: "):
        flt.update(state, meas)  # type: ignore[attr-defined]


@pytest.mark.parametrize("flt", [EKF(), UKF()])
@pytest.mark.parametrize("what", sorted(BAD_P))
def test_invalid_prior_P_is_a_value_error(flt: object, what: str) -> None:
    state, meas = _case(BAD_P[what], GOOD_R, GOOD_Z)
    with pytest.raises(ValueError, match=r"^prior P: "):
        flt.update(state, meas)  # type: ignore[attr-defined]


@pytest.mark.parametrize("flt", [EKF(), UKF()])
def test_semi_definite_prior_is_accepted(flt: object) -> None:
    """A singular but PSD prior (a perfectly known component) is a valid covariance."""
    state, meas = _case(np.diag([1.0, 0.0]), GOOD_R, GOOD_Z)
    res = flt.update(state, meas)  # type: ignore[attr-defined]
    assert res.n_used == 3 and np.all(np.isfinite(res.state.P))


@pytest.mark.parametrize("flt", [EKF(), UKF()])
@pytest.mark.parametrize("t_s", [float("nan"), -1.0, float("inf")])
def test_predict_refuses_nan_and_negative_steps(flt: object, t_s: float) -> None:
    from robustrtk.estimation.models import RandomWalkModel
    from robustrtk.estimation.state import StateLayout

    state = GaussianState(x=np.zeros(3), P=np.eye(3), t_s=0.0, layout=StateLayout())
    with pytest.raises(ValueError, match="time step"):
        flt.predict(state, RandomWalkModel(), t_s)  # type: ignore[attr-defined]
    assert np.all(np.isfinite(flt.predict(state, RandomWalkModel(), 0.0).P))  # type: ignore[attr-defined]


@settings(max_examples=300, deadline=None, derandomize=True)
@given(
    p=st.lists(st.floats(-3.0, 3.0), min_size=4, max_size=4),
    r=st.lists(st.floats(-3.0, 3.0), min_size=9, max_size=9),
    use_ukf=st.booleans(),
)
def test_accepted_inputs_give_a_psd_posterior(p: list[float], r: list[float], use_ukf: bool) -> None:
    """The grid of the issue: random (often invalid) P and R; whatever the filter accepts
    gives a symmetric positive semi-definite posterior."""
    P = np.array(p).reshape(2, 2)
    R = np.array(r).reshape(3, 3)
    if p[1] > 0:  # symmetric half of the time, so that PSD and indefinite matrices both occur
        P = 0.5 * (P + P.T)
    if r[1] > 0:
        R = 0.5 * (R + R.T)
    state, meas = _case(P, R, GOOD_Z)
    flt = UKF() if use_ukf else EKF()
    try:
        res = flt.update(state, meas)
    except ValueError:
        return
    Pp = res.state.P
    assert np.allclose(Pp, Pp.T, atol=1e-9 * max(1.0, float(np.max(np.abs(Pp)))))
    assert float(np.min(np.linalg.eigvalsh(0.5 * (Pp + Pp.T)))) >= -1e-8 * max(1.0, float(np.max(np.abs(Pp))))
