"""Compiled (numba) kernels of the LAMBDA method: LᵀDL, reduction, MLAMBDA search.

Each kernel does, operation for operation, what the pure-Python reference of the same
name in :mod:`robustrtk.ambiguity.lambda_` does (``ltdl_py``, ``reduce_ops_py``,
``search_py``, ``ils_search_py``); the pure versions are the test oracles
(tests/ambiguity/test_lambda_kernels.py). The equations are those of algorithms.md §7
(LAMBDA) and §22 (kernels) and the notes of :func:`robustrtk.ambiguity.lambda_.reduce_ops`.

This module imports numba and is itself imported lazily (on the first ambiguity
resolution), so the command line's start-up never pays numba's import. Kernels are compiled
once per machine and cached on disk (``cache=True``).

Errors are returned as integer codes, never raised, so that a kernel never leaves the
compiled code through an exception:

* ``OK = 0``
* ``NOT_PD = 1``: ``Q`` is not positive definite (a non-positive pivot or a non-finite factor);
* ``SEARCH_LIMIT = 2``: the search visited more than ``max_nodes`` nodes;
* ``NONFINITE_A = 3``, ``NONFINITE_Q = 4``, ``ASYMMETRIC_Q = 5``: input checks of
  :func:`lambda_all`.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

OK = 0
NOT_PD = 1
SEARCH_LIMIT = 2
NONFINITE_A = 3
NONFINITE_Q = 4
ASYMMETRIC_Q = 5

#: Tolerance that prevents endless swapping in the reduction (as in ``lambda_``).
SWAP_TOL = 1e-6

_jit = nb.njit(cache=True, nogil=True, error_model="numpy")


@_jit
def ltdl_k(q: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """``Q = Lᵀ diag(d) L`` by elimination from the last row to the first.

    Parameters
    ----------
    q : ndarray, shape (n, n)
        Symmetric covariance (cycles²); not modified.

    Returns
    -------
    L : ndarray, shape (n, n)
        Unit lower-triangular factor.
    d : ndarray, shape (n,)
        Conditional variances (cycles²).
    code : int
        ``OK`` or ``NOT_PD``.

    Notes
    -----
    For ``i = n−1 … 0``: ``d_i = A_ii``, ``L_i,0:i = A_i,0:i / d_i``, then the leading block
    is updated, ``A_jk ← A_jk − L_ij L_ik d_i`` (``j, k < i``): the Schur complement of the
    trailing variables, so that ``d_i`` is the variance of ambiguity ``i`` given ``i+1 … n−1``.
    """
    n = q.shape[0]
    A = q.copy()
    L = np.zeros((n, n))
    d = np.zeros(n)
    for i in range(n - 1, -1, -1):
        di = A[i, i]
        if not (di > 0.0) or not math.isfinite(di):
            return L, d, NOT_PD
        d[i] = di
        s = math.sqrt(di)
        for j in range(i):
            L[i, j] = A[i, j] / s  # scaled (Cholesky) row
        for j in range(i):
            lij = L[i, j]
            for k in range(j + 1):
                A[j, k] -= L[i, k] * lij
        for j in range(i):
            L[i, j] = L[i, j] / s
            if not math.isfinite(L[i, j]):
                return L, d, NOT_PD
        L[i, i] = 1.0
    return L, d, OK


@_jit
def reduce_k(L: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Integer Gauss transformations and permutations (works on copies).

    Parameters
    ----------
    L : ndarray, shape (n, n)
        Unit lower-triangular factor.
    d : ndarray, shape (n,)
        Its diagonal (cycles²).

    Returns
    -------
    ops : ndarray of int64, shape (k, 3)
        The operations ``(j, i, mu)`` (``i = -1``: permutation of ``j, j+1``), in order.
    L, d : ndarray
        The reduced factors, ``Zᵀ Q Z = Lᵀ diag(d) L``.

    Notes
    -----
    Runs :func:`reduce_into_k` with room for ``8 n² + 16`` operations, again with four
    times the room in the (never observed) case it was not enough.
    """
    n = d.shape[0]
    cap = 8 * n * n + 16
    while True:
        ops, nops, Lr, dr = reduce_into_k(L, d, cap)
        if nops >= 0:
            return ops[:nops].copy(), Lr, dr
        cap *= 4


