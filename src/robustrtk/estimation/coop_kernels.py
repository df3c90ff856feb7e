"""Compiled (numba) kernels of the cooperative augmented UKF (algorithms.md §21, §26).

:func:`ukf_predict` and :func:`ukf_update` do, operation for operation, what the numpy
path of :func:`robustrtk.estimation.coop.augmented_ukf_predict` and
:meth:`robustrtk.estimation.coop.KalmanNode.update` do (Zhou et al. eqs. 14–19): sigma
points ``x ± √c Lᵢ`` of the lower Cholesky factor, weights ``Wm, Wc``, pseudorange rows
``|s − p| + ω_e (s_x p_y − s_y p_x)/c + b`` and peer rows ``|p − p̂|`` evaluated by the
expansion ``|a'|² − 2 a'·p' + |p'|²`` about the first sigma point, ``S = Σ Wc dY dYᵀ + R``,
``K = P_xy S⁻¹`` (Cholesky solve), ``P⁺ = P − K S Kᵀ`` symmetrised. Tests compare both
with a plain reference (tests/estimation/test_coop_ukf_fast.py).

Imported lazily (on the first UKF step) so that start-up never pays numba's import;
compiled once per machine and cached on disk. Errors come back as codes: ``OK = 0``,
``NOT_PD = 1`` (a covariance, or ``S``, is not positive definite: the caller falls back to
the numpy path, which jitters or solves generally), ``NONFINITE = 2`` (the posterior is
not finite: the step is refused).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

OK = 0
NOT_PD = 1
NONFINITE = 2

_jit = nb.njit(cache=True, nogil=True, error_model="numpy")


@_jit
def _chol(A: np.ndarray, L: np.ndarray) -> bool:  # pragma: no cover - compiled
    """Lower Cholesky factor of ``A`` (lower triangle read) into ``L``; False if not PD."""
    n = A.shape[0]
    for j in range(n):
        s = A[j, j]
        for k in range(j):
            s -= L[j, k] * L[j, k]
        if not s > 0.0:
            return False
        d = math.sqrt(s)
        L[j, j] = d
        for i in range(j + 1, n):
            t = A[i, j]
            for k in range(j):
                t -= L[i, k] * L[j, k]
            L[i, j] = t / d
        for i in range(j):
            L[i, j] = 0.0
    return True


@_jit
def ukf_predict(
    x: np.ndarray,
    P: np.ndarray,
    F: np.ndarray,
    W: np.ndarray,
    Qw: np.ndarray,
    Wm: np.ndarray,
    Wc: np.ndarray,
    sqrt_c: float,
    x_out: np.ndarray,
    P_out: np.ndarray,
) -> int:  # pragma: no cover - compiled
    """Augmented time update (eqs. 14–17) into ``x_out`` (n,), ``P_out`` (n, n)."""
    n = x.shape[0]
    Lp = np.zeros((n, n))
    Lq = np.zeros((n, n))
    if not _chol(P, Lp) or not _chol(Qw, Lq):
        return NOT_PD
    k_pts = 4 * n + 1
    Xp = np.empty((k_pts, n))
    chi = np.empty(n)
    for r in range(k_pts):
        # χ_x, χ_w of the sigma point r (see augmented_ukf_predict)
        for i in range(n):
            chi[i] = x[i]
        if 1 <= r <= n:
            for i in range(n):
                chi[i] = x[i] + sqrt_c * Lp[i, r - 1]
        elif 2 * n + 1 <= r <= 3 * n:
            for i in range(n):
                chi[i] = x[i] - sqrt_c * Lp[i, r - 2 * n - 1]
        for i in range(n):
            s = 0.0
            for j in range(n):
                s += chi[j] * F[i, j]
            Xp[r, i] = s
        if n + 1 <= r <= 2 * n:
            c = r - n - 1
            for i in range(n):
                s = 0.0
                for j in range(n):
                    s += sqrt_c * Lq[j, c] * W[i, j]
                Xp[r, i] += s
        elif 3 * n + 1 <= r:
            c = r - 3 * n - 1
            for i in range(n):
                s = 0.0
                for j in range(n):
                    s += -(sqrt_c * Lq[j, c]) * W[i, j]
                Xp[r, i] += s
    for i in range(n):
        s = 0.0
        for r in range(k_pts):
            s += Wm[r] * Xp[r, i]
        x_out[i] = s
    for i in range(n):
        for j in range(i, n):
            s = 0.0
            for r in range(k_pts):
                s += Wc[r] * (Xp[r, i] - x_out[i]) * (Xp[r, j] - x_out[j])
            P_out[i, j] = s
            P_out[j, i] = s
    return OK


@_jit
def ukf_update(
    x: np.ndarray,
    P: np.ndarray,
    anchors: np.ndarray,
    clk: np.ndarray,
    sagnac: float,
    z: np.ndarray,
    var: np.ndarray,
    pos_start: int,
    Wm: np.ndarray,
    Wc: np.ndarray,
    sqrt_c: float,
    x_out: np.ndarray,
    P_out: np.ndarray,
    d_out: np.ndarray,
) -> int:  # pragma: no cover - compiled
    """UKF correction (eqs. 18–19) on pseudorange / peer rows.

    ``anchors`` (m, 3) satellites and peers (m); ``clk`` (m,) the clock index of a
    pseudorange row, −1 for a peer row; ``sagnac`` ``ω_e/c`` (1/m·m, i.e. rad/s over m/s);
    ``var`` (m,) the diagonal of ``R`` (m²). Returns ``NONFINITE`` when the posterior is
    not finite.
    """
    n = x.shape[0]
    m = z.shape[0]
    k_pts = 2 * n + 1
    L = np.zeros((n, n))
    if not _chol(P, L):
        return NOT_PD
    X = np.empty((k_pts, n))
    for i in range(n):
        X[0, i] = x[i]
    for c in range(n):
        for i in range(n):
            D = sqrt_c * L[i, c]
            X[1 + c, i] = x[i] + D
            X[1 + n + c, i] = x[i] - D
    c0 = X[0, pos_start]
    c1 = X[0, pos_start + 1]
    c2 = X[0, pos_start + 2]
    Y = np.empty((k_pts, m))
    for j in range(m):
        a0 = anchors[j, 0] - c0
        a1 = anchors[j, 1] - c1
        a2 = anchors[j, 2] - c2
        aa = a0 * a0 + a1 * a1 + a2 * a2
        for r in range(k_pts):
            px = X[r, pos_start]
            py = X[r, pos_start + 1]
            p0 = px - c0
            p1 = py - c1
            p2 = X[r, pos_start + 2] - c2
            r2 = aa - 2.0 * (p0 * a0 + p1 * a1 + p2 * a2) + (p0 * p0 + p1 * p1 + p2 * p2)
            v = math.sqrt(max(r2, 0.0))
            if clk[j] >= 0:
                v += px * (sagnac * -anchors[j, 1]) + py * (sagnac * anchors[j, 0])
                v += X[r, clk[j]]
            Y[r, j] = v
    y = np.zeros(m)
    for j in range(m):
        s = 0.0
        for r in range(k_pts):
            s += Wm[r] * Y[r, j]
        y[j] = s
    for r in range(k_pts):
        for j in range(m):
            Y[r, j] -= y[j]  # dY
    S = np.empty((m, m))
    for i in range(m):
        for j in range(i, m):
            s = 0.0
            for r in range(k_pts):
                s += Y[r, i] * Wc[r] * Y[r, j]
            S[i, j] = s
            S[j, i] = s
        S[i, i] += var[i]
    Pxy = np.empty((n, m))
    for i in range(n):
        for j in range(m):
            s = 0.0
            for r in range(k_pts):
                s += (X[r, i] - x[i]) * Wc[r] * Y[r, j]
            Pxy[i, j] = s
    Ls = np.zeros((m, m))
    if not _chol(S, Ls):
        return NOT_PD
    # Kᵀ = S⁻¹ P_xyᵀ by forward and back substitution
    Kt = np.empty((m, n))
    for c in range(n):
        for i in range(m):
            t = Pxy[c, i]
            for k in range(i):
                t -= Ls[i, k] * Kt[k, c]
            Kt[i, c] = t / Ls[i, i]
        for i in range(m - 1, -1, -1):
            t = Kt[i, c]
            for k in range(i + 1, m):
                t -= Ls[k, i] * Kt[k, c]
            Kt[i, c] = t / Ls[i, i]
    for j in range(m):
        d_out[j] = z[j] - y[j]
    for i in range(n):
        s = 0.0
        for j in range(m):
            s += Kt[j, i] * d_out[j]
        x_out[i] = x[i] + s
    # P⁺ = P − (K S) Kᵀ as the numpy path computes it, symmetrised
    KS = np.empty((n, m))
    for i in range(n):
        for j in range(m):
            s = 0.0
            for k in range(m):
                s += Kt[k, i] * S[k, j]
            KS[i, j] = s
    KSK = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            s = 0.0
            for k in range(m):
                s += KS[i, k] * Kt[k, j]
            KSK[i, j] = s
    for i in range(n):
        for j in range(i, n):
            v = 0.5 * ((P[i, j] - KSK[i, j]) + (P[j, i] - KSK[j, i]))
            P_out[i, j] = v
            P_out[j, i] = v
            if not math.isfinite(v):
                return NONFINITE
        if not math.isfinite(x_out[i]):
            return NONFINITE
    return OK
