"""Full and partial ambiguity resolution (PAR) and the conditional update of the state.

Strategies
----------
* :func:`resolve_full` — LAMBDA on all ambiguities, validated by the ratio test.
* :func:`resolve_par_ranked` — the PAR of Li et al. (2019, sec. 2.3): ambiguities are
  ranked by a statistic (the error-discriminant ``|Δv̄|`` of their phase rows, smallest
  first); the full set is tried first, then the best-ranked ``m = n−1, n−2, …`` until a
  subset validates or ``m < min_size``.
* :func:`resolve_par_success_rate` — drop the most poorly determined ambiguities (largest
  float variance ``Q_ii`` first) until the bootstrapped success rate of the remaining
  subset reaches ``p0``, then validate that subset with the ratio test.

:func:`conditional_update` then conditions the whole Gaussian state (baseline and the
unfixed ambiguities) on the fixed subset (Li et al. eqs. 16–19 in general form).

Outcomes that are not errors (no subset validates, too few ambiguities) are returned as a
:class:`FixResult` with ``status == "float"``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from types import ModuleType
from typing import Literal

import numpy as np
import numpy.typing as npt

from robustrtk.ambiguity.lambda_ import (
    SearchLimitError,
    bootstrap_success_rate,
    check_q,
    ils_search,
    kernels,
    reduce_q,
)
from robustrtk.ambiguity.validation import (
    DEFAULT_RATIO_THRESHOLD,
    ffrt_threshold,
    ratio_of,
)
from robustrtk.estimation.gaussian import condition_on

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
Method = Literal["ratio", "ffrt"]

__all__ = [
    "FixResult",
    "conditional_update",
    "fix_state",
    "resolve_full",
    "resolve_par_ranked",
    "resolve_par_success_rate",
]


@dataclass(frozen=True)
class FixResult:
    """Result of an ambiguity-resolution attempt.

    Attributes
    ----------
    fixed : ndarray, shape (n,)
        Integer values (cycles, float dtype) of the fixed ambiguities; NaN where not fixed.
    subset : ndarray of int, shape (m,)
        Indices into the float vector of the fixed ambiguities (ascending); empty for float.
    ratio : float
        ``s2 / s1`` of the subset that was accepted, or of the full set when none was.
    norms : ndarray, shape (2,)
        Best and second-best squared norms ``s1 ≤ s2`` belonging to ``ratio``.
    success_rate : float
        Bootstrapped success rate of the same subset (decorrelated conditional variances).
    validated : bool
        Whether the subset passed validation.
    status : str
        ``"fixed"`` (all ambiguities), ``"partial"`` (a proper subset) or ``"float"``.
    threshold : float
        Ratio threshold that was applied (the FFRT value when ``method="ffrt"``).
    """

    fixed: FloatArray
    subset: IntArray
    ratio: float
    norms: FloatArray
    success_rate: float
    validated: bool
    status: str
    threshold: float = DEFAULT_RATIO_THRESHOLD


@dataclass(frozen=True)
class _Attempt:
    best: FloatArray
    norms: FloatArray
    ratio: float
    success_rate: float
    threshold: float
    accepted: bool


def _check_float(a_float: npt.ArrayLike, Q: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
    a = np.asarray(a_float, dtype=np.float64).reshape(-1)
    if a.shape[0] == 0:
        raise ValueError("a_float must have at least one element")
    if not np.isfinite(a).all():
        raise ValueError("a_float contains NaN or infinite entries")
    return a, check_q(Q, a.shape[0])


def _attempt(
    a: FloatArray,
    Q: FloatArray,
    method: Method,
    ratio_threshold: float,
    pf: float,
    rng: np.random.Generator | None,
    n_samples: int,
    reduced: tuple[npt.NDArray[np.int64], FloatArray, FloatArray] | None = None,
    success_rate: float | None = None,
    kern: ModuleType | None = None,
) -> _Attempt:
    """LAMBDA on one subset + validation (not accepted when the search gives up).

    ``success_rate``: the bootstrapped success rate of ``reduced`` when already computed;
    ``kern``: the kernels to search with (:func:`~robustrtk.ambiguity.lambda_.kernels`)."""
    try:
        F, s, d = ils_search(a, Q, 2, reduced, kern=kern)
    except SearchLimitError:
        nan2 = np.full(2, np.nan)
        return _Attempt(np.round(a), nan2, float("nan"), 0.0, float(ratio_threshold), False)
    best = F[:, 0]
    # with ``reduced`` given the search hands back its d unchanged
    ps = bootstrap_success_rate(d) if success_rate is None or reduced is None else success_rate
    r = ratio_of(s)
    if method == "ratio":
        thr = float(ratio_threshold)
    elif method == "ffrt":
        thr = ffrt_threshold(Q, pf=pf, rng=rng, n_samples=n_samples)
    else:
        raise ValueError(f"unknown validation method {method!r}; expected 'ratio' or 'ffrt'")
    return _Attempt(best, s, r, ps, thr, bool(r >= thr))


#: Extra test of a ratio-validated subset: ``accept(indices, integers) -> bool``.
Accept = Callable[[IntArray, FloatArray], bool]


def _accepted(att: _Attempt, idx: IntArray, accept: Accept | None) -> _Attempt:
    """``att``, marked not accepted when ``accept`` rejects its integers."""
    if not att.accepted or accept is None or accept(idx, att.best):
        return att
    return replace(att, accepted=False)


def _result(n: int, idx: IntArray, att: _Attempt) -> FixResult:
    fixed = np.full(n, np.nan)
    if att.accepted:
        order = np.argsort(idx)
        sub = idx[order].astype(np.int64)
        fixed[sub] = att.best[order]
        status = "fixed" if sub.shape[0] == n else "partial"
    else:
        sub = np.zeros(0, dtype=np.int64)
        status = "float"
    return FixResult(
        fixed=fixed,
        subset=sub,
        ratio=att.ratio,
        norms=np.asarray(att.norms, dtype=np.float64),
        success_rate=att.success_rate,
        validated=att.accepted,
        status=status,
        threshold=att.threshold,
    )


def resolve_full(
    a_float: npt.ArrayLike,
    Q: npt.ArrayLike,
    ratio_threshold: float = DEFAULT_RATIO_THRESHOLD,
    method: Method = "ratio",
    pf: float = 1e-3,
    rng: np.random.Generator | None = None,
    n_samples: int = 2000,
    accept: Accept | None = None,
) -> FixResult:
    """Resolve all ambiguities at once (LAMBDA + validation).

    Parameters
    ----------
    a_float : array_like, shape (n,)
        Float ambiguities (cycles).
    Q : array_like, shape (n, n)
        Their covariance (cycles²), symmetric positive definite.
    ratio_threshold : float
        Threshold of the ratio test ``s2/s1 ≥ threshold`` (``method="ratio"``).
    method : {"ratio", "ffrt"}
        Fixed threshold, or the fixed-failure-rate threshold of
        :func:`robustrtk.ambiguity.validation.ffrt_threshold` (needs ``rng``).
    pf, rng, n_samples
        FFRT failure rate, random generator and Monte Carlo size.
    accept : callable, optional
        A further test of a ratio-validated candidate: ``accept(idx, values)`` with the
        subset's indices into ``a_float`` and its integers; False rejects it (e.g. the
        fixed solution's residual test).

    Returns
    -------
    FixResult
        ``status`` is ``"fixed"`` when validated, else ``"float"``.
    """
    a, q = _check_float(a_float, Q)
    idx = np.arange(a.shape[0], dtype=np.int64)
    att = _attempt(a, q, method, ratio_threshold, pf, rng, n_samples)
    return _result(a.shape[0], idx, _accepted(att, idx, accept))


def resolve_par_ranked(
    a_float: npt.ArrayLike,
    Q: npt.ArrayLike,
    rank: npt.ArrayLike,
    min_size: int = 3,
    ratio_threshold: float = DEFAULT_RATIO_THRESHOLD,
    method: Method = "ratio",
    pf: float = 1e-3,
    rng: np.random.Generator | None = None,
    n_samples: int = 2000,
    accept: Accept | None = None,
) -> FixResult:
    """Partial ambiguity resolution by a ranking statistic (Li et al. 2019, eqs. 17–18).

    Parameters
    ----------
    a_float, Q
        Float ambiguities (cycles) and their covariance (cycles²), as in :func:`resolve_full`.
    rank : array_like, shape (n,)
        Ranking statistic, smaller is better (the paper uses ``|Δv̄|`` of each
        ambiguity's phase row). NaN ranks last. Ties keep the input order.
    min_size : int
        Smallest subset tried (the paper stops when ``m < 3``).
    ratio_threshold, method, pf, rng, n_samples, accept
        Validation, as in :func:`resolve_full` (a subset that ``accept`` rejects counts as
        not fixed, and the next smaller one is tried).

    Returns
    -------
    FixResult
        The first validated subset among the full set and the best-ranked
        ``m = n−1, n−2, …, min_size`` ambiguities; ``"float"`` (with the ratio, norms and
        success rate of the full set) when none validates.
    """
    a, q = _check_float(a_float, Q)
    n = a.shape[0]
    rk = np.asarray(rank, dtype=np.float64).reshape(-1)
    if rk.shape[0] != n:
        raise ValueError(f"rank has length {rk.shape[0]}, expected {n}")
    if min_size < 1:
        raise ValueError("min_size must be >= 1")
    order = np.argsort(np.where(np.isnan(rk), np.inf, rk), kind="stable").astype(np.int64)
    first: _Attempt | None = None
    m = n
    while m == n or m >= min_size:
        idx = order[:m]
        att = _attempt(a[idx], q[np.ix_(idx, idx)], method, ratio_threshold, pf, rng, n_samples)
        att = _accepted(att, idx, accept)
        if first is None:
            first = att
        if att.accepted:
            return _result(n, idx, att)
        m -= 1
        if m < 1:
            break
    assert first is not None
    return _result(n, np.arange(n, dtype=np.int64), first)


def resolve_par_success_rate(
    a_float: npt.ArrayLike,
    Q: npt.ArrayLike,
    p0: float = 0.999,
    min_size: int = 3,
    ratio_threshold: float = DEFAULT_RATIO_THRESHOLD,
    method: Method = "ratio",
    pf: float = 1e-3,
    rng: np.random.Generator | None = None,
    n_samples: int = 2000,
    max_attempts: int = 8,
) -> FixResult:
    """Partial ambiguity resolution driven by the bootstrapped success rate.

    Ambiguities are dropped in decreasing order of their float variance ``Q_ii`` (the
    most poorly determined first; ties keep the input order). After each drop the
    remaining subset is decorrelated and its bootstrapped success rate
    ``Π (2Φ(1/(2√d_i)) − 1)`` evaluated; the first subset (starting with the full set)
    reaching ``p0`` is resolved with LAMBDA and validated. When it fails validation the
    dropping goes on (a newly risen satellite can spoil the ratio of a well-determined
    set), for at most ``max_attempts`` searches. Dropping works on the original
    ambiguities (not on decorrelated combinations), so the fixed values stay
    individual integers that :func:`conditional_update` can use directly.

    Parameters
    ----------
    a_float : array_like, shape (n,)
        Float ambiguities (cycles).
    Q : array_like, shape (n, n)
        Their covariance (cycles²).
    p0 : float
        Required bootstrapped success rate, in (0, 1].
    min_size : int
        Smallest subset considered.
    max_attempts : int
        Most subsets searched and validated.
    ratio_threshold, method, pf, rng, n_samples
        Validation, as in :func:`resolve_full`.

    Returns
    -------
    FixResult
        Validated subset, or ``"float"`` when no subset of size ≥ ``min_size`` reaches
        ``p0`` (values of the full set reported) or the chosen subset fails validation
        (values of that subset reported).
    """
    a, q = _check_float(a_float, Q)
    n = a.shape[0]
    if not 0.0 < p0 <= 1.0:
        raise ValueError(f"p0 must be in (0, 1], got {p0}")
    order = np.argsort(-np.diag(q), kind="stable").astype(np.int64)  # worst first
    m = n
    first: tuple[IntArray, _Attempt] | None = None
    attempts = 0
    d_full: FloatArray | None = None
    kern = kernels()  # one look-up for every reduction and search below
    while (m == n or m >= min_size) and attempts < max_attempts:
        idx = np.sort(order[n - m :])
        q_sub = q[idx][:, idx]  # a principal submatrix of check_q's output: symmetric, finite
        reduced = reduce_q(q_sub, checked=True, kern=kern)
        if m == n:
            d_full = reduced[2]
        ps = bootstrap_success_rate(reduced[2])
        if ps >= p0:
            att = _attempt(a[idx], q_sub, method, ratio_threshold, pf, rng, n_samples, reduced, ps, kern)
            attempts += 1
            if att.accepted:
                return _result(n, idx, att)
            if first is None:
                first = (idx, att)
        m -= 1
        if m < 1:
            break
    if first is not None:
        return _result(n, first[0], first[1])
    # no subset is precise enough: report the full set's success rate without searching
    # (a search over a weak float solution visits astronomically many points)
    dz = d_full if d_full is not None else reduce_q(q)[2]
    nan2 = np.full(2, np.nan)
    sr = bootstrap_success_rate(dz)
    full = _Attempt(np.round(a), nan2, float("nan"), sr, float(ratio_threshold), False)
    return _result(n, np.arange(n, dtype=np.int64), full)


def conditional_update(
    x: npt.ArrayLike,
    P: npt.ArrayLike,
    idx_fixed: npt.ArrayLike,
    values: npt.ArrayLike,
) -> tuple[FloatArray, FloatArray]:
    """Condition a Gaussian ``N(x, P)`` on ``x[f] = values`` exactly.

    Parameters, returns and errors as :func:`robustrtk.estimation.gaussian.condition_on`,
    of which this is a thin wrapper (also
    :meth:`robustrtk.estimation.state.GaussianState.conditional_update`): ``x_c =
    x − P[:, f] P[f, f]⁻¹ (x[f] − values)`` and ``P_c = P − P[:, f] P[f, f]⁻¹ P[f, :]``,
    Li et al. (2019) eqs. 16–19 (algorithms.md §8).
    """
    return condition_on(x, P, idx_fixed, values)


def fix_state(
    x: npt.ArrayLike, P: npt.ArrayLike, amb_idx: npt.ArrayLike, result: FixResult
) -> tuple[FloatArray, FloatArray]:
    """Apply a :class:`FixResult` to a state whose ambiguities sit at ``amb_idx``.

    Parameters
    ----------
    x : array_like, shape (k,)
        State mean.
    P : array_like, shape (k, k)
        State covariance.
    amb_idx : array_like of int, shape (n,)
        State index of each entry of the float ambiguity vector given to the resolver.
    result : FixResult
        Resolution outcome; nothing changes when it is not validated.

    Returns
    -------
    x_c, P_c : ndarray
        :func:`conditional_update` on ``amb_idx[result.subset]``.
    """
    ai = np.asarray(amb_idx, dtype=np.int64).reshape(-1)
    if ai.shape[0] != result.fixed.shape[0]:
        raise ValueError("amb_idx must have one entry per ambiguity of the FixResult")
    if not result.validated or result.subset.shape[0] == 0:
        return np.asarray(x, dtype=np.float64).copy(), np.asarray(P, dtype=np.float64).copy()
    return conditional_update(x, P, ai[result.subset], result.fixed[result.subset])
