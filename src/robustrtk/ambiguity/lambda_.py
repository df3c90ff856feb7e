"""LAMBDA integer least squares: LᵀDL factorisation, decorrelation and MLAMBDA search.

The integer least-squares (ILS) problem solved here is

    ǎ = argmin_{a ∈ Zⁿ} (â − a)ᵀ Q⁻¹ (â − a)

for a float ambiguity vector ``â`` (cycles) with covariance ``Q`` (cycles²).

Steps (Teunissen's LAMBDA with the MLAMBDA search of Chang, Yang & Zhou 2005):

1. :func:`ltdl` factorises ``Q = Lᵀ diag(d) L`` with ``L`` unit lower triangular.
2. :func:`decorrelate` applies integer Gauss transformations and symmetric
   permutations (the "reduction") giving a unimodular integer ``Z`` with
   ``Qz = Zᵀ Q Z = Lᵀ diag(d) L`` (the new factors) and ``ẑ = Zᵀ â``.
3. :func:`search` enumerates integer vectors inside a shrinking ellipsoid,
   depth first from the last component (conditional variance ``d[n-1]``) to the
   first, returning the best ``m`` candidates and their squared norms.
4. :func:`lambda_search` runs the pipeline and back-transforms the candidates
   with ``a = Z⁻ᵀ z``.

Conventions: all vectors are in cycles, covariances in cycles². Candidates are
returned as float arrays holding integer values.

Three implementations of the same arithmetic: compiled kernels in C
(:mod:`robustrtk.ambiguity.lambda_ckernels`, an optional library built at install time),
compiled kernels in numba (:mod:`robustrtk.ambiguity.lambda_kernels`, imported on first use so
the command line's start-up does not pay for numba) and the pure-Python references
``ltdl_py``, ``reduce_ops_py``, ``search_py``, ``ils_search_py`` and ``lambda_search_py``
(plain Python floats in the inner loops), kept as the kernels' test oracles. The public entry
points take the C kernels when they are built (no fixed cost), else the numba kernels when
:mod:`robustrtk.jit` says they pay (a long run, or ``ROBUSTRTK_JIT=on``) and numba is
installed; the pure path charges its work to that policy (:func:`kernels`; algorithms.md
§22, §27).
"""

from __future__ import annotations

import math
import os
from types import ModuleType

import numpy as np
import numpy.typing as npt

from robustrtk import jit
from robustrtk.errors import InputError

FloatArray = npt.NDArray[np.float64]

__all__ = [
    "BACKENDS",
    "ReduceOp",
    "backend",
    "bootstrap_success_rate",
    "check_q",
    "decorrelate",
    "fixed_kernels",
    "ils_search",
    "ils_search_py",
    "kernels",
    "lambda_search",
    "lambda_search_py",
    "ltdl",
    "ltdl_py",
    "reduce_ops",
    "reduce_ops_py",
    "reduce_q",
    "search",
    "search_py",
]

_KERNELS: list[ModuleType | None] = []  # the numba module once imported (None: numba absent)
_CKERNELS: list[ModuleType | None] = []  # the C module once imported (None: not built)

#: Values of ``ROBUSTRTK_LAMBDA_BACKEND``: ``auto`` (C when built, else numba under the
#: policy), ``c``, ``numba`` (numba under the policy, never C) or ``pure``.
BACKENDS = ("auto", "c", "numba", "pure")


def backend() -> str:
    """The LAMBDA backend asked for by ``ROBUSTRTK_LAMBDA_BACKEND`` (default ``auto``).

    Raises
    ------
    InputError
        The variable holds something other than auto, c, numba or pure.
    """
    raw = os.environ.get("ROBUSTRTK_LAMBDA_BACKEND", "").strip().lower() or "auto"
    if raw not in BACKENDS:
        raise InputError(
            f"environment variable ROBUSTRTK_LAMBDA_BACKEND={raw!r}: expected auto, c, numba or pure"
        )
    return raw


_BACKEND_KEPT: list[tuple[int, str]] = []  # (jit.reads() when read, backend())


def _kept_backend() -> str:
    """:func:`backend`, read again only when :mod:`robustrtk.jit` has read the environment
    since (:func:`robustrtk.jit.refresh`: at the start of every run, by :func:`robustrtk.jit.mode`):
    a look-up then costs a comparison, not three environment reads."""
    n = jit.reads()
    if _BACKEND_KEPT and _BACKEND_KEPT[0][0] == n:
        return _BACKEND_KEPT[0][1]
    choice = backend()
    _BACKEND_KEPT[:] = [(n, choice)]
    return choice


