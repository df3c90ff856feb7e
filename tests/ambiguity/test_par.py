"""Tests of full/partial ambiguity resolution and of the conditional update."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk.ambiguity.lambda_ import bootstrap_success_rate, decorrelate
from robustrtk.ambiguity.par import (
    FixResult,
    conditional_update,
    fix_state,
    resolve_full,
    resolve_par_ranked,
    resolve_par_success_rate,
)

LAMBDA_PL_M = 0.19  # pseudolite carrier wavelength used by the scenarios (m)


def pl_float_problem(
    rng: np.random.Generator,
    n_dd: int = 6,
    n_epochs: int = 5,
    sig_phase_m: float = 0.003,
    sig_code_m: float = 0.5,
    sig_prior_m: float = 0.2,
) -> np.ndarray:
    """Float-ambiguity covariance (cycles²) of an indoor pseudolite DD problem.

    ``n_dd + 1`` pseudolites on the ceiling of a 20 m room, a rover moving over
    ``n_epochs`` epochs with a known-point prior ``sig_prior_m`` on each position,
    DD phase and code with the correlation of a common reference; the ambiguities
    are constant, positions per epoch are estimated jointly (least squares).
    """
    n_pl = n_dd + 1
    pls = rng.uniform([-10.0, -10.0, 2.5], [10.0, 10.0, 3.5], (n_pl, 3))
    D = np.hstack([-np.ones((n_dd, 1)), np.eye(n_dd)])
    C = D @ D.T
    nx = 3 * n_epochs + n_dd
    rows, blocks = [], []
    for t in range(n_epochs):
        p = np.array([0.0, 0.0, 1.0]) + rng.uniform(-1.0, 1.0, 3) * [1.0, 1.0, 0.1]
        u = (p - pls) / np.linalg.norm(p - pls, axis=1)[:, None]
        G = D @ u
        for sig, phase in ((sig_phase_m, True), (sig_code_m, False)):
            A = np.zeros((n_dd, nx))
            A[:, 3 * t : 3 * t + 3] = G
            if phase:
                A[:, 3 * n_epochs :] = LAMBDA_PL_M * np.eye(n_dd)
            rows.append(A)
            blocks.append(sig**2 * C)
        A = np.zeros((3, nx))
        A[:, 3 * t : 3 * t + 3] = np.eye(3)
        rows.append(A)
        blocks.append(sig_prior_m**2 * np.eye(3))
    A_all = np.vstack(rows)
    R = scipy.linalg.block_diag(*blocks)
    P = np.linalg.inv(A_all.T @ np.linalg.solve(R, A_all))
    Q = P[3 * n_epochs :, 3 * n_epochs :]
    return 0.5 * (Q + Q.T)


def _draw(rng: np.random.Generator, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = Q.shape[0]
    truth = rng.integers(-500, 500, n).astype(float)
    return truth, truth + np.linalg.cholesky(Q) @ rng.standard_normal(n)


# --------------------------------------------------------------------------- full / ranked PAR


@pytest.mark.parametrize("seed", range(6))
def test_clean_problem_fixed_in_full(seed: int) -> None:
    rng = np.random.default_rng(seed)
    Q = pl_float_problem(rng)
    truth, a = _draw(rng, Q)
    rank = rng.uniform(0.2, 1.0, Q.shape[0])
    for res in (resolve_full(a, Q), resolve_par_ranked(a, Q, rank)):
        assert res.status == "fixed" and res.validated
        np.testing.assert_array_equal(res.fixed, truth)
        np.testing.assert_array_equal(res.subset, np.arange(Q.shape[0]))
        assert res.ratio >= 3.0 and res.ratio == pytest.approx(res.norms[1] / res.norms[0])
        assert 0.0 < res.success_rate <= 1.0


@pytest.mark.parametrize(("n_dd", "seed"), [(6, s) for s in range(8)] + [(8, 0), (8, 1), (4, 0)])
def test_par_excludes_biased_ambiguity(n_dd: int, seed: int) -> None:
    """A 0.15 m DD phase error at 0.19 m wavelength (≈0.8 cycle) on one ambiguity with
    the largest rank statistic: the full set fails the ratio test, PAR fixes the rest."""
    rng = np.random.default_rng(seed)
    Q = pl_float_problem(rng, n_dd=n_dd)
    truth, a = _draw(rng, Q)
    k = int(rng.integers(n_dd))
    a[k] += 0.15 / LAMBDA_PL_M
    rank = rng.uniform(0.2, 1.0, n_dd)
    rank[k] = 5.0

    full = resolve_full(a, Q)
    assert full.status == "float" and not full.validated
    assert np.all(np.isnan(full.fixed)) and full.subset.shape == (0,)

    res = resolve_par_ranked(a, Q, rank)
    assert res.status == "partial" and res.validated
    assert k not in res.subset
    np.testing.assert_array_equal(res.subset, np.sort(np.argsort(rank)[: res.subset.shape[0]]))
    np.testing.assert_array_equal(res.fixed[res.subset], truth[res.subset])
    assert np.isnan(res.fixed[k])
    assert res.ratio >= 3.0


def test_par_statistics_over_many_biased_problems() -> None:
    """Over 40 random rooms: whenever the full set is rejected, PAR either fixes the
    unbiased subset correctly or stays float; the biased full set is never fixed
    correctly; and PAR succeeds in most cases. (When the ratio test wrongly accepts the
    biased full set, PAR — which tries the full set first — inherits that error.)"""
    n_dd = 6
    correct = 0
    for seed in range(40):
        rng = np.random.default_rng(1000 + seed)
        Q = pl_float_problem(rng, n_dd=n_dd)
        truth, a = _draw(rng, Q)
        k = int(rng.integers(n_dd))
        a[k] += 0.15 / LAMBDA_PL_M
        rank = rng.uniform(0.2, 1.0, n_dd)
        rank[k] = 5.0
        full = resolve_full(a, Q)
        assert not (full.validated and np.array_equal(full.fixed, truth))
        res = resolve_par_ranked(a, Q, rank)
        if full.validated:
            assert res.status == "fixed"
            continue
        if res.validated:
            assert k not in res.subset
            np.testing.assert_array_equal(res.fixed[res.subset], truth[res.subset])
            correct += 1
    assert correct >= 30


def test_par_with_bad_rank_ends_float_or_never_fixes_wrong_subset_silently() -> None:
    """Ranking the faulty ambiguity first keeps it in every subset: no subset without it
    is tried, so if a subset validates it must contain k."""
    rng = np.random.default_rng(0)
    Q = pl_float_problem(rng)
    truth, a = _draw(rng, Q)
    a[1] += 0.8
    rank = np.arange(6, dtype=float)
    rank[1] = -1.0
    res = resolve_par_ranked(a, Q, rank)
    assert res.status == "float" or 1 in res.subset
    full = resolve_full(a, Q)
    if res.status == "float":
        assert res.ratio == full.ratio  # float reports the full-set statistics
        np.testing.assert_array_equal(res.norms, full.norms)


def test_par_ranked_min_size_and_input_checks() -> None:
    Q = 0.3**2 * (0.5 * np.eye(4) + 0.5)
    a = np.array([0.5, 0.45, -0.5, 0.52])  # hopeless: every subset ambiguous
    res = resolve_par_ranked(a, Q, np.arange(4.0), min_size=3)
    assert res.status == "float" and not res.validated
    with pytest.raises(ValueError):
        resolve_par_ranked(a, Q, np.arange(3.0))
    with pytest.raises(ValueError):
        resolve_par_ranked(a, np.eye(3), np.arange(4.0))


def test_nan_rank_is_last() -> None:
    rng = np.random.default_rng(4)
    Q = pl_float_problem(rng)
    truth, a = _draw(rng, Q)
    a[2] += 0.8
    rank = rng.uniform(0.2, 1.0, 6)
    rank[2] = np.nan
    res = resolve_par_ranked(a, Q, rank)
    assert res.validated and 2 not in res.subset
    np.testing.assert_array_equal(res.fixed[res.subset], truth[res.subset])


# --------------------------------------------------------------------------- success-rate PAR


def test_success_rate_par_drops_poorly_determined() -> None:
    rng = np.random.default_rng(9)
    Q = pl_float_problem(rng, n_dd=6)
    # a newly tracked transmitter: its ambiguity is hardly known (σ = 3 cycles)
    Q[4, 4] += 9.0
    truth, a = _draw(rng, Q)
    _, _, d_full, _ = decorrelate(Q, a)
    assert bootstrap_success_rate(d_full) < 0.999
    res = resolve_par_success_rate(a, Q, p0=0.999)
    assert res.status == "partial" and res.validated
    assert 4 not in res.subset and res.subset.shape[0] == 5
    assert res.success_rate >= 0.999
    np.testing.assert_array_equal(res.fixed[res.subset], truth[res.subset])


def test_success_rate_par_full_when_strong_and_float_when_weak() -> None:
    rng = np.random.default_rng(10)
    Q = pl_float_problem(rng, n_dd=5)
    truth, a = _draw(rng, Q)
    res = resolve_par_success_rate(a, Q, p0=0.99)
    assert res.status == "fixed"
    np.testing.assert_array_equal(res.fixed, truth)
    weak = resolve_par_success_rate(a, 25.0 * np.eye(5), p0=0.99)
    assert weak.status == "float" and weak.subset.shape == (0,)


# --------------------------------------------------------------------------- conditional update


def _conditional_via_precision(
    x: np.ndarray, P: np.ndarray, f: np.ndarray, v: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Gaussian conditioning through the precision matrix Λ = P⁻¹:
    x_u | x_f = v ~ N(x_u − Λ_uu⁻¹ Λ_uf (v − x_f), Λ_uu⁻¹)."""
    k = x.shape[0]
    u = np.setdiff1d(np.arange(k), f)
    Lam = np.linalg.inv(P)
    Luu = Lam[np.ix_(u, u)]
    cov_u = np.linalg.inv(Luu)
    mean_u = x[u] - cov_u @ Lam[np.ix_(u, f)] @ (v - x[f])
    xc = np.empty(k)
    xc[u] = mean_u
    xc[f] = v
    Pc = np.zeros((k, k))
    Pc[np.ix_(u, u)] = cov_u
    return xc, Pc


