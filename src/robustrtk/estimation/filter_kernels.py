"""Compiled (numba) measurement update of the EKF and UKF for DD range models.

One call does what :meth:`robustrtk.estimation.filters._KalmanBase.update` does for a
:class:`~robustrtk.measurement.dd.DDRangeModel`, no prior scaling and the standard
(non-robust) policy: linearisation (EKF Jacobian or UKF sigma points, algorithms.md §6),
the Kalman update, the posterior residuals and their covariance, the nominal ``Cvv = R S⁻¹ R``,
the standardized residuals and Δv̄ (algorithms.md §4). The equations are those of the module
docstring of :mod:`robustrtk.estimation.filters`; the pure path stays the reference (tests
compare both on random and simulated problems) and takes over whenever this kernel reports
anything but success (a non-finite input, a covariance that is not positive definite, a
singular system), so every refusal keeps its pure-path diagnostics.

This module imports numba; :mod:`robustrtk.estimation.filters` imports it on the first
update that can use it (algorithms.md §22).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

OK = 0
FALLBACK = 1

_jit = nb.njit(cache=True, nogil=True, error_model="numpy")


@_jit
def _chol(A: np.ndarray) -> tuple[np.ndarray, bool]:
    """Lower Cholesky factor ``A = L Lᵀ``; ``ok`` False when a pivot is not positive."""
    n = A.shape[0]
    L = np.zeros((n, n))
    for j in range(n):
        s = A[j, j]
        for k in range(j):
            s -= L[j, k] * L[j, k]
        if not (s > 0.0) or not math.isfinite(s):
            return L, False
        L[j, j] = math.sqrt(s)
        for i in range(j + 1, n):
            t = A[i, j]
            for k in range(j):
                t -= L[i, k] * L[j, k]
            L[i, j] = t / L[j, j]
    return L, True


@_jit
def _solve(A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, bool]:
    """``A⁻¹ B`` by LU with partial pivoting (``B`` of shape (n, k)); ``ok`` False when singular."""
    n = A.shape[0]
    k = B.shape[1]
    M = A.copy()
    X = B.copy()
    for c in range(n):
        p = c
        best = abs(M[c, c])
        for r in range(c + 1, n):
            if abs(M[r, c]) > best:
                best = abs(M[r, c])
                p = r
        if not (best > 0.0) or not math.isfinite(best):
            return X, False
        if p != c:
            for j in range(n):
                t = M[c, j]
                M[c, j] = M[p, j]
                M[p, j] = t
            for j in range(k):
                t = X[c, j]
                X[c, j] = X[p, j]
                X[p, j] = t
        piv = M[c, c]
        for r in range(c + 1, n):
            f = M[r, c] / piv
            if f != 0.0:
                for j in range(c + 1, n):
                    M[r, j] -= f * M[c, j]
                for j in range(k):
                    X[r, j] -= f * X[c, j]
    for c in range(n - 1, -1, -1):
        piv = M[c, c]
        for j in range(k):
            s = X[c, j]
            for q in range(c + 1, n):
                s -= M[c, q] * X[q, j]
            X[c, j] = s / piv
    return X, True


@_jit
def _dd_h(
    X: np.ndarray,
    p0: int,
    tx: np.ndarray,
    base: np.ndarray,
    i_tx: np.ndarray,
    i_ref: np.ndarray,
    amb: np.ndarray,
    wl: np.ndarray,
    corr: np.ndarray,
    has_corr: bool,
    sagnac: bool,
    omega_e: float,
    clight: float,
) -> np.ndarray:
    """DD ranges ``h`` of each row of ``X`` (k, n): shape (k, m) (``DDRangeModel.h``)."""
    k = X.shape[0]
    N = tx.shape[0]
    m = i_tx.shape[0]
    out = np.empty((k, m))
    r = np.empty(N)
    for s in range(k):
        px = X[s, p0]
        py = X[s, p0 + 1]
        pz = X[s, p0 + 2]
        for t in range(N):
            dx = px - tx[t, 0]
            dy = py - tx[t, 1]
            dz = pz - tx[t, 2]
            rr = math.sqrt(dx * dx + dy * dy + dz * dz)
            if sagnac:
                rr = rr + omega_e * (tx[t, 0] * py - tx[t, 1] * px) / clight
            if has_corr:
                rr = rr + corr[t]
            r[t] = rr
        for i in range(m):
            v = (r[i_tx[i]] - r[i_ref[i]]) - (base[i_tx[i]] - base[i_ref[i]])
            if amb[i] >= 0:
                v = v + X[s, amb[i]] * wl[i]
            out[s, i] = v
    return out


@_jit
def _mm(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``A B`` by loops (faster than a BLAS call at these sizes)."""
    n, k = A.shape
    m = B.shape[1]
    C = np.zeros((n, m))
    for i in range(n):
        for q in range(k):
            a = A[i, q]
            if a != 0.0:
                for j in range(m):
                    C[i, j] += a * B[q, j]
    return C