def _c_kernels() -> ModuleType | None:
    """The C kernels module (:mod:`robustrtk.ambiguity.lambda_ckernels`), None when not built."""
    if not _CKERNELS:
        mod: ModuleType | None = None
        try:
            from robustrtk.ambiguity import lambda_ckernels as mod
        except ImportError:  # the optional library was not built: numba or pure serve
            mod = None
        _CKERNELS.append(mod)
    return _CKERNELS[0]


def kernels() -> ModuleType | None:
    """The compiled kernels module to use now, else None (the pure references).

    * ``jit.current() == "off"`` (``ROBUSTRTK_JIT=off``, ``ROBUSTRTK_NO_JIT=1``): None.
    * The C kernels (:mod:`robustrtk.ambiguity.lambda_ckernels`) when they were built: they
      have no fixed cost (about a millisecond and a megabyte to load), so they serve from the
      first call, outside the run-length policy, and nothing is charged to it.
    * Else the numba kernels when :mod:`robustrtk.jit` says they pay (pure first, compiled
      once they pay for themselves; ``ROBUSTRTK_JIT=on`` at once), imported on the first call
      that wants them; without numba the pure references serve.

    ``ROBUSTRTK_LAMBDA_BACKEND=c|numba|pure`` forces one backend (``numba``: the numba
    kernels under the policy, never the C ones); ``c`` when the library is not built is an
    error. algorithms.md §22, §27. The variables are read when :mod:`robustrtk.jit` reads
    its own (:func:`robustrtk.jit.refresh`: at the start of a run, by
    :func:`robustrtk.jit.mode`, or on the first look-up); a change takes effect then, not in
    the middle of a run.

    Raises
    ------
    InputError
        ``ROBUSTRTK_LAMBDA_BACKEND`` is not auto, c, numba or pure, or is ``c`` and the C
        library is not built.
    """
    if jit.current() == "off":
        return None
    choice = _kept_backend()
    if choice == "pure":
        return None
    if choice != "numba":
        ck = _c_kernels()
        if ck is not None:
            return ck
        if choice == "c":
            raise InputError(
                "environment variable ROBUSTRTK_LAMBDA_BACKEND=c but the C LAMBDA kernels are not built "
                "(python setup.py build_ext --inplace)"
            )
    if not jit.compiled():
        return None
    if not _KERNELS:
        mod: ModuleType | None = None
        try:
            from robustrtk.ambiguity import lambda_kernels as mod
        except ImportError:  # numba absent: the pure references serve
            mod = None
        _KERNELS.append(mod)
    return _KERNELS[0]


def fixed_kernels() -> ModuleType | None:
    """The kernels :func:`kernels` gives now when that choice cannot change before the next
    look-up (the C kernels: no run-length policy, nothing charged), else None.

    A caller making many calls in a row (PAR: a reduction and a search per subset) may
    look the backend up once with this and pass it on as ``kern``; None means each call
    looks it up itself (the numba policy may switch between two calls of the pure path).
    """
    k = kernels()
    return k if k is not None and k is _c_kernels() else None


def _charge_reduction(n: int) -> None:
    """Charge one pure reduction of ``n`` ambiguities to the kernel policy."""
    jit.charge(jit.REDUCE_US_N2 * n * n)


#: Tolerance that prevents endless swapping in the reduction (RTKLIB/MLAMBDA use 1e-6).
_SWAP_TOL = 1e-6


def check_q(Q: npt.ArrayLike, n: int | None = None) -> FloatArray:
    """Validate an ambiguity covariance and return it symmetrised.

    Parameters
    ----------
    Q : array_like, shape (n, n)
        Covariance of the float ambiguities (cycles²).
    n : int, optional
        Expected size (length of the float vector).

    Returns
    -------
    ndarray, shape (n, n)
        ``(Q + Qᵀ)/2`` as float64.

    Raises
    ------
    ValueError
        Not square, wrong size, empty, non-finite, or asymmetric beyond
        ``1e-9 · max|Q|``.
    """
    q = np.asarray(Q, dtype=np.float64)
    if q.ndim != 2 or q.shape[0] != q.shape[1]:
        raise ValueError(f"Q must be a square (n, n) matrix, got shape {q.shape}")
    if n is not None and q.shape[0] != n:
        raise ValueError(f"Q has shape {q.shape} but the float vector has length {n}")
    if q.shape[0] == 0:
        raise ValueError("Q must have at least one row (n >= 1)")
    scale = float(np.max(np.abs(q)))
    if not math.isfinite(scale):
        raise ValueError("Q contains NaN or infinite entries")
    if float(np.max(np.abs(q - q.T))) > 1e-9 * scale:
        raise ValueError("Q must be symmetric")
    return 0.5 * (q + q.T)


