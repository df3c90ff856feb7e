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
from robustrtk.core import CLIGHT
from robustrtk.estimation import filters
from robustrtk.estimation.filters import EKF, UKF
from robustrtk.estimation.robust import DeltaVIGG3, NoRobust
from robustrtk.estimation.state import GaussianState, StateLayout, UpdateResult
from robustrtk.measurement.dd import OMEGA_E, DDRangeModel, ranges

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
    for name, tol in (("innovation", tol_m), ("residual", tol_m), ("std_residual", tol_std)):
        np.testing.assert_allclose(getattr(a, name), getattr(b, name), rtol=1e-9, atol=tol, err_msg=name)
    # Δv̄_k = v̄_k / mean_{j≠k} |v̄_j| carries the standardized residuals' error divided by that
    # mean: when the other rows fit to a few thousandths, it amplifies what tol_std allows
    # (|ΔΔv̄_k| ≤ tol_std (1 + |Δv̄_k|) / mean_{j≠k} |v̄_j|), never less than tol_std itself
    v = np.abs(np.asarray(b.std_residual, float))
    v = np.where(np.isfinite(v), v, 0.0)  # rows without a value are not in Δv̄'s set
    others = (v.sum() - v) / max(int(np.isfinite(np.asarray(b.std_residual, float)).sum()) - 1, 1)
    dv_b = np.asarray(b.dv, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        tol_dv = tol_std * np.maximum(1.0, (1.0 + np.abs(dv_b)) / others)
    np.testing.assert_array_equal(np.isfinite(a.dv), np.isfinite(dv_b), err_msg="dv finite")
    fin = np.isfinite(dv_b)
    assert np.all(
        np.abs(np.asarray(a.dv, float)[fin] - dv_b[fin]) <= tol_dv[fin] + 1e-9 * np.abs(dv_b[fin])
    ), "dv"
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
    P[0, 0] = -1.0  # not a covariance: refused at the entry, before either path
    bad_p = st_.with_(P=P)
    with pytest.raises(ValueError, match="prior P"):
        filt.update(bad_p, model)
    # declined (the pure path decides): the very same result
    declined = [(st_, bad_z)]
    for s, mdl in declined:
        fast = filt.update(s, mdl)
        pure = _pure(filt, s, mdl, monkeypatch)
        np.testing.assert_array_equal(fast.factors, pure.factors)
        np.testing.assert_array_equal(fast.state.x, pure.state.x)
        np.testing.assert_array_equal(fast.state.P, pure.state.P)
        np.testing.assert_array_equal(fast.innovation, pure.innovation)
    assert np.all(np.isinf(filt.update(st_, bad_z).factors))


def test_alpha_is_honoured(monkeypatch: pytest.MonkeyPatch) -> None:
    st_, model = _problem(np.random.default_rng(4), 5, 4, False, True, False)
    for filt in (UKF(alpha=0.3, beta=2.0, kappa=1.0), UKF(alpha=1.0, kappa=3.0)):
        _assert_same(filt.update(st_, model), _pure(filt, st_, model, monkeypatch))


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n_tx=st.integers(2, 9), sagnac=st.booleans(), corr=st.booleans())
def test_packed_kernel_equals_the_field_by_field_kernel_bit_for_bit(
    seed: int, n_tx: int, sagnac: bool, corr: bool
) -> None:
    """The fast path's entry (the model packed, two output buffers) runs the very same
    operations as :func:`dd_update_k` with the fields one by one."""
    k = filters.kernels()
    assert k is not None
    rng = np.random.default_rng(seed)
    st_, model = _problem(rng, n_tx, int(rng.integers(0, n_tx)), sagnac, corr, bool(rng.integers(0, 2)))
    packed = model.kernel_args
    assert packed is not None
    geo, idx = packed
    assert geo.dtype == np.float64 and idx.dtype == np.int64
    n, m = st_.n, model.z.shape[0]
    for ukf in (True, False):
        xP, rows = np.full((n + 1, n), -7.0), np.full((5 + 2 * m, m), -7.0)
        work = np.empty(k.work_size(n, m, model.tx_pos_m.shape[0]))
        code = k.dd_update_packed_k(
            st_.x, st_.P, model.z, model.R, geo, idx, ukf, 0.8, 2.0, 1.0, xP, rows, work
        )
        outs = [np.full(n, -7.0), np.full((n, n), -7.0)] + [
            np.full(s, -7.0) for s in (m, (m, m), m, (m, m), m, m)
        ]
        corr_m = model.tx_corr_m if model.tx_corr_m is not None else np.zeros(0)
        ref = k.dd_update_k(
            st_.x, st_.P, model.z, model.R, 0, model.tx_pos_m, model.base_range_m, model.i_tx,
            model.i_ref, model.amb_idx, model.wavelength_m, corr_m, model.tx_corr_m is not None,
            sagnac, OMEGA_E, CLIGHT, ukf, 0.8, 2.0, 1.0, *outs,
        )  # fmt: skip
        assert code == ref
        if code != k.OK:
            continue
        got = [xP[0], xP[1:], rows[0], rows[5 : 5 + m], rows[1], rows[5 + m :], rows[2], rows[3]]
        for a, b in zip(got, outs, strict=True):
            np.testing.assert_array_equal(a, b)
        np.testing.assert_array_equal(rows[4], np.ones(m))