@_jit
def reduce_into_k(L: np.ndarray, d: np.ndarray, cap: int) -> tuple[np.ndarray, int, np.ndarray, np.ndarray]:
    """Integer Gauss transformations and permutations (works on copies).

    Parameters
    ----------
    L : ndarray, shape (n, n)
        Unit lower-triangular factor.
    d : ndarray, shape (n,)
        Its diagonal (cycles²).

    cap : int
        Room for operations.

    Returns
    -------
    ops : ndarray of int64, shape (cap, 3)
        The operations ``(j, i, mu)`` (``i = -1``: permutation of ``j, j+1``), in order, in
        the first ``nops`` rows.
    nops : int
        Their number; ``-1`` when ``cap`` was too small (the other outputs are then void).
    L, d : ndarray
        The reduced factors, ``Zᵀ Q Z = Lᵀ diag(d) L``.

    Notes
    -----
    De Jonge & Tiberius' order with whole-column size reduction (see
    :func:`robustrtk.ambiguity.lambda_.reduce_ops`), the same arithmetic in the same order.
    """
    n = d.shape[0]
    Lc = np.ascontiguousarray(L.T)  # Lc[j, r] = L[r, j]: column j of L is row j of Lc
    dl = d.copy()
    ops = np.empty((cap, 3), dtype=np.int64)
    nops = 0
    j = n - 2
    k = n - 2
    while j >= 0:
        if j <= k:
            for i in range(j + 1, n):
                v = Lc[j, i]
                if v > 0.5 or v < -0.5:
                    mu = np.rint(v)
                    if mu != 0.0:
                        for r in range(i, n):
                            Lc[j, r] = Lc[j, r] - mu * Lc[i, r]
                        if nops == cap:
                            return ops, -1, Lc, dl
                        ops[nops, 0] = j
                        ops[nops, 1] = i
                        ops[nops, 2] = np.int64(mu)
                        nops += 1
        lj1 = Lc[j, j + 1]
        delta = dl[j] + lj1 * lj1 * dl[j + 1]
        if delta + SWAP_TOL < dl[j + 1]:
            eta = dl[j] / delta
            lam = dl[j + 1] * lj1 / delta
            dl[j] = eta * dl[j + 1]
            dl[j + 1] = delta
            for c in range(j):
                a0 = Lc[c, j]
                a1 = Lc[c, j + 1]
                Lc[c, j] = -lj1 * a0 + a1
                Lc[c, j + 1] = eta * a0 + lam * a1
            Lc[j, j + 1] = lam
            for r in range(j + 2, n):
                t = Lc[j, r]
                Lc[j, r] = Lc[j + 1, r]
                Lc[j + 1, r] = t
            if nops == cap:
                return ops, -1, Lc, dl
            ops[nops, 0] = j
            ops[nops, 1] = -1
            ops[nops, 2] = 0
            nops += 1
            k = j
            j = n - 2
        else:
            j -= 1
    return ops, nops, np.ascontiguousarray(Lc.T), dl


@_jit
def search_k(
    L: np.ndarray, d: np.ndarray, zs: np.ndarray, m: int, max_nodes: int
) -> tuple[np.ndarray, np.ndarray, int]:
    """MLAMBDA depth-first search (Schnorr–Euchner zig-zag, shrinking ellipsoid).

    Parameters
    ----------
    L : ndarray, shape (n, n)
        Unit lower-triangular factor of ``Qz = Lᵀ diag(d) L``.
    d : ndarray, shape (n,)
        Positive conditional variances (cycles²).
    zs : ndarray, shape (n,)
        Float ambiguities in the decorrelated space (cycles).
    m : int
        Number of candidates (≥ 1).
    max_nodes : int
        Cap on the search steps.

    Returns
    -------
    Zfix : ndarray, shape (n, m)
        Candidates as columns, best first.
    s : ndarray, shape (m,)
        Their squared norms ``Σ_k (ž_k|K − z_k)² / d_k``, ascending.
    code : int
        ``OK`` or ``SEARCH_LIMIT``.
    """
    n = d.shape[0]
    dinv = 1.0 / d
    S = np.zeros((n, n))
    dist = np.zeros(n)
    zb = np.zeros(n)
    z = np.zeros(n)
    step = np.zeros(n)
    cand_z = np.zeros((m, n))
    cand_s = np.full(m, np.inf)
    ncand = 0
    maxdist = np.inf
    imax = 0
    k = n - 1
    zb[k] = zs[k]
    z[k] = np.rint(zb[k])
    y = zb[k] - z[k]
    step[k] = 1.0 if y > 0.0 else -1.0
    nodes = 0
    code = OK
    while True:
        nodes += 1
        if nodes > max_nodes:
            code = SEARCH_LIMIT
            break
        newdist = dist[k] + y * y * dinv[k]
        if newdist < maxdist:
            if k != 0:
                dz = z[k] - zb[k]
                k1 = k
                k -= 1
                dist[k] = newdist
                for t in range(k + 1):
                    S[k, t] = S[k1, t] + dz * L[k1, t]
                zb[k] = zs[k] + S[k, k]
                z[k] = np.rint(zb[k])
                y = zb[k] - z[k]
                step[k] = 1.0 if y > 0.0 else -1.0
            else:
                if ncand < m:
                    cand_z[ncand, :] = z
                    cand_s[ncand] = newdist
                    ncand += 1
                    if ncand == m:
                        imax = 0
                        for c in range(1, m):
                            if cand_s[c] > cand_s[imax]:
                                imax = c
                        maxdist = cand_s[imax]
                else:
                    if newdist < cand_s[imax]:
                        cand_z[imax, :] = z
                        cand_s[imax] = newdist
                        imax = 0
                        for c in range(1, m):
                            if cand_s[c] > cand_s[imax]:
                                imax = c
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
    order = np.argsort(cand_s, kind="mergesort")  # stable, as Python's sorted
    Zfix = np.empty((n, m))
    s = np.empty(m)
    for c in range(m):
        Zfix[:, c] = cand_z[order[c], :]
        s[c] = cand_s[order[c]]
    return Zfix, s, code