def ltdl(Q: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Factorise a symmetric positive-definite matrix as ``Q = Lᵀ diag(d) L``.

    Parameters
    ----------
    Q : array_like, shape (n, n)
        Symmetric positive-definite covariance (cycles²).

    Returns
    -------
    L : ndarray, shape (n, n)
        Unit lower-triangular factor.
    d : ndarray, shape (n,)
        Positive diagonal; ``d[i]`` is the variance of ambiguity ``i`` conditioned on
        ambiguities ``i+1 … n-1`` (cycles²).

    Raises
    ------
    ValueError
        If ``Q`` is not square, not symmetric, not finite or not positive definite.

    Notes
    -----
    This is the usual Cholesky factorisation applied in reverse order (the LAMBDA
    "LᵀDL" convention, eliminating from the last ambiguity to the first): with ``J``
    the exchange matrix, ``J Q J = C Cᵀ`` gives ``L = J (C diag(C)⁻¹)ᵀ J`` and
    ``d = J diag(C)²``. ``d[i]`` is the variance of ambiguity ``i`` conditioned on
    ``i+1 … n-1``. The compiled kernel eliminates row by row from the last
    (:func:`robustrtk.ambiguity.lambda_kernels.ltdl_k`); the same factors to rounding.
    """
    return _ltdl(check_q(Q))


def ltdl_py(Q: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Pure reference of :func:`ltdl` (LAPACK Cholesky of the flipped matrix)."""
    return _ltdl_py(check_q(Q))


def _ltdl(q: FloatArray) -> tuple[FloatArray, FloatArray]:
    """:func:`ltdl` without the input checks (``q`` symmetric, finite)."""
    k = kernels()
    if k is None:
        return _ltdl_py(q)
    L, d, code = k.ltdl_k(np.ascontiguousarray(q))
    if code != k.OK:
        raise ValueError("Q is not positive definite")
    return L, d


def _ltdl_py(q: FloatArray) -> tuple[FloatArray, FloatArray]:
    """:func:`ltdl_py` without the input checks."""
    # Flip rows and columns (J Q J, J the exchange matrix): J Q J = C Cᵀ (Cholesky, C lower)
    # gives Q = (J C J)(J Cᵀ J) with J C J upper, hence L = J (C/diag C)ᵀ J, d = J diag(C)².
    try:
        C = np.linalg.cholesky(q[::-1, ::-1])
    except np.linalg.LinAlgError as err:
        raise ValueError("Q is not positive definite") from err
    c = np.diag(C).copy()
    if not np.all(c > 0.0) or not np.all(np.isfinite(C)):
        raise ValueError("Q is not positive definite")
    L = (C / c[None, :]).T[::-1, ::-1].copy()
    d = (c * c)[::-1].copy()
    return L, d


#: One step of the reduction: ``(j, i, mu)`` is the integer Gauss transformation
#: ``Z <- Z (I - mu e_i e_jᵀ)``; ``(j, -1, 0)`` is the permutation of ``j`` and ``j+1``.
ReduceOp = tuple[int, int, int]


def reduce_ops(
    L: FloatArray, d: FloatArray, full: bool = True
) -> tuple[list[ReduceOp], FloatArray, FloatArray]:
    """Integer Gauss transformations + permutations on the factors (works on copies).

    The compiled kernel (:func:`robustrtk.ambiguity.lambda_kernels.reduce_k`) when
    available, else :func:`reduce_ops_py`; same parameters, results and operation order.
    """
    k = kernels()
    if k is None:
        _charge_reduction(d.shape[0])
        return reduce_ops_py(L, d, full)
    ops, Lr, dr = k.reduce_k(np.ascontiguousarray(L, dtype=np.float64), np.asarray(d, dtype=np.float64))
    return [(j, i, mu) for j, i, mu in ops.tolist()], Lr, dr


def reduce_q(
    Q: npt.ArrayLike, *, checked: bool = False, kern: ModuleType | None = None
) -> tuple[npt.NDArray[np.int64], FloatArray, FloatArray]:
    """:func:`ltdl` then :func:`reduce_ops` of a covariance, the operations as an array.

    Parameters
    ----------
    Q : array_like, shape (n, n)
        Symmetric positive-definite covariance (cycles²).
    checked : bool
        ``Q`` is already exactly symmetric and finite (an output of :func:`check_q` or a
        principal submatrix of one), so :func:`check_q`, which would return the same
        numbers, is skipped.
    kern : module, optional
        Compiled kernels to use instead of looking them up (:func:`fixed_kernels` of the
        caller); None looks them up with :func:`kernels`.

    Returns
    -------
    ops : ndarray of int64, shape (k, 3)
        The rows ``(j, i, mu)`` of :func:`reduce_ops` (``i = -1``: a permutation), in order;
        accepted as ``reduced`` by :func:`ils_search`.
    L, d : ndarray, shapes (n, n), (n,)
        Factors of ``Zᵀ Q Z = Lᵀ diag(d) L``.

    Raises
    ------
    ValueError
        As :func:`ltdl`.

    Notes
    -----
    The same numbers as ``reduce_ops(*ltdl(Q))``, without building the list of tuples
    (PAR reduces several subsets per epoch and needs only ``d`` and the search). The
    backend is looked up once for both steps (nothing between them can change it).
    """
    q = np.asarray(Q, dtype=np.float64) if checked else check_q(Q)
    k = kernels() if kern is None else kern
    if k is None:
        L0, d0 = _ltdl_py(q)
        _charge_reduction(d0.shape[0])
        ops_l, L, d = reduce_ops_py(L0, d0)
        return np.array(ops_l, dtype=np.int64).reshape(-1, 3), L, d
    L0, d0, code = k.ltdl_k(np.ascontiguousarray(q))
    if code != k.OK:
        raise ValueError("Q is not positive definite")
    ops, L, d = k.reduce_k(L0, d0)
    return ops, L, d


def reduce_ops_py(
    L: FloatArray, d: FloatArray, full: bool = True
) -> tuple[list[ReduceOp], FloatArray, FloatArray]:
    """Integer Gauss transformations + permutations on the factors (works on copies).

    Parameters
    ----------
    L : ndarray, shape (n, n)
        Unit lower-triangular factor of ``Q = Lᵀ diag(d) L`` (from :func:`ltdl`).
    d : ndarray, shape (n,)
        Its diagonal (cycles²).
    full : bool
        Kept for the interface; the reduction is always complete.

    Returns
    -------
    ops : list of ReduceOp
        Elementary operations whose product is the unimodular ``Z``.
    L, d : ndarray, shapes (n, n), (n,)
        New factors with ``Zᵀ Q Z = Lᵀ diag(d) L``.

    Notes
    -----

    De Jonge & Tiberius' order: column ``j`` is size-reduced as a whole
    (``|L_ij| ≤ 1/2`` for ``i > j``) whenever it may have changed since its last
    reduction (``j ≤ k``, ``k`` the last swap), then the swap condition at ``j`` is
    tested; after a swap the sweep restarts at ``n−2``. Reducing only the sub-diagonal
    entry (which is all the test reads) is mathematically equivalent but numerically
    unstable: the other entries of ``L`` and ``Z`` then grow without bound (past 2⁵³
    on ill-conditioned 26-ambiguity sets of real receivers), and ``Z`` stops being
    exactly integer and unimodular. ``full`` is kept for the interface; the result is
    always fully reduced.
    """
    n = d.shape[0]
    Lc = [list(map(float, col)) for col in L.T]  # Lc[j][r] = L[r, j] (column storage)
    dl = [float(v) for v in d]
    ops: list[ReduceOp] = []

    def gauss(i: int, j: int) -> None:
        # L[i:, j] -= mu L[i:, i]
        mu = round(Lc[j][i])
        if mu != 0:
            cj = Lc[j]
            ci = Lc[i]
            cj[i:] = [x - mu * y for x, y in zip(cj[i:], ci[i:], strict=True)]
            ops.append((j, i, mu))

    j = n - 2
    k = n - 2
    while j >= 0:
        if j <= k:
            cj = Lc[j]
            for i in range(j + 1, n):
                v = cj[i]
                if v > 0.5 or v < -0.5:  # round(v) != 0 (round half to even: ±0.5 → 0)
                    gauss(i, j)
        colj = Lc[j]
        colj1 = Lc[j + 1]
        lj1 = colj[j + 1]
        delta = dl[j] + lj1 * lj1 * dl[j + 1]
        if delta + _SWAP_TOL < dl[j + 1]:
            # permute j and j+1: new d_j = d_j d_{j+1} / delta, new d_{j+1} = delta
            eta = dl[j] / delta
            lam = dl[j + 1] * lj1 / delta
            dl[j] = eta * dl[j + 1]
            dl[j + 1] = delta
            for c in range(j):
                col = Lc[c]
                a0 = col[j]
                a1 = col[j + 1]
                col[j] = -lj1 * a0 + a1
                col[j + 1] = eta * a0 + lam * a1
            colj[j + 1] = lam
            tail = colj[j + 2 :]
            colj[j + 2 :] = colj1[j + 2 :]
            colj1[j + 2 :] = tail
            ops.append((j, -1, 0))
            k = j
            j = n - 2
        else:
            j -= 1
    del full  # always fully reduced (see the notes)
    return ops, np.array(Lc).T.reshape(n, n).copy(), np.array(dl)


def _ops_to_z(n: int, ops: list[ReduceOp]) -> tuple[FloatArray, FloatArray]:
    """Build ``Z`` and ``Z⁻¹`` (exact integers) from the reduction operations."""
    Z = np.eye(n)
    Zinv = np.eye(n)
    for j, i, mu in ops:
        if i < 0:
            Z[:, [j, j + 1]] = Z[:, [j + 1, j]]
            Zinv[[j, j + 1], :] = Zinv[[j + 1, j], :]
        else:
            Z[:, j] -= mu * Z[:, i]
            Zinv[i, :] += mu * Zinv[j, :]
    return Z, Zinv


def _apply_zt(ops: list[ReduceOp], v: FloatArray) -> FloatArray:
    """``Zᵀ v`` for ``v`` of shape (n,), from the operation list."""
    x = np.asarray(v, dtype=np.float64).tolist()
    for j, i, mu in ops:
        if i < 0:
            x[j], x[j + 1] = x[j + 1], x[j]
        else:
            x[j] -= mu * x[i]
    return np.array(x)


def _apply_zinvt(ops: list[ReduceOp], v: FloatArray) -> FloatArray:
    """``Z⁻ᵀ v`` for ``v`` of shape (n, k), from the operation list (reverse order)."""
    cols = np.asarray(v, dtype=np.float64).T.tolist()
    for j, i, mu in reversed(ops):
        if i < 0:
            for x in cols:
                x[j], x[j + 1] = x[j + 1], x[j]
        else:
            for x in cols:
                x[j] += mu * x[i]
    return np.array(cols).T.copy()


def _reduce(
    L: FloatArray, d: FloatArray, full: bool = True
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Reduction returning ``(Z, Zinv, L, d)``; see :func:`reduce_ops`."""
    ops, Lr, dr = reduce_ops(L, d, full)
    Z, Zinv = _ops_to_z(d.shape[0], ops)
    return Z, Zinv, Lr, dr


def ils_search(
    a: FloatArray,
    Q: FloatArray,
    m: int,
    reduced: tuple[list[ReduceOp] | npt.NDArray[np.int64], FloatArray, FloatArray] | None = None,
    *,
    kern: ModuleType | None = None,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Integer least squares on already-checked inputs (no validation).

    Parameters
    ----------
    a : ndarray, shape (n,)
        Finite float ambiguities (cycles).
    Q : ndarray, shape (n, n)
        Their covariance (cycles²), symmetric positive definite (see :func:`check_q`).
    m : int
        Number of candidates.
    reduced : tuple, optional
        The output of :func:`reduce_ops` for ``ltdl(Q)`` (or of :func:`reduce_q` for ``Q``)
        when already computed.
    kern : module, optional
        As in :func:`reduce_q`.

    Returns
    -------
    F : ndarray, shape (n, m)
        Best ``m`` integer candidates ``a = Z⁻ᵀ z + round(â)`` (float dtype), best first.
    s : ndarray, shape (m,)
        Their squared norms ``(â − a)ᵀ Q⁻¹ (â − a)``, ascending.
    d : ndarray, shape (n,)
        Decorrelated conditional variances (for the bootstrapped success rate).

    Raises
    ------
    SearchLimitError
        When the search gives up (see :func:`search`).
    """
    k = kernels() if kern is None else kern
    if k is None:
        if reduced is None:
            _charge_reduction(np.shape(a)[0])
        return ils_search_py(a, Q, m, reduced)
    av = np.ascontiguousarray(a, dtype=np.float64)
    if reduced is None:
        F, s, d, code = k.ils_k(av, np.ascontiguousarray(Q, dtype=np.float64), m, MAX_SEARCH_NODES)
    else:
        ops, L, d = reduced
        ops_a = np.asarray(ops, dtype=np.int64).reshape(-1, 3)
        F, s, code = k.ils_from_reduced_k(
            av, ops_a, np.ascontiguousarray(L, dtype=np.float64), d, m, MAX_SEARCH_NODES
        )
    if code != k.OK:
        raise _kernel_error(k, code)
    return F, s, d


def ils_search_py(
    a: FloatArray,
    Q: FloatArray,
    m: int,
    reduced: tuple[list[ReduceOp] | npt.NDArray[np.int64], FloatArray, FloatArray] | None = None,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Pure reference of :func:`ils_search` (same parameters and results)."""
    a0 = np.round(a)
    if reduced is None:
        L0, d0 = _ltdl_py(Q)
        reduced = reduce_ops_py(L0, d0, full=False)
    ops_any, L, d = reduced
    ops: list[ReduceOp] = (
        [(j, i, mu) for j, i, mu in ops_any.tolist()] if isinstance(ops_any, np.ndarray) else ops_any
    )
    z_hat = _apply_zt(ops, a - a0)
    Zfix, s = search_py(L, d, z_hat, m)
    F = np.round(_apply_zinvt(ops, Zfix)) + a0[:, None]
    return F, s, d


#: Former private name of :func:`reduce_ops` (kept so existing callers keep working).
_reduce_ops = reduce_ops


def decorrelate(Q: npt.ArrayLike, a: npt.ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """LAMBDA reduction: decorrelate the float ambiguities with a unimodular ``Z``.

    Parameters
    ----------
    Q : array_like, shape (n, n)
        Covariance of the float ambiguities (cycles²), symmetric positive definite.
    a : array_like, shape (n,)
        Float ambiguities (cycles).

    Returns
    -------
    Z : ndarray, shape (n, n)
        Unimodular integer matrix (float dtype, integer values, ``|det Z| = 1``).
    L : ndarray, shape (n, n)
        Unit lower-triangular factor of ``Qz = Zᵀ Q Z = Lᵀ diag(d) L``.
    d : ndarray, shape (n,)
        Conditional variances of the decorrelated ambiguities (cycles²).
    z_hat : ndarray, shape (n,)
        Decorrelated float ambiguities ``ẑ = Zᵀ â`` (cycles).

    Notes
    -----
    Integer Gauss transformations make ``|L_ij| ≤ 1/2`` below the diagonal and
    symmetric permutations of adjacent pairs ``(j, j+1)`` are applied while
    ``d_j + L²_{j+1,j} d_{j+1} < d_{j+1}`` (de Jonge & Tiberius 1996; the
    "reduction" of Chang et al. 2005 with its restart rule).
    """
    aa = np.asarray(a, dtype=np.float64).reshape(-1)
    L0, d0 = ltdl(check_q(Q, aa.shape[0]))
    Z, _, L, d = _reduce(L0, d0)
    return Z, L, d, Z.T @ aa


class SearchLimitError(ValueError):
    """The integer search visited more nodes than allowed (float solution far too weak)."""


#: Default cap on the nodes the search may visit; a float solution that needs more is
#: far too weak to be fixed (the candidates' ellipsoid holds astronomically many points).
MAX_SEARCH_NODES = 200_000


def search(
    L: npt.ArrayLike,
    d: npt.ArrayLike,
    z_hat: npt.ArrayLike,
    m: int = 2,
    max_nodes: int = MAX_SEARCH_NODES,
) -> tuple[FloatArray, FloatArray]:
    """MLAMBDA depth-first search with a shrinking ellipsoid.

    The compiled kernel (:func:`robustrtk.ambiguity.lambda_kernels.search_k`) when
    available, else :func:`search_py`; same parameters, results and errors.
    """
    k = kernels()
    if k is None:
        return search_py(L, d, z_hat, m, max_nodes)
    Ln = np.ascontiguousarray(L, dtype=np.float64)
    dn = np.ascontiguousarray(d, dtype=np.float64).reshape(-1)
    zs = np.ascontiguousarray(z_hat, dtype=np.float64).reshape(-1)
    n = dn.shape[0]
    if m < 1:
        raise ValueError(f"m must be >= 1, got {m}")
    if Ln.shape != (n, n) or zs.shape[0] != n:
        raise ValueError("L, d and z_hat have inconsistent sizes")
    if not np.all(dn > 0.0):
        raise ValueError("d must be positive")
    Zfix, s, code = k.search_k(Ln, dn, zs, m, max_nodes)
    if code == k.SEARCH_LIMIT:
        raise SearchLimitError(f"integer search exceeded {max_nodes} nodes (float solution too weak)")
    return Zfix, s


def search_py(
    L: npt.ArrayLike,
    d: npt.ArrayLike,
    z_hat: npt.ArrayLike,
    m: int = 2,
    max_nodes: int = MAX_SEARCH_NODES,
) -> tuple[FloatArray, FloatArray]:
    """MLAMBDA depth-first search with a shrinking ellipsoid (pure reference of :func:`search`).

    Finds the ``m`` integer vectors ``z`` with the smallest
    ``(ẑ − z)ᵀ Qz⁻¹ (ẑ − z)`` where ``Qz = Lᵀ diag(d) L``.

    Parameters
    ----------
    L : array_like, shape (n, n)
        Unit lower-triangular factor.
    d : array_like, shape (n,)
        Conditional variances (cycles²), all positive.
    z_hat : array_like, shape (n,)
        Float ambiguities in the same (decorrelated) space (cycles).
    m : int
        Number of candidates (≥ 1).
    max_nodes : int
        Largest number of search steps; :class:`SearchLimitError` beyond it.

    Returns
    -------
    Zfix : ndarray, shape (n, m)
        Candidates as columns (integer values), best first.
    s : ndarray, shape (m,)
        Their squared norms, ascending.

    Raises
    ------
    SearchLimitError
        More than ``max_nodes`` steps were needed.

    Notes
    -----
    With ``Qz = Lᵀ D L`` the quadratic form splits into
    ``Σ_k (ž_k|K − z_k)² / d_k`` where the conditional estimate is
    ``ž_k|K = ẑ_k + Σ_{i>k} (z_i − ž_i|I) L_ik`` (``ž_i|I`` the conditional
    estimate at level ``i``), enumerated from ``k = n−1`` down to ``0`` in the
    zig-zag order of Schnorr–Euchner around ``round(ž_k|K)``. Once ``m``
    candidates are stored the radius shrinks to the largest stored norm
    (Chang, Yang & Zhou 2005).
    """
    Ln = np.asarray(L, dtype=np.float64)
    dn = np.asarray(d, dtype=np.float64).reshape(-1)
    zs = [float(v) for v in np.asarray(z_hat, dtype=np.float64).reshape(-1)]
    n = dn.shape[0]
    if m < 1:
        raise ValueError(f"m must be >= 1, got {m}")
    if Ln.shape != (n, n) or len(zs) != n:
        raise ValueError("L, d and z_hat have inconsistent sizes")
    if not np.all(dn > 0.0):
        raise ValueError("d must be positive")
    Lr = [list(map(float, row)) for row in Ln]  # Lr[i][k] = L[i, k]
    dinv = [1.0 / float(v) for v in dn]

    # S[k][t] accumulates Σ_{i>k} (z_i − zb_i) L[i, t] for t ≤ k
    S = [[0.0] * n for _ in range(n)]
    dist = [0.0] * n
    zb = [0.0] * n
    z = [0.0] * n
    step = [0.0] * n

    cand_z: list[list[float]] = []
    cand_s: list[float] = []
    maxdist = math.inf
    imax = 0

    k = n - 1
    zb[k] = zs[k]
    z[k] = float(round(zb[k]))
    y = zb[k] - z[k]
    step[k] = 1.0 if y > 0.0 else -1.0
    nodes = 0
    while True:
        nodes += 1
        if nodes > max_nodes:
            raise SearchLimitError(f"integer search exceeded {max_nodes} nodes (float solution too weak)")
        newdist = dist[k] + y * y * dinv[k]
        if newdist < maxdist:
            if k != 0:
                dz = z[k] - zb[k]
                rowk = Lr[k]
                Sk1 = S[k]
                k -= 1
                dist[k] = newdist
                Sk = S[k]
                for t in range(k + 1):
                    Sk[t] = Sk1[t] + dz * rowk[t]
                zb[k] = zs[k] + Sk[k]
                z[k] = float(round(zb[k]))
                y = zb[k] - z[k]
                step[k] = 1.0 if y > 0.0 else -1.0
            else:
                if len(cand_s) < m:
                    cand_z.append(z.copy())
                    cand_s.append(newdist)
                    if len(cand_s) == m:
                        imax = max(range(m), key=cand_s.__getitem__)
                        maxdist = cand_s[imax]
                else:
                    if newdist < cand_s[imax]:
                        cand_z[imax] = z.copy()
                        cand_s[imax] = newdist
                        imax = max(range(m), key=cand_s.__getitem__)
                    maxdist = cand_s[imax]
                z[0] += step[0]
                y = zb[0] - z[0]
                step[0] = -step[0] - (1.0 if step[0] > 0.0 else -1.0)
        else:
            if k == n - 1:
                break
            k += 1
            z[k] += step[k]
            y = zb[k] - z[k]
            step[k] = -step[k] - (1.0 if step[k] > 0.0 else -1.0)

    order = sorted(range(m), key=cand_s.__getitem__)
    Zfix = np.array([cand_z[i] for i in order]).T.reshape(n, m)
    s = np.array([cand_s[i] for i in order])
    return Zfix, s


def lambda_search(a_float: npt.ArrayLike, Q: npt.ArrayLike, m: int = 2) -> tuple[FloatArray, FloatArray]:
    """Best ``m`` integer least-squares candidates for float ambiguities.

    Parameters
    ----------
    a_float : array_like, shape (n,)
        Float ambiguities ``â`` (cycles), finite.
    Q : array_like, shape (n, n)
        Their covariance (cycles²), symmetric positive definite.
    m : int
        Number of candidates.

    Returns
    -------
    F : ndarray, shape (n, m)
        Candidates (integer values as float64) in the original space, best first.
    s : ndarray, shape (m,)
        Squared norms ``(â − F[:, j])ᵀ Q⁻¹ (â − F[:, j])``, ascending.

    Raises
    ------
    ValueError
        If ``Q`` is not symmetric positive definite, sizes disagree, ``m < 1`` or
        ``a_float`` is not finite.

    Notes
    -----
    ``round(â)`` is removed before the search and added back (integer shift; it
    keeps ``ẑ`` small so large ambiguities lose no precision). Candidates are
    back-transformed as ``a = Z⁻ᵀ z`` by undoing the recorded integer operations of
    the reduction (exact; ``Z`` is never formed).
    """
    k = kernels()
    if k is None:
        _charge_reduction(np.shape(a_float)[0])
        return lambda_search_py(a_float, Q, m)
    a = np.ascontiguousarray(a_float, dtype=np.float64).reshape(-1)
    q = np.ascontiguousarray(Q, dtype=np.float64)
    n = a.shape[0]
    if n == 0:
        raise ValueError("a_float must have at least one element")
    if m < 1:
        raise ValueError(f"m must be >= 1, got {m}")
    if q.ndim != 2 or q.shape[0] != q.shape[1]:
        raise ValueError(f"Q must be a square (n, n) matrix, got shape {q.shape}")
    if q.shape[0] != n:
        raise ValueError(f"Q has shape {q.shape} but the float vector has length {n}")
    F, s, code = k.lambda_all(a, q, m, MAX_SEARCH_NODES)
    if code != k.OK:
        raise _kernel_error(k, code)
    return F, s


def lambda_search_py(a_float: npt.ArrayLike, Q: npt.ArrayLike, m: int = 2) -> tuple[FloatArray, FloatArray]:
    """Pure reference of :func:`lambda_search` (same parameters, results and errors)."""
    a = np.asarray(a_float, dtype=np.float64).reshape(-1)
    if a.shape[0] == 0:
        raise ValueError("a_float must have at least one element")
    if not np.all(np.isfinite(a)):
        raise ValueError("a_float contains NaN or infinite entries")
    if m < 1:
        raise ValueError(f"m must be >= 1, got {m}")
    F, s, _ = ils_search_py(a, check_q(Q, a.shape[0]), m)
    return F, s


def _kernel_error(k: ModuleType, code: int) -> ValueError:
    """The exception (and message) of the pure path for a kernel's error code."""
    if code == k.SEARCH_LIMIT:
        return SearchLimitError(f"integer search exceeded {MAX_SEARCH_NODES} nodes (float solution too weak)")
    messages = {
        k.NONFINITE_A: "a_float contains NaN or infinite entries",
        k.NONFINITE_Q: "Q contains NaN or infinite entries",
        k.ASYMMETRIC_Q: "Q must be symmetric",
        k.NOT_PD: "Q is not positive definite",
    }
    return ValueError(messages.get(code, f"LAMBDA kernel failed (code {code})"))


def bootstrap_success_rate(d: npt.ArrayLike) -> float:
    """Integer-bootstrapping success rate from conditional variances.

    Parameters
    ----------
    d : array_like, shape (n,)
        Conditional variances of the (decorrelated) ambiguities (cycles²).

    Returns
    -------
    float
        ``P_s = Π_i (2 Φ(1 / (2 √d_i)) − 1)``, with ``Φ`` the standard normal CDF
        (computed as ``erf(1 / (2 √(2 d_i)))``). A lower bound of the ILS success rate
        (Teunissen 1999). Empty input gives 1.
    """
    dv = np.asarray(d, dtype=np.float64).reshape(-1).tolist()
    if not all(di > 0.0 for di in dv):  # NaN fails too
        raise ValueError("conditional variances must be positive")
    p = 1.0
    for di in dv:
        p *= math.erf(1.0 / (2.0 * math.sqrt(2.0 * di)))
    return p