@settings(max_examples=60, deadline=None)
@given(
    st.integers(min_value=0, max_value=2**32 - 1),
    st.integers(min_value=2, max_value=9),
    st.data(),
)
def test_conditional_update_matches_precision_form(seed: int, k: int, data: st.DataObject) -> None:
    rng = np.random.default_rng(seed)
    m = data.draw(st.integers(min_value=1, max_value=k - 1))
    B = rng.standard_normal((k, k + 3))
    P = B @ B.T / (k + 3) + 0.05 * np.eye(k)
    x = rng.normal(0.0, 5.0, k)
    f = rng.permutation(k)[:m]
    v = np.round(x[f] + rng.normal(0.0, 0.5, m))
    xc, Pc = conditional_update(x, P, f, v)
    xr, Pr = _conditional_via_precision(x, P, f, v)
    np.testing.assert_allclose(xc, xr, atol=1e-8 * (1 + np.abs(xr).max()))
    np.testing.assert_allclose(Pc, Pr, atol=1e-8 * np.abs(P).max())
    np.testing.assert_array_equal(Pc, Pc.T)
    np.testing.assert_array_equal(xc[f], v)


def test_conditional_update_sequential_equals_joint() -> None:
    rng = np.random.default_rng(2)
    B = rng.standard_normal((7, 9))
    P = B @ B.T / 9 + 0.1 * np.eye(7)
    x = rng.normal(0.0, 3.0, 7)
    f = np.array([5, 2, 6])
    v = np.array([1.0, -2.0, 4.0])
    xj, Pj = conditional_update(x, P, f, v)
    xs, Ps = conditional_update(x, P, f[:1], v[:1])
    # the first fixed component is now exact (zero variance): condition the rest only
    keep = np.setdiff1d(np.arange(7), f[:1])
    x2, P2 = conditional_update(xs[keep], Ps[np.ix_(keep, keep)], np.searchsorted(keep, f[1:]), v[1:])
    np.testing.assert_allclose(x2, xj[keep], atol=1e-10)
    np.testing.assert_allclose(P2, Pj[np.ix_(keep, keep)], atol=1e-10)


