"""The compiled EKF/UKF update of DD range models against the pure path (the oracle).

Every field of the :class:`UpdateResult` agrees to rounding on random problems (positions,
ambiguity states, correlated R, Sagnac term, rover-side delays); refusals and the cases the
kernel declines give exactly the pure path's results.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk import jit
from robustrtk.estimation import filters
from robustrtk.estimation.filters import EKF, UKF
from robustrtk.estimation.robust import DeltaVIGG3, NoRobust
from robustrtk.estimation.state import GaussianState, StateLayout, UpdateResult
from robustrtk.measurement.dd import DDRangeModel, ranges

pytest.importorskip("numba")


@pytest.fixture(autouse=True, scope="module")
def _compiled_kernels() -> Iterator[None]:
    """These tests are about the compiled path: the policy is forced on (algorithms.md §27)."""
    with jit.use("on"):
        yield


def _problem(
    rng: np.random.Generator, n_tx: int, n_amb: int, sagnac: bool, corr: bool, ecef: bool
) -> tuple[GaussianState, DDRangeModel]:
    if ecef:  # a receiver on the Earth's surface, satellites ~2e7 m away above its horizon
        up = rng.normal(size=3)
        up /= np.linalg.norm(up)
        base = 6.37e6 * up
        look = up + rng.normal(size=(n_tx, 3)) * 0.6
        look /= np.linalg.norm(look, axis=1)[:, None]
        tx = base + 2.2e7 * look
    else:
        tx = rng.normal(size=(n_tx, 3)) * 5.0
        base = rng.normal(size=3)
    rover = base + rng.normal(size=3) * 3.0
    m = n_tx - 1
    i_ref = np.zeros(m, dtype=np.int64)
    i_tx = np.arange(1, n_tx, dtype=np.int64)
    n = 3 + n_amb
    amb = np.full(m, -1, dtype=np.int64)
    amb[:n_amb] = 3 + np.arange(n_amb)
    wl = np.where(amb >= 0, 0.19, 0.0)
    rb = ranges(base, tx, sagnac)
    A = rng.normal(size=(m, m))
    R = 0.01 * (np.eye(m) + np.ones((m, m))) + 1e-4 * (A @ A.T)
    z = rng.normal(size=m) * 2.0
    B = rng.normal(size=(n, n))
    P = np.diag(rng.uniform(0.01, 4.0, n)) + 0.05 * (B @ B.T)
    x = np.concatenate([rover, rng.normal(size=n_amb) * 3.0])
    model = DDRangeModel(
        tx, rb, i_tx, i_ref, slice(0, 3), amb, wl, z, R, tuple(f"r{i}" for i in range(m)),
        sagnac=sagnac, tx_corr_m=rng.uniform(2.0, 10.0, n_tx) if corr else None,
    )  # fmt: skip
    # measurements near the model's prediction, with noise
    z = model.h(x) + rng.normal(size=m) * 0.05
    model = replace(model, z=z)
    return GaussianState(x, P, 0.0, StateLayout()), model


def _pure(
    filt: object, st_: GaussianState, model: DDRangeModel, monkeypatch: pytest.MonkeyPatch
) -> UpdateResult:
    with monkeypatch.context() as mp:
        mp.setattr(filters, "_KERNELS", [None])
        return filt.update(st_, model)  # type: ignore[attr-defined,no-any-return]


def _assert_same(a: UpdateResult, b: UpdateResult, ecef: bool = False) -> None:
    """Agreement to rounding: metres of ranges in ECEF (2e7 m) carry ~1e-8 m of it, which
    the posterior residuals (mm) and their standardized values amplify."""
    tol_m = 1e-7 if ecef else 1e-10  # m: innovations, residuals, state
    tol_std = 1e-4 if ecef else 1e-8  # dimensionless: standardized residuals, Δv̄
    tol_cov = 1e-7 if ecef else 1e-9  # relative to the largest entry: covariances
    for name, tol in (("innovation", tol_m), ("residual", tol_m), ("std_residual", tol_std), ("dv", tol_std)):
        np.testing.assert_allclose(getattr(a, name), getattr(b, name), rtol=1e-9, atol=tol, err_msg=name)
    for name in ("innovation_cov", "residual_cov"):
        vb = getattr(b, name)
        np.testing.assert_allclose(
            getattr(a, name), vb, rtol=0, atol=tol_cov * float(np.abs(vb).max()), err_msg=name
        )
    np.testing.assert_allclose(a.state.x, b.state.x, rtol=0, atol=tol_m * 10)
    np.testing.assert_allclose(a.state.P, b.state.P, rtol=0, atol=tol_cov * float(np.abs(b.state.P).max()))
    np.testing.assert_array_equal(a.factors, b.factors)
    np.testing.assert_array_equal(a.situation, b.situation)
    assert a.situation.dtype == b.situation.dtype
    assert (a.n_used, a.iterations, a.prior_scale) == (b.n_used, b.iterations, b.prior_scale)
    assert a.state.t_s == b.state.t_s and a.state.layout == b.state.layout


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n_tx=st.integers(2, 9),
    n_amb_frac=st.floats(0.0, 1.0),
    sagnac=st.booleans(),
    corr=st.booleans(),
    ecef=st.booleans(),
    ukf=st.booleans(),
)
def test_fast_update_equals_the_pure_path(
    seed: int, n_tx: int, n_amb_frac: float, sagnac: bool, corr: bool, ecef: bool, ukf: bool
) -> None:
    rng = np.random.default_rng(seed)
    n_amb = int(round(n_amb_frac * (n_tx - 1)))
    st_, model = _problem(rng, n_tx, n_amb, sagnac, corr, ecef)
    filt = UKF() if ukf else EKF()
    fast = filt.update(st_, model)
    with pytest.MonkeyPatch.context() as mp:
        pure = _pure(filt, st_, model, mp)
    _assert_same(fast, pure, ecef)


def test_the_fast_path_is_taken_and_declines_what_it_does_not_cover(monkeypatch: pytest.MonkeyPatch) -> None:
    st_, model = _problem(np.random.default_rng(1), 6, 3, False, False, False)
    k = filters.kernels()
    assert k is not None
    calls = []
    orig = k.dd_update_packed_k

    def spy(*args: object) -> int:
        calls.append(1)
        return orig(*args)  # type: ignore[no-any-return]

    monkeypatch.setattr(k, "dd_update_packed_k", spy)
    UKF().update(st_, model)
    EKF().update(st_, model, NoRobust())
    assert len(calls) == 2
    UKF().update(st_, model, DeltaVIGG3())  # a robust policy: the pure path
    UKF().update(st_, model, prior_scale=2.0)  # prior scaling: the pure path
    UKF(alpha=0.5).update(st_, model)  # other sigma-point parameters are passed on
    assert len(calls) == 3


@pytest.mark.parametrize("ukf", [True, False])
def test_refusals_are_those_of_the_pure_path(ukf: bool, monkeypatch: pytest.MonkeyPatch) -> None:
    st_, model = _problem(np.random.default_rng(2), 6, 2, False, False, False)
    filt = UKF() if ukf else EKF()
    z = model.z.copy()
    z[1] = np.nan
    bad_z = replace(model, z=z)
    P = st_.P.copy()
    P[0, 0] = -1.0  # not positive definite: the UKF's jittered Cholesky fails, the EKF goes on
    bad_p = st_.with_(P=P)
    # declined (the pure path decides): the very same result
    declined = [(st_, bad_z)] + ([(bad_p, model)] if ukf else [])
    for s, mdl in declined:
        fast = filt.update(s, mdl)
        pure = _pure(filt, s, mdl, monkeypatch)
        np.testing.assert_array_equal(fast.factors, pure.factors)
        np.testing.assert_array_equal(fast.state.x, pure.state.x)
        np.testing.assert_array_equal(fast.state.P, pure.state.P)
        np.testing.assert_array_equal(fast.innovation, pure.innovation)
    assert np.all(np.isinf(filt.update(st_, bad_z).factors))
    if not ukf:  # the EKF never factorises P̄: an indefinite prior is updated, by both paths
        _assert_same(filt.update(bad_p, model), _pure(filt, bad_p, model, monkeypatch))


def test_alpha_is_honoured(monkeypatch: pytest.MonkeyPatch) -> None:
    st_, model = _problem(np.random.default_rng(4), 5, 4, False, True, False)
    for filt in (UKF(alpha=0.3, beta=2.0, kappa=1.0), UKF(alpha=1.0, kappa=3.0)):
        _assert_same(filt.update(st_, model), _pure(filt, st_, model, monkeypatch))