@_jit
def apply_zt_k(ops: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``Zᵀ v`` for ``v`` of shape (n,) from the operation list (in order)."""
    x = v.copy()
    for r in range(ops.shape[0]):
        j = ops[r, 0]
        i = ops[r, 1]
        if i < 0:
            t = x[j]
            x[j] = x[j + 1]
            x[j + 1] = t
        else:
            x[j] -= ops[r, 2] * x[i]
    return x


@_jit
def apply_zinvt_k(ops: np.ndarray, V: np.ndarray) -> np.ndarray:
    """``Z⁻ᵀ V`` for ``V`` of shape (n, k) from the operation list (in reverse order)."""
    X = V.copy()
    kk = X.shape[1]
    for r in range(ops.shape[0] - 1, -1, -1):
        j = ops[r, 0]
        i = ops[r, 1]
        if i < 0:
            for c in range(kk):
                t = X[j, c]
                X[j, c] = X[j + 1, c]
                X[j + 1, c] = t
        else:
            mu = ops[r, 2]
            for c in range(kk):
                X[j, c] += mu * X[i, c]
    return X


@_jit
def ils_from_reduced_k(
    a: np.ndarray, ops: np.ndarray, L: np.ndarray, d: np.ndarray, m: int, max_nodes: int
) -> tuple[np.ndarray, np.ndarray, int]:
    """Search on reduced factors and back-transform: ``F = round(Z⁻ᵀ ž) + round(â)``.

    Parameters
    ----------
    a : ndarray, shape (n,)
        Float ambiguities (cycles).
    ops, L, d :
        The output of :func:`reduce_k` for ``Q``.
    m, max_nodes : int
        As :func:`search_k`.

    Returns
    -------
    F : ndarray, shape (n, m)
    s : ndarray, shape (m,)
    code : int
    """
    a0 = np.rint(a)
    z_hat = apply_zt_k(ops, a - a0)
    Zfix, s, code = search_k(L, d, z_hat, m, max_nodes)
    F = np.rint(apply_zinvt_k(ops, Zfix))
    n = a.shape[0]
    for i in range(n):
        for c in range(m):
            F[i, c] += a0[i]
    return F, s, code


@_jit
def ils_k(
    a: np.ndarray, q: np.ndarray, m: int, max_nodes: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Whole ILS on a checked, symmetric ``q``: LᵀDL, reduction, search, back-transform.

    Returns
    -------
    F : ndarray, shape (n, m)
        Candidates, best first (integer values).
    s : ndarray, shape (m,)
        Squared norms, ascending.
    d : ndarray, shape (n,)
        Decorrelated conditional variances (cycles²).
    code : int
        ``OK``, ``NOT_PD`` or ``SEARCH_LIMIT``.
    """
    n = a.shape[0]
    L0, d0, code = ltdl_k(q)
    if code != OK:
        return np.zeros((n, m)), np.zeros(m), d0, code
    ops, L, d = reduce_k(L0, d0)
    F, s, code = ils_from_reduced_k(a, ops, L, d, m, max_nodes)
    return F, s, d, code


@_jit
def lambda_all(a: np.ndarray, Q: np.ndarray, m: int, max_nodes: int) -> tuple[np.ndarray, np.ndarray, int]:
    """Input checks of ``check_q`` (finite, symmetric to ``1e-9 max|Q|``), symmetrisation
    ``(Q + Qᵀ)/2`` and :func:`ils_k`, in one call.

    Returns
    -------
    F : ndarray, shape (n, m)
    s : ndarray, shape (m,)
    code : int
        ``OK``, ``NONFINITE_A``, ``NONFINITE_Q``, ``ASYMMETRIC_Q``, ``NOT_PD`` or
        ``SEARCH_LIMIT``.
    """
    n = a.shape[0]
    for i in range(n):
        if not math.isfinite(a[i]):
            return np.zeros((n, m)), np.zeros(m), NONFINITE_A
    scale = 0.0
    for i in range(n):
        for j in range(n):
            v = abs(Q[i, j])
            if not math.isfinite(v):
                return np.zeros((n, m)), np.zeros(m), NONFINITE_Q
            if v > scale:
                scale = v
    asym = 0.0
    q = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            e = abs(Q[i, j] - Q[j, i])
            if e > asym:
                asym = e
            q[i, j] = 0.5 * (Q[i, j] + Q[j, i])
    if asym > 1e-9 * scale:
        return np.zeros((n, m)), np.zeros(m), ASYMMETRIC_Q
    F, s, _, code = ils_k(a, q, m, max_nodes)
    return F, s, code