def test_conditional_update_paper_form_baseline_and_remaining() -> None:
    """Li et al. eqs. 16–19 written blockwise (baseline a, fixed b1, remaining b2)."""
    rng = np.random.default_rng(8)
    B = rng.standard_normal((8, 10))
    P = B @ B.T / 10 + 0.05 * np.eye(8)
    x = rng.normal(0.0, 2.0, 8)
    ia, i1, i2 = np.arange(3), np.array([3, 5, 6]), np.array([4, 7])
    b1_fix = np.round(x[i1])
    Q11 = P[np.ix_(i1, i1)]
    db = x[i1] - b1_fix
    b2 = x[i2] - P[np.ix_(i2, i1)] @ np.linalg.solve(Q11, db)
    Qb2 = P[np.ix_(i2, i2)] - P[np.ix_(i2, i1)] @ np.linalg.solve(Q11, P[np.ix_(i1, i2)])
    a = x[ia] - P[np.ix_(ia, i1)] @ np.linalg.solve(Q11, db)
    Qa = P[np.ix_(ia, ia)] - P[np.ix_(ia, i1)] @ np.linalg.solve(Q11, P[np.ix_(i1, ia)])
    xc, Pc = conditional_update(x, P, i1, b1_fix)
    np.testing.assert_allclose(xc[i2], b2, atol=1e-10)
    np.testing.assert_allclose(xc[ia], a, atol=1e-10)
    np.testing.assert_allclose(Pc[np.ix_(i2, i2)], Qb2, atol=1e-10)
    np.testing.assert_allclose(Pc[np.ix_(ia, ia)], Qa, atol=1e-10)


