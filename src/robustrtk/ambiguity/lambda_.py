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

Two implementations of the same arithmetic: compiled kernels in C
(:mod:`robustrtk.ambiguity.lambda_ckernels`, an optional library built at install time) and
the pure-Python references of :mod:`robustrtk.ambiguity.lambda_pure` (``ltdl_py``,
``reduce_ops_py``, ``search_py``, ``ils_search_py``, ``lambda_search_py``; re-exported here),
the kernels' test oracles. The public entry points take the C kernels whenever they are
built, else the pure references (:func:`kernels`; algorithms.md §22).
"""

from __future__ import annotations

import math
import os
from types import ModuleType

import numpy as np
import numpy.typing as npt

from robustrtk.ambiguity.lambda_pure import (
    MAX_SEARCH_NODES,
    FloatArray,
    ReduceOp,
    SearchLimitError,
    check_q,
    ils_search_py,
    lambda_search_py,
    ltdl_py,
    ops_to_z,
    reduce_ops_py,
    search_py,
)
from robustrtk.errors import InputError

__all__ = [
    "BACKENDS",
    "MAX_SEARCH_NODES",
    "ReduceOp",
    "SearchLimitError",
    "backend",
    "bootstrap_success_rate",
    "check_q",
    "decorrelate",
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

_CKERNELS: list[ModuleType | None] = []  # the C module once imported (None: not built)
_BACKEND: list[str] = []  # the backend as last read by backend(), kept for kernels()

#: Values of ``ROBUSTRTK_LAMBDA_BACKEND``: ``auto`` (C when built, else pure), ``c`` (C, an
#: error when it is not built) or ``pure``.
BACKENDS = ("auto", "c", "pure")


def backend() -> str:
    """Read ``ROBUSTRTK_LAMBDA_BACKEND`` now (default ``auto``) and keep it for
    :func:`kernels` until the next call (a run calls this when it begins).

    Raises
    ------
    InputError
        The variable holds something other than auto, c or pure.
    """
    raw = os.environ.get("ROBUSTRTK_LAMBDA_BACKEND", "").strip().lower() or "auto"
    if raw not in BACKENDS:
        raise InputError(f"environment variable ROBUSTRTK_LAMBDA_BACKEND={raw!r}: expected auto, c or pure")
    _BACKEND[:] = [raw]
    return raw


def _c_kernels() -> ModuleType | None:
    """The C kernels module (:mod:`robustrtk.ambiguity.lambda_ckernels`), None when not built."""
    if not _CKERNELS:
        mod: ModuleType | None = None
        try:
            from robustrtk.ambiguity import lambda_ckernels as mod
        except ImportError:  # the optional library was not built: the pure references serve
            mod = None
        _CKERNELS.append(mod)
    return _CKERNELS[0]


def kernels() -> ModuleType | None:
    """The C kernels (:mod:`robustrtk.ambiguity.lambda_ckernels`) when they are built, else
    None (the pure references of :mod:`robustrtk.ambiguity.lambda_pure`).

    The library costs about a millisecond and a megabyte to load, so it serves from the first
    call. ``ROBUSTRTK_LAMBDA_BACKEND=pure`` selects the references, ``c`` insists on the
    library (algorithms.md §22). The variable is read by :func:`backend` (when a run begins,
    or on the first look-up) and kept: reading the environment costs a few microseconds, a
    large part of a 10-ambiguity search, so a change takes effect at the next run.

    Raises
    ------
    InputError
        ``ROBUSTRTK_LAMBDA_BACKEND`` is not auto, c or pure, or is ``c`` and the C library is
        not built.
    """
    choice = _BACKEND[0] if _BACKEND else backend()
    if choice == "pure":
        return None
    ck = _c_kernels()
    if ck is None and choice == "c":
        raise InputError(
            "environment variable ROBUSTRTK_LAMBDA_BACKEND=c but the C LAMBDA kernels are not built "
            "(python setup.py build_ext --inplace)"
        )
    return ck


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
    ``i+1 … n-1``. The C kernel eliminates row by row from the last
    (:func:`robustrtk.ambiguity.lambda_ckernels.ltdl_k`); the same factors to rounding.
    """
    return _ltdl(check_q(Q))


def _ltdl(q: FloatArray) -> tuple[FloatArray, FloatArray]:
    """:func:`ltdl` without the input checks (``q`` symmetric, finite)."""
    k = kernels()
    if k is None:
        return ltdl_py(q, checked=True)
    L, d, code = k.ltdl_k(np.ascontiguousarray(q))
    if code != k.OK:
        raise ValueError("Q is not positive definite")
    return L, d


def reduce_ops(
    L: FloatArray, d: FloatArray, full: bool = True
) -> tuple[list[ReduceOp], FloatArray, FloatArray]:
    """Integer Gauss transformations + permutations on the factors (works on copies).

    The C kernel (:func:`robustrtk.ambiguity.lambda_ckernels.reduce_k`) when built, else
    :func:`~robustrtk.ambiguity.lambda_pure.reduce_ops_py`; same parameters, results and
    operation order.
    """
    k = kernels()
    if k is None:
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
        Kernels to use instead of looking them up (:func:`kernels` of the caller, which
        makes many calls in a row); None looks them up.

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
        L0, d0 = ltdl_py(q, checked=True)
        ops_l, L, d = reduce_ops_py(L0, d0)
        return np.array(ops_l, dtype=np.int64).reshape(-1, 3), L, d
    L0, d0, code = k.ltdl_k(np.ascontiguousarray(q))
    if code != k.OK:
        raise ValueError("Q is not positive definite")
    ops, L, d = k.reduce_k(L0, d0)
    return ops, L, d


def _reduce(
    L: FloatArray, d: FloatArray, full: bool = True
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Reduction returning ``(Z, Zinv, L, d)``; see :func:`reduce_ops`."""
    ops, Lr, dr = reduce_ops(L, d, full)
    Z, Zinv = ops_to_z(d.shape[0], ops)
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


def search(
    L: npt.ArrayLike,
    d: npt.ArrayLike,
    z_hat: npt.ArrayLike,
    m: int = 2,
    max_nodes: int = MAX_SEARCH_NODES,
) -> tuple[FloatArray, FloatArray]:
    """MLAMBDA depth-first search with a shrinking ellipsoid.

    The C kernel (:func:`robustrtk.ambiguity.lambda_ckernels.search_k`) when built, else
    :func:`~robustrtk.ambiguity.lambda_pure.search_py`; same parameters, results and errors.
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