def test_models_the_kernel_does_not_cover_take_the_pure_path(monkeypatch: pytest.MonkeyPatch) -> None:
    st_, model = _problem(np.random.default_rng(5), 6, 3, False, False, False)
    assert model.kernel_args is not None
    perm = np.r_[3 : st_.n, 0:3]  # the ambiguities first, the position block last
    moved = st_.with_(x=st_.x[perm], P=st_.P[np.ix_(perm, perm)])
    amb = np.where(model.amb_idx >= 0, model.amb_idx - 3, -1)
    shifted = replace(model, pos_slice=slice(st_.n - 3, st_.n), amb_idx=amb)
    assert shifted.kernel_args is not None and shifted.kernel_args[1][0] == st_.n - 3
    _assert_same(UKF().update(moved, shifted), _pure(UKF(), moved, shifted, monkeypatch))
    uncovered = [
        replace(model, pos_slice=slice(0, 6, 2)),  # not consecutive
        replace(model, pos_slice=slice(0, 2)),  # not three states
        replace(model, i_tx=model.i_tx + 10),  # a transmitter out of range
        replace(model, wavelength_m=model.wavelength_m[:-1]),  # rows disagree
    ]
    for bad in uncovered:
        assert bad.kernel_args is None
    ok = uncovered[0]  # still a valid model for the pure path (positions at 0, 2, 4)
    np.testing.assert_array_equal(UKF().update(st_, ok).state.x, _pure(UKF(), st_, ok, monkeypatch).state.x)


def test_packed_kernel_declines_inconsistent_buffers() -> None:
    k = filters.kernels()
    assert k is not None
    st_, model = _problem(np.random.default_rng(6), 5, 2, False, True, False)
    geo, idx = model.kernel_args  # type: ignore[misc]
    n, m = st_.n, model.z.shape[0]
    args = (st_.x, st_.P, model.z, model.R, geo, idx, True, 1.0, 2.0, 0.0)
    xP, rows = np.empty((n + 1, n)), np.empty((5 + 2 * m, m))
    work = np.empty(k.work_size(n, m, model.tx_pos_m.shape[0]))
    assert k.dd_update_packed_k(*args, xP, rows, work) == k.OK
    assert k.dd_update_packed_k(*args, xP, rows, work[:-1]) == k.FALLBACK  # work too short
    assert k.dd_update_packed_k(*args, np.empty((n, n)), rows, work) == k.FALLBACK
    assert k.dd_update_packed_k(*args, xP, np.empty((4 + 2 * m, m)), work) == k.FALLBACK
    short = (st_.x, st_.P, model.z[:-1], model.R[:-1, :-1], geo, idx, True, 1.0, 2.0, 0.0)
    assert k.dd_update_packed_k(*short, xP, np.empty((3 + 2 * m, m - 1)), work) == k.FALLBACK
    assert k.dd_update_packed_k(*args[:4], geo[:-1], idx, *args[6:], xP, rows, work) == k.FALLBACK


def test_fast_results_are_contiguous_and_their_own() -> None:
    st_, model = _problem(np.random.default_rng(7), 6, 4, True, False, False)
    a, b = UKF().update(st_, model), UKF().update(st_, model)
    m = model.z.shape[0]
    for name, shape in (
        ("innovation", (m,)), ("innovation_cov", (m, m)), ("residual", (m,)), ("residual_cov", (m, m)),
        ("std_residual", (m,)), ("dv", (m,)), ("factors", (m,)), ("situation", (m,)),
    ):  # fmt: skip
        arr = getattr(a, name)
        assert arr.shape == shape and arr.flags.c_contiguous, name
    assert a.state.x.flags.c_contiguous and a.state.P.flags.c_contiguous
    assert a.state.P.shape == (st_.n, st_.n) and a.situation.dtype == np.int8
    a.state.x[:] = 0.0
    a.situation[:] = 3
    a.factors[:] = 9.0
    assert not np.all(b.state.x == 0.0) and np.all(b.situation == 1) and np.all(b.factors == 1.0)
    assert np.all(UKF().update(st_, model).situation == 1)