@_jit
def _mmt(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``A Bᵀ`` by loops."""
    n, k = A.shape
    m = B.shape[0]
    C = np.empty((n, m))
    for i in range(n):
        for j in range(m):
            s = 0.0
            for q in range(k):
                s += A[i, q] * B[j, q]
            C[i, j] = s
    return C


@_jit
def _finite(a: np.ndarray) -> bool:
    for v in a.ravel():
        if not math.isfinite(v):
            return False
    return True


@_jit
def dd_update_k(
    x0: np.ndarray,
    P0: np.ndarray,
    z: np.ndarray,
    R: np.ndarray,
    p0: int,
    tx: np.ndarray,
    base: np.ndarray,
    i_tx: np.ndarray,
    i_ref: np.ndarray,
    amb: np.ndarray,
    wl: np.ndarray,
    corr: np.ndarray,
    has_corr: bool,
    sagnac: bool,
    omega_e: float,
    clight: float,
    ukf: bool,
    alpha: float,
    beta: float,
    kappa: float,
    x: np.ndarray,
    P: np.ndarray,
    d: np.ndarray,
    S: np.ndarray,
    v: np.ndarray,
    Cv: np.ndarray,
    std: np.ndarray,
    dv: np.ndarray,
) -> int:
    """One standard (γ = 1, all rows) EKF or UKF update with a DD range model.

    Parameters
    ----------
    x0 : ndarray, shape (n,)
        Prior mean; position at ``x0[p0:p0+3]`` (ECEF or local, m).
    P0 : ndarray, shape (n, n)
        Prior covariance.
    z : ndarray, shape (m,)
        DD measurements (m).
    R : ndarray, shape (m, m)
        Their covariance (m²).
    p0 : int
        Start of the position block.
    tx, base, i_tx, i_ref, amb, wl, corr :
        The fields of :class:`~robustrtk.measurement.dd.DDRangeModel` (``corr`` the
        rover-side delays, used when ``has_corr``).
    sagnac : bool
        Add ``ω (xₛ y − yₛ x) / c`` to each range.
    omega_e, clight : float
        Earth rotation rate (rad/s) and speed of light (m/s) of that term.
    ukf : bool
        Sigma-point linearisation (else the Jacobian at ``x0`` and the Joseph form).
    alpha, beta, kappa : float
        Sigma-point parameters.
    x, P, d, S, v, Cv, std, dv : ndarray
        Outputs, written in place (the caller allocates them; returning arrays from
        compiled code costs more than this whole update): posterior mean (n,) and
        covariance (n, n); innovation ``z − ŷ`` (m,) and its covariance (m, m); posterior
        residuals ``z − h(x̂)`` (m,) and ``R − H P̂ Hᵀ`` (m, m); standardized residuals
        with the nominal ``Cvv = R S⁻¹ R`` (m,) and Δv̄ (m,).

    Returns
    -------
    code : int
        ``OK``, or ``FALLBACK`` (the outputs are void; the pure path must decide).
    """
    n = x0.shape[0]
    m = z.shape[0]
    if not (_finite(x0) and _finite(P0) and _finite(z) and _finite(R)):
        return FALLBACK
    H = np.zeros((m, n))
    if ukf:
        L, ok = _chol(P0)
        if not ok:
            return FALLBACK
        lam = alpha * alpha * (n + kappa) - n
        c = n + lam
        sc = math.sqrt(c)
        ns = 2 * n + 1
        X = np.empty((ns, n))
        for j in range(n):
            X[0, j] = x0[j]
        for i in range(n):
            for j in range(n):
                dij = sc * L[j, i]
                X[1 + i, j] = x0[j] + dij
                X[1 + n + i, j] = x0[j] - dij
        wi = 1.0 / (2 * c)
        Wm = np.full(ns, wi)
        Wc = np.full(ns, wi)
        Wm[0] = lam / c
        Wc[0] = lam / c + (1 - alpha * alpha + beta)
        Y = _dd_h(X, p0, tx, base, i_tx, i_ref, amb, wl, corr, has_corr, sagnac, omega_e, clight)
        y = np.zeros(m)
        for s in range(ns):
            for i in range(m):
                y[i] += Wm[s] * Y[s, i]
        Pyy = np.zeros((m, m))
        Pxy = np.zeros((n, m))
        for s in range(ns):
            w = Wc[s]
            for i in range(m):
                a = (Y[s, i] - y[i]) * w
                for j in range(m):
                    Pyy[i, j] += a * (Y[s, j] - y[j])
            for i in range(n):
                a = (X[s, i] - x0[i]) * w
                for j in range(m):
                    Pxy[i, j] += a * (Y[s, j] - y[j])
        for i in range(m):
            for j in range(i + 1, m):
                t = 0.5 * (Pyy[i, j] + Pyy[j, i])
                Pyy[i, j] = t
                Pyy[j, i] = t
        # statistical linearisation H = Pxyᵀ P̄⁻¹
        HT, ok = _solve(P0, Pxy)
        if not ok:
            return FALLBACK
        for i in range(m):
            for j in range(n):
                H[i, j] = HT[j, i]
    else:
        px = x0[p0]
        py = x0[p0 + 1]
        pz = x0[p0 + 2]
        N = tx.shape[0]
        E = np.empty((N, 3))
        for t in range(N):
            dx = px - tx[t, 0]
            dy = py - tx[t, 1]
            dz = pz - tx[t, 2]
            nr = math.sqrt(dx * dx + dy * dy + dz * dz)
            E[t, 0] = dx / nr
            E[t, 1] = dy / nr
            E[t, 2] = dz / nr
        for i in range(m):
            for k in range(3):
                H[i, p0 + k] = E[i_tx[i], k] - E[i_ref[i], k]
            if amb[i] >= 0:
                H[i, amb[i]] = wl[i]
        Pxy = _mmt(P0, H)
        Pyy = _mm(H, Pxy)
        X1 = np.empty((1, n))
        X1[0, :] = x0
        y = _dd_h(X1, p0, tx, base, i_tx, i_ref, amb, wl, corr, has_corr, sagnac, omega_e, clight)[0]
    for i in range(m):
        d[i] = z[i] - y[i]
        for j in range(m):
            S[i, j] = Pyy[i, j] + R[i, j]
    for i in range(m):
        if not math.isfinite(d[i]) or not (S[i, i] > 0.0):
            return FALLBACK
    if not _finite(Pxy):
        return FALLBACK
    PyxT = np.empty((m, n))
    for i in range(m):
        for j in range(n):
            PyxT[i, j] = Pxy[j, i]
    KT, ok = _solve(S, PyxT)  # K = Pxy S⁻¹
    if not ok:
        return FALLBACK
    for i in range(n):
        acc = 0.0
        for j in range(m):
            acc += KT[j, i] * d[j]
        x[i] = x0[i] + acc
    K = np.empty((n, m))
    for i in range(n):
        for j in range(m):
            K[i, j] = KT[j, i]
    if ukf:
        KS = _mm(K, S)
        KSK = _mm(KS, KT)
        for i in range(n):
            for j in range(n):
                P[i, j] = P0[i, j] - KSK[i, j]
    else:
        IKH = _mm(K, H)
        for i in range(n):
            for j in range(n):
                IKH[i, j] = -IKH[i, j]
            IKH[i, i] += 1.0
        A = _mmt(_mm(IKH, P0), IKH)
        B = _mm(_mm(K, R), KT)
        for i in range(n):
            for j in range(n):
                P[i, j] = A[i, j] + B[i, j]
    for i in range(n):
        for j in range(i + 1, n):
            t = 0.5 * (P[i, j] + P[j, i])
            P[i, j] = t
            P[j, i] = t
        if not math.isfinite(x[i]):
            return FALLBACK
    if not _finite(P):
        return FALLBACK
    X1 = np.empty((1, n))
    X1[0, :] = x
    hx = _dd_h(X1, p0, tx, base, i_tx, i_ref, amb, wl, corr, has_corr, sagnac, omega_e, clight)
    for i in range(m):
        v[i] = z[i] - hx[0, i]
    HPH = _mmt(_mm(H, P), H)
    for i in range(m):
        for j in range(m):
            Cv[i, j] = R[i, j] - HPH[i, j]
    # nominal Cvv = R S⁻¹ R (symmetrised), standardized residuals and Δv̄
    SR, ok = _solve(S, R)
    if not ok:
        return FALLBACK
    cnt = 0
    tot = 0.0
    for i in range(m):
        cii = 0.0  # the diagonal of R S⁻¹ R (that of its symmetrised form)
        for q in range(m):
            cii += R[i, q] * SR[q, i]
        std[i] = np.nan
        if cii > 0.0 and cii > 1e-4 * R[i, i]:
            std[i] = v[i] / math.sqrt(cii)
            cnt += 1
            tot += abs(std[i])
    for i in range(m):
        dv[i] = np.nan
        s = std[i]
        if cnt >= 3 and math.isfinite(s):
            others = (tot - abs(s)) / (cnt - 1)
            if others > 0:
                dv[i] = s / others
            elif s == 0.0:
                dv[i] = 0.0
            else:
                dv[i] = math.copysign(math.inf, s)
    return OK


@_jit
def dd_update_into_k(
    x0: np.ndarray,
    P0: np.ndarray,
    z: np.ndarray,
    R: np.ndarray,
    p0: int,
    tx: np.ndarray,
    base: np.ndarray,
    i_tx: np.ndarray,
    i_ref: np.ndarray,
    amb: np.ndarray,
    wl: np.ndarray,
    corr: np.ndarray,
    has_corr: bool,
    sagnac: bool,
    omega_e: float,
    clight: float,
    ukf: bool,
    alpha: float,
    beta: float,
    kappa: float,
    out: np.ndarray,
) -> int:
    """:func:`dd_update_k` with its eight outputs in one flat buffer.

    ``out`` (``n + n² + 4m + 2m²``,) holds, in order, ``x`` (n), ``P`` (n·n, row-major),
    ``d`` (m), ``S`` (m·m), ``v`` (m), ``Cv`` (m·m), ``std`` (m) and ``dv`` (m): one
    argument instead of eight, since each array argument costs the call's dispatch
    about as much as the update of a few rows.
    """
    n = x0.shape[0]
    m = z.shape[0]
    o = 0
    x = out[o : o + n]
    o += n
    P = out[o : o + n * n].reshape((n, n))
    o += n * n
    d = out[o : o + m]
    o += m
    S = out[o : o + m * m].reshape((m, m))
    o += m * m
    v = out[o : o + m]
    o += m
    Cv = out[o : o + m * m].reshape((m, m))
    o += m * m
    std = out[o : o + m]
    o += m
    dv = out[o : o + m]
    return dd_update_k(
        x0, P0, z, R, p0, tx, base, i_tx, i_ref, amb, wl, corr, has_corr, sagnac, omega_e, clight,
        ukf, alpha, beta, kappa, x, P, d, S, v, Cv, std, dv,
    )  # fmt: skip
