"""The pure-Python LAMBDA: the oracle of the compiled kernels (``lambda_ckernels``).

The same arithmetic as the C kernels, operation for operation, in plain Python floats in the
inner loops: the LᵀDL factorisation (:func:`ltdl_py`, LAPACK's Cholesky of the flipped
matrix), the reduction (:func:`reduce_ops_py`), the MLAMBDA search (:func:`search_py`) and
the whole integer least squares (:func:`ils_search_py`, :func:`lambda_search_py`), with the
input check (:func:`check_q`) and the exact integer back-transforms from the list of
reduction operations (:func:`ops_to_z`, :func:`apply_zt`, :func:`apply_zinvt`). The public
entry points of :mod:`robustrtk.ambiguity.lambda_` call these when the C kernels are not
built (or ``ROBUSTRTK_LAMBDA_BACKEND=pure``); the tests hold the C kernels to them
(algorithms.md §7, §22).

Conventions: vectors in cycles, covariances in cycles²; candidates are float arrays holding
integer values.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]

__all__ = [
    "MAX_SEARCH_NODES",
    "ReduceOp",
    "SearchLimitError",
    "apply_zinvt",
    "apply_zt",
    "check_q",
    "ils_search_py",
    "lambda_search_py",
    "ltdl_py",
    "ops_to_z",
    "reduce_ops_py",
    "search_py",
]


class SearchLimitError(ValueError):
    """The integer search visited more nodes than allowed (float solution far too weak)."""


#: Default cap on the nodes the search may visit; a float solution that needs more is
#: far too weak to be fixed (the candidates' ellipsoid holds astronomically many points).
MAX_SEARCH_NODES = 200_000


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


def ltdl_py(Q: npt.ArrayLike, *, checked: bool = False) -> tuple[FloatArray, FloatArray]:
    """Pure reference of :func:`robustrtk.ambiguity.lambda_.ltdl`: ``Q = Lᵀ diag(d) L``
    by LAPACK's Cholesky of the flipped matrix.

    Parameters
    ----------
    Q : array_like, shape (n, n)
        Symmetric positive-definite covariance (cycles²).
    checked : bool
        ``Q`` is already an output of :func:`check_q` (exactly symmetric, finite): the check,
        which would return the same numbers, is skipped.

    Returns
    -------
    L : ndarray, shape (n, n)
        Unit lower-triangular factor.
    d : ndarray, shape (n,)
        Conditional variances (cycles²).

    Raises
    ------
    ValueError
        ``Q`` fails :func:`check_q` or is not positive definite.
    """
    q = np.asarray(Q, dtype=np.float64) if checked else check_q(Q)
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


def reduce_ops_py(
    L: FloatArray, d: FloatArray, full: bool = True
) -> tuple[list[ReduceOp], FloatArray, FloatArray]:
    """Integer Gauss transformations + permutations on the factors (works on copies).

    Parameters
    ----------
    L : ndarray, shape (n, n)
        Unit lower-triangular factor of ``Q = Lᵀ diag(d) L`` (from :func:`ltdl_py` or
        :func:`robustrtk.ambiguity.lambda_.ltdl`).
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


def ops_to_z(n: int, ops: list[ReduceOp]) -> tuple[FloatArray, FloatArray]:
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


def apply_zt(ops: list[ReduceOp], v: FloatArray) -> FloatArray:
    """``Zᵀ v`` for ``v`` of shape (n,), from the operation list."""
    x = np.asarray(v, dtype=np.float64).tolist()
    for j, i, mu in ops:
        if i < 0:
            x[j], x[j + 1] = x[j + 1], x[j]
        else:
            x[j] -= mu * x[i]
    return np.array(x)


def apply_zinvt(ops: list[ReduceOp], v: FloatArray) -> FloatArray:
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


def ils_search_py(
    a: FloatArray,
    Q: FloatArray,
    m: int,
    reduced: tuple[list[ReduceOp] | npt.NDArray[np.int64], FloatArray, FloatArray] | None = None,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Pure reference of :func:`robustrtk.ambiguity.lambda_.ils_search` (same parameters and results)."""
    a0 = np.round(a)
    if reduced is None:
        L0, d0 = ltdl_py(Q, checked=True)
        reduced = reduce_ops_py(L0, d0, full=False)
    ops_any, L, d = reduced
    ops: list[ReduceOp] = (
        [(j, i, mu) for j, i, mu in ops_any.tolist()] if isinstance(ops_any, np.ndarray) else ops_any
    )
    z_hat = apply_zt(ops, a - a0)
    Zfix, s = search_py(L, d, z_hat, m)
    F = np.round(apply_zinvt(ops, Zfix)) + a0[:, None]
    return F, s, d


def search_py(
    L: npt.ArrayLike,
    d: npt.ArrayLike,
    z_hat: npt.ArrayLike,
    m: int = 2,
    max_nodes: int = MAX_SEARCH_NODES,
) -> tuple[FloatArray, FloatArray]:
    """MLAMBDA depth-first search with a shrinking ellipsoid (pure reference of
    :func:`robustrtk.ambiguity.lambda_.search`).

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


def lambda_search_py(a_float: npt.ArrayLike, Q: npt.ArrayLike, m: int = 2) -> tuple[FloatArray, FloatArray]:
    """Pure reference of :func:`robustrtk.ambiguity.lambda_.lambda_search` (same parameters,
    results and errors)."""
    a = np.asarray(a_float, dtype=np.float64).reshape(-1)
    if a.shape[0] == 0:
        raise ValueError("a_float must have at least one element")
    if not np.all(np.isfinite(a)):
        raise ValueError("a_float contains NaN or infinite entries")
    if m < 1:
        raise ValueError(f"m must be >= 1, got {m}")
    F, s, _ = ils_search_py(a, check_q(Q, a.shape[0]), m)
    return F, s