def test_conditional_update_input_checks() -> None:
    P = np.eye(3)
    x = np.zeros(3)
    xc, Pc = conditional_update(x, P, [], [])
    np.testing.assert_array_equal(xc, x)
    np.testing.assert_array_equal(Pc, P)
    with pytest.raises(ValueError):
        conditional_update(x, P, [0, 0], [1.0, 1.0])
    with pytest.raises(ValueError):
        conditional_update(x, P, [3], [1.0])
    with pytest.raises(ValueError):
        conditional_update(x, np.eye(2), [0], [1.0])
    with pytest.raises(ValueError):
        conditional_update(x, np.diag([1.0, 0.0, 1.0]), [1], [0.0])


def test_fix_state_maps_ambiguity_indices() -> None:
    rng = np.random.default_rng(12)
    Q = pl_float_problem(rng, n_dd=5)
    truth, a = _draw(rng, Q)
    # state = [3 baseline components, 5 ambiguities] with a correlated baseline block
    k = 8
    Bx = rng.standard_normal((k, k))
    P = 1e-4 * (Bx @ Bx.T)
    P[3:, 3:] += Q
    x = np.concatenate([rng.normal(0.0, 1.0, 3), a])
    amb_idx = np.arange(3, 8)
    res = resolve_full(a, P[3:, 3:])
    assert isinstance(res, FixResult) and res.validated
    xc, Pc = fix_state(x, P, amb_idx, res)
    xr, Pr = conditional_update(x, P, amb_idx, truth)
    np.testing.assert_allclose(xc, xr)
    np.testing.assert_allclose(Pc, Pr)
    float_res = resolve_full(a + 0.5, 25.0 * np.eye(5))
    xf, Pf = fix_state(x, P, amb_idx, float_res)
    np.testing.assert_array_equal(xf, x)
    np.testing.assert_array_equal(Pf, P)


def test_accept_callback_rejects_a_ratio_validated_subset() -> None:
    """``accept`` is a further test after the ratio test: a subset it rejects counts as not
    fixed (full: float; ranked PAR: the next smaller subset is tried)."""
    from robustrtk.ambiguity.par import resolve_full, resolve_par_ranked

    a = np.array([1.02, -2.01, 3.0, 0.97])
    Q = np.diag([0.01, 0.01, 0.01, 0.01])
    assert resolve_full(a, Q).validated
    assert not resolve_full(a, Q, accept=lambda idx, v: False).validated
    seen: list[tuple[int, ...]] = []

    def no_last(idx: np.ndarray, v: np.ndarray) -> bool:
        seen.append(tuple(int(i) for i in idx))
        return 3 not in idx

    fix = resolve_par_ranked(a, Q, rank=np.array([0.1, 0.2, 0.3, 0.4]), min_size=3, accept=no_last)
    assert fix.validated and fix.subset.tolist() == [0, 1, 2]
    np.testing.assert_array_equal(fix.fixed[:3], [1.0, -2.0, 3.0])
    assert seen[0] == (0, 1, 2, 3) and set(seen[1]) == {0, 1, 2}
