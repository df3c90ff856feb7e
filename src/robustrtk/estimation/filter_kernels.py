"""Compiled (numba) measurement update of the EKF and UKF for DD range models.

One call does what :meth:`robustrtk.estimation.filters._KalmanBase.update` does for a
:class:`~robustrtk.measurement.dd.DDRangeModel`, no prior scaling and the standard
(non-robust) policy: linearisation (EKF Jacobian or UKF sigma points, algorithms.md §6),
the Kalman update, the posterior residuals and their covariance, the nominal ``Cvv = R S⁻¹ R``,
the standardized residuals and Δv̄ (algorithms.md §4). The equations are those of the module
docstring of :mod:`robustrtk.estimation.filters`; the pure path stays the reference (tests
compare both on random and simulated problems) and takes over whenever this kernel reports
anything but success (a non-finite input, a covariance that is not positive definite, a
singular system, inconsistent shapes or indices), so every refusal keeps its pure-path
diagnostics.

Two entry points run the same code: :func:`dd_update_k` takes the model's fields one by one,
:func:`dd_update_packed_k` (the filters' fast path) takes them packed in one float64 and one
int64 array (:attr:`~robustrtk.measurement.dd.DDRangeModel.kernel_args`, built once per model),
since each argument of a compiled call costs its dispatch about 0.1 µs, and writes its outputs
into two buffers whose rows are the result's arrays. Every temporary of the update lives in one
work array (:func:`work_size`; the caller passes it to the packed entry, which is compiled
without numba's runtime), and the helpers are inlined.

This module imports numba; :mod:`robustrtk.estimation.filters` imports it on the first
update that can use it (algorithms.md §22).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

OK = 0
FALLBACK = 1

#: Layout of the packed index array: position start, transmitters N, rows m, flags, then
#: ``i_tx`` (m), ``i_ref`` (m), ``amb_idx`` (m).
IDX_P0, IDX_N, IDX_M, IDX_HAS_CORR, IDX_SAGNAC, IDX_HEAD = 0, 1, 2, 3, 4, 5
#: Layout of the packed float array: ω (rad/s), c (m/s), then ``tx_pos_m`` (3N, row-major),
#: ``base_range_m`` (N), ``wavelength_m`` (m) and, with delays, ``tx_corr_m`` (N).
GEO_OMEGA, GEO_CLIGHT, GEO_HEAD = 0, 1, 2

_jit = nb.njit(cache=True, nogil=True, error_model="numpy")
#: The helpers are inlined into the update (numba IR inlining): a call passing a dozen array
#: views costs their reference counting, about a fifth of the update at 7 states.
_jit_inline = nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
#: The fast path's entry is compiled without numba's runtime (``_nrt=False``, numba's own
#: option for code that allocates nothing): its array arguments and views are not
#: reference-counted, which saves about 0.05 µs an array at the call alone and a fifth of
#: the update inside. The tests run it against the field-by-field entry, bit for bit.
_jit_bare = nb.njit(cache=True, nogil=True, error_model="numpy", _nrt=False)  # type: ignore[call-overload]


@_jit_inline
def work_size(n: int, m: int, N: int) -> int:
    """Length of the work array of an update with ``n`` states, ``m`` rows and ``N``
    transmitters: ``s (2n + 4s + 3) + 4N`` with ``s = n + m`` (it holds the sigma points and
    their h, ``(2n+1)(n+m)``, four n×n, eight n×m and four m×m blocks, ``4 (n+m)²``, and the
    vectors)."""
    s = n + m
    return s * (2 * n + 4 * s + 3) + 4 * N


@_jit_inline
def _chol_into(A: np.ndarray, L: np.ndarray) -> bool:
    """Lower Cholesky factor ``A = L Lᵀ`` into ``L`` (n, n; upper triangle zero); False when
    a pivot is not positive."""
    n = A.shape[0]
    for i in range(n):
        for j in range(n):
            L[i, j] = 0.0
    for j in range(n):
        s = A[j, j]
        for k in range(j):
            s -= L[j, k] * L[j, k]
        if not (s > 0.0) or not math.isfinite(s):
            return False
        L[j, j] = math.sqrt(s)
        for i in range(j + 1, n):
            t = A[i, j]
            for k in range(j):
                t -= L[i, k] * L[j, k]
            L[i, j] = t / L[j, j]
    return True


@_jit_inline
def _solve_into(A: np.ndarray, B: np.ndarray, M: np.ndarray, X: np.ndarray) -> bool:
    """``X = A⁻¹ B`` by LU with partial pivoting (``B``, ``X`` of shape (n, k); ``M`` (n, n)
    the elimination's copy of ``A``); False when singular."""
    n = A.shape[0]
    k = B.shape[1]
    for i in range(n):
        for j in range(n):
            M[i, j] = A[i, j]
        for j in range(k):
            X[i, j] = B[i, j]
    for c in range(n):
        p = c
        best = abs(M[c, c])
        for r in range(c + 1, n):
            if abs(M[r, c]) > best:
                best = abs(M[r, c])
                p = r
        if not (best > 0.0) or not math.isfinite(best):
            return False
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
    return True


@_jit_inline
def _ranges_into(
    px: float,
    py: float,
    pz: float,
    tx: np.ndarray,
    corr: np.ndarray,
    has_corr: bool,
    sagnac: bool,
    omega_e: float,
    clight: float,
    r: np.ndarray,
) -> None:
    """Rover ranges (N,) from the position ``(px, py, pz)`` into ``r`` (Sagnac term and
    delays included, as ``DDRangeModel.h``)."""
    for t in range(tx.shape[0]):
        dx = px - tx[t, 0]
        dy = py - tx[t, 1]
        dz = pz - tx[t, 2]
        rr = math.sqrt(dx * dx + dy * dy + dz * dz)
        if sagnac:
            rr = rr + omega_e * (tx[t, 0] * py - tx[t, 1] * px) / clight
        if has_corr:
            rr = rr + corr[t]
        r[t] = rr


@_jit_inline
def _dd_into(
    xs: np.ndarray,
    r: np.ndarray,
    base: np.ndarray,
    i_tx: np.ndarray,
    i_ref: np.ndarray,
    amb: np.ndarray,
    wl: np.ndarray,
    out: np.ndarray,
) -> None:
    """DD ranges ``h(xs)`` (m,) of the state ``xs`` (n,) whose rover ranges are ``r``."""
    for i in range(i_tx.shape[0]):
        v = (r[i_tx[i]] - r[i_ref[i]]) - (base[i_tx[i]] - base[i_ref[i]])
        if amb[i] >= 0:
            v = v + xs[amb[i]] * wl[i]
        out[i] = v


@_jit_inline
def _h_into(
    xs: np.ndarray,
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
    r: np.ndarray,
    out: np.ndarray,
) -> None:
    """DD ranges ``h(xs)`` (m,) of one state ``xs`` (n,) into ``out`` (``DDRangeModel.h``);
    ``r`` (N,) holds the rover ranges."""
    _ranges_into(xs[p0], xs[p0 + 1], xs[p0 + 2], tx, corr, has_corr, sagnac, omega_e, clight, r)
    _dd_into(xs, r, base, i_tx, i_ref, amb, wl, out)


@_jit_inline
def _mm_into(A: np.ndarray, B: np.ndarray, C: np.ndarray) -> None:
    """``C = A B`` by loops (faster than a BLAS call at these sizes)."""
    n, k = A.shape
    m = B.shape[1]
    for i in range(n):
        for j in range(m):
            C[i, j] = 0.0
    for i in range(n):
        for q in range(k):
            a = A[i, q]
            if a != 0.0:
                for j in range(m):
                    C[i, j] += a * B[q, j]


@_jit_inline
def _mmt_into(A: np.ndarray, B: np.ndarray, C: np.ndarray) -> None:
    """``C = A Bᵀ`` by loops."""
    n, k = A.shape
    m = B.shape[0]
    for i in range(n):
        for j in range(m):
            s = 0.0
            for q in range(k):
                s += A[i, q] * B[j, q]
            C[i, j] = s


@_jit_inline
def _finite2(a: np.ndarray) -> bool:
    for i in range(a.shape[0]):
        for j in range(a.shape[1]):
            if not math.isfinite(a[i, j]):
                return False
    return True


@_jit_inline
def _finite1(a: np.ndarray) -> bool:
    for i in range(a.shape[0]):
        if not math.isfinite(a[i]):
            return False
    return True


@_jit_inline
def _take(w: np.ndarray, o: int, rows: int, cols: int) -> np.ndarray:
    """The (rows, cols) block of the work array ``w`` at offset ``o``."""
    return w[o : o + rows * cols].reshape((rows, cols))


@_jit_inline
def _update(
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
    w: np.ndarray,
) -> int:
    """The update of :func:`dd_update_k` (same arguments), every temporary in the work array
    ``w`` (at least ``work_size(n, m, N)`` long)."""
    n = x0.shape[0]
    m = z.shape[0]
    N = tx.shape[0]
    # shapes and indices (the pure path raises or decides on anything else)
    if (
        P0.shape[0] != n or P0.shape[1] != n or R.shape[0] != m or R.shape[1] != m
        or i_tx.shape[0] != m or i_ref.shape[0] != m or amb.shape[0] != m or wl.shape[0] != m
        or tx.shape[1] != 3 or base.shape[0] != N or (has_corr and corr.shape[0] != N)
        or p0 < 0 or p0 + 3 > n or w.shape[0] < work_size(n, m, N)
    ):  # fmt: skip
        return FALLBACK
    for i in range(m):
        if not (0 <= i_tx[i] < N and 0 <= i_ref[i] < N and amb[i] < n):
            return FALLBACK
    if not (_finite1(x0) and _finite2(P0) and _finite1(z) and _finite2(R)):
        return FALLBACK
    ns = 2 * n + 1
    nn, nm, mm = n * n, n * m, m * m
    o = 0
    Y = _take(w, o, ns, m)
    o += ns * m
    r = w[o : o + N]
    o += N
    y = w[o : o + m]
    o += m
    Pyy = _take(w, o, m, m)
    o += mm
    Pxy = _take(w, o, n, m)
    o += nm
    H = _take(w, o, m, n)
    o += nm
    PyxT = _take(w, o, m, n)
    o += nm
    Ms = _take(w, o, m, m)
    o += mm
    KT = _take(w, o, m, n)
    o += nm
    K = _take(w, o, n, m)
    o += nm
    Mn = _take(w, o, n, n)  # LU of P̄ (UKF), (I − KH) P̄ (EKF)
    o += nn
    T1 = _take(w, o, n, n)  # chol P̄ (UKF), I − KH (EKF)
    o += nn
    T2 = _take(w, o, n, n)  # K S Kᵀ (UKF), the Joseph form's first term (EKF)
    o += nn
    T3 = _take(w, o, n, n)  # its second term (EKF)
    o += nn
    Tn = _take(w, o, n, m)  # Pxyᵀ P̄⁻¹ transposed (UKF), K S (UKF), K R (EKF)
    o += nm
    HP = _take(w, o, m, n)
    o += nm
    HPH = _take(w, o, m, m)
    o += mm
    SR = _take(w, o, m, m)
    o += mm
    hx = w[o : o + m]
    o += m
    xs = w[o : o + n]
    o += n
    X = _take(w, o, ns, n)  # sigma points (UKF)
    o += ns * n
    E = _take(w, o, N, 3)  # line-of-sight units (EKF)
    if ukf:
        L = T1
        if not _chol_into(P0, L):
            return FALLBACK
        lam = alpha * alpha * (n + kappa) - n
        c = n + lam
        sc = math.sqrt(c)
        for j in range(n):
            X[0, j] = x0[j]
        for i in range(n):
            for j in range(n):
                dij = sc * L[j, i]
                X[1 + i, j] = x0[j] + dij
                X[1 + n + i, j] = x0[j] - dij
        wi = 1.0 / (2 * c)
        w0m = lam / c
        w0c = lam / c + (1 - alpha * alpha + beta)
        # h of each sigma point; the rover ranges are recomputed only when the position
        # differs from the previous point's (the points along the ambiguity columns of
        # chol P̄ keep x̄'s position: the same ranges, bit for bit)
        qx = qy = qz = 0.0
        for s in range(ns):
            px = X[s, p0]
            py = X[s, p0 + 1]
            pz = X[s, p0 + 2]
            if s == 0 or not (px == qx and py == qy and pz == qz):
                _ranges_into(px, py, pz, tx, corr, has_corr, sagnac, omega_e, clight, r)
                qx, qy, qz = px, py, pz
            _dd_into(X[s], r, base, i_tx, i_ref, amb, wl, Y[s])
        for i in range(m):
            y[i] = 0.0
        for s in range(ns):
            ws = w0m if s == 0 else wi
            for i in range(m):
                y[i] += ws * Y[s, i]
        # deviations in place (Y ← Y − ŷ, X ← X − x̄), then Pyy and Pxy; a zero weight
        # deviation adds nothing (the sums start at +0 and ŷ is finite when the update is kept)
        for s in range(ns):
            for i in range(m):
                Y[s, i] = Y[s, i] - y[i]
            for i in range(n):
                X[s, i] = X[s, i] - x0[i]
        for i in range(m):
            for j in range(m):
                Pyy[i, j] = 0.0
        for i in range(n):
            for j in range(m):
                Pxy[i, j] = 0.0
        for s in range(ns):
            ws = w0c if s == 0 else wi
            for i in range(m):
                a = Y[s, i] * ws
                for j in range(m):
                    Pyy[i, j] += a * Y[s, j]
            for i in range(n):
                a = X[s, i] * ws
                if a != 0.0:
                    for j in range(m):
                        Pxy[i, j] += a * Y[s, j]
        for i in range(m):
            for j in range(i + 1, m):
                t = 0.5 * (Pyy[i, j] + Pyy[j, i])
                Pyy[i, j] = t
                Pyy[j, i] = t
        # statistical linearisation H = Pxyᵀ P̄⁻¹
        HT = Tn
        if not _solve_into(P0, Pxy, Mn, HT):
            return FALLBACK
        for i in range(m):
            for j in range(n):
                H[i, j] = HT[j, i]
    else:
        for i in range(m):
            for j in range(n):
                H[i, j] = 0.0
        px = x0[p0]
        py = x0[p0 + 1]
        pz = x0[p0 + 2]
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
        _mmt_into(P0, H, Pxy)
        _mm_into(H, Pxy, Pyy)
        _h_into(x0, p0, tx, base, i_tx, i_ref, amb, wl, corr, has_corr, sagnac, omega_e, clight, r, y)
    for i in range(m):
        d[i] = z[i] - y[i]
        for j in range(m):
            S[i, j] = Pyy[i, j] + R[i, j]
    for i in range(m):
        if not math.isfinite(d[i]) or not (S[i, i] > 0.0):
            return FALLBACK
    if not _finite2(Pxy):
        return FALLBACK
    for i in range(m):
        for j in range(n):
            PyxT[i, j] = Pxy[j, i]
    if not _solve_into(S, PyxT, Ms, KT):  # K = Pxy S⁻¹
        return FALLBACK
    for i in range(n):
        acc = 0.0
        for j in range(m):
            acc += KT[j, i] * d[j]
        x[i] = x0[i] + acc
    for i in range(n):
        for j in range(m):
            K[i, j] = KT[j, i]
    if ukf:
        _mm_into(K, S, Tn)
        _mm_into(Tn, KT, T2)
        for i in range(n):
            for j in range(n):
                P[i, j] = P0[i, j] - T2[i, j]
    else:
        IKH = T1
        _mm_into(K, H, IKH)
        for i in range(n):
            for j in range(n):
                IKH[i, j] = -IKH[i, j]
            IKH[i, i] += 1.0
        _mm_into(IKH, P0, Mn)
        _mmt_into(Mn, IKH, T2)
        _mm_into(K, R, Tn)
        _mm_into(Tn, KT, T3)
        for i in range(n):
            for j in range(n):
                P[i, j] = T2[i, j] + T3[i, j]
    for i in range(n):
        for j in range(i + 1, n):
            t = 0.5 * (P[i, j] + P[j, i])
            P[i, j] = t
            P[j, i] = t
        if not math.isfinite(x[i]):
            return FALLBACK
    if not _finite2(P):
        return FALLBACK
    for i in range(n):
        xs[i] = x[i]
    _h_into(xs, p0, tx, base, i_tx, i_ref, amb, wl, corr, has_corr, sagnac, omega_e, clight, r, hx)
    for i in range(m):
        v[i] = z[i] - hx[i]
    _mm_into(H, P, HP)
    _mmt_into(HP, H, HPH)
    for i in range(m):
        for j in range(m):
            Cv[i, j] = R[i, j] - HPH[i, j]
    # nominal Cvv = R S⁻¹ R (symmetrised), standardized residuals and Δv̄
    if not _solve_into(S, R, Ms, SR):
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
    w = np.empty(work_size(x0.shape[0], z.shape[0], tx.shape[0]))
    return _update(
        x0, P0, z, R, p0, tx, base, i_tx, i_ref, amb, wl, corr, has_corr, sagnac, omega_e, clight,
        ukf, alpha, beta, kappa, x, P, d, S, v, Cv, std, dv, w,
    )  # fmt: skip


@_jit_bare
def dd_update_packed_k(
    x0: np.ndarray,
    P0: np.ndarray,
    z: np.ndarray,
    R: np.ndarray,
    geo: np.ndarray,
    idx: np.ndarray,
    ukf: bool,
    alpha: float,
    beta: float,
    kappa: float,
    xP: np.ndarray,
    rows: np.ndarray,
    work: np.ndarray,
) -> int:
    """:func:`dd_update_k` with the model's fields packed and the outputs in two buffers.

    Parameters
    ----------
    x0, P0, z, R :
        As for :func:`dd_update_k`.
    geo : ndarray of float64
        ``[ω, c, tx_pos_m (3N), base_range_m (N), wavelength_m (m), tx_corr_m (N, if any)]``
        (the ``GEO_*`` offsets).
    idx : ndarray of int64
        ``[p0, N, m, has_corr, sagnac, i_tx (m), i_ref (m), amb_idx (m)]`` (the ``IDX_*``
        offsets).
    ukf, alpha, beta, kappa :
        As for :func:`dd_update_k`.
    xP : ndarray, shape (n + 1, n)
        Written: the posterior mean ``x`` (row 0) and covariance ``P`` (rows 1…n).
    rows : ndarray, shape (5 + 2m, m)
        Written, by rows: ``d``, ``v``, ``std``, ``dv``, the factors γ (all 1), then ``S``
        (m rows) and ``Cv`` (m rows). Rows and blocks of rows of C-ordered buffers are
        contiguous arrays that the caller gets without a reshape.
    work : ndarray, shape (≥ ``work_size(n, m, N)``,)
        Scratch (the caller allocates it: this entry is compiled without numba's runtime, so
        neither its arguments nor its views are reference-counted).

    Returns
    -------
    code : int
        ``OK`` or ``FALLBACK`` (also for a packing or buffers of the wrong size).
    """
    n = x0.shape[0]
    m = z.shape[0]
    if idx.shape[0] < IDX_HEAD:
        return FALLBACK
    p0 = idx[IDX_P0]
    N = idx[IDX_N]
    has_corr = idx[IDX_HAS_CORR] != 0
    if (
        idx[IDX_M] != m or N < 1 or idx.shape[0] != IDX_HEAD + 3 * m
        or geo.shape[0] != GEO_HEAD + 4 * N + m + (N if has_corr else 0)
        or xP.shape[0] != n + 1 or xP.shape[1] != n or rows.shape[0] != 5 + 2 * m or rows.shape[1] != m
    ):  # fmt: skip
        return FALLBACK
    i_tx = idx[IDX_HEAD : IDX_HEAD + m]
    i_ref = idx[IDX_HEAD + m : IDX_HEAD + 2 * m]
    amb = idx[IDX_HEAD + 2 * m : IDX_HEAD + 3 * m]
    g = GEO_HEAD
    tx = geo[g : g + 3 * N].reshape((N, 3))
    g += 3 * N
    base = geo[g : g + N]
    g += N
    wl = geo[g : g + m]
    g += m
    corr = geo[g : g + N] if has_corr else geo[g:g]
    for i in range(m):
        rows[4, i] = 1.0
    return _update(
        x0, P0, z, R, p0, tx, base, i_tx, i_ref, amb, wl, corr, has_corr, idx[IDX_SAGNAC] != 0,
        geo[GEO_OMEGA], geo[GEO_CLIGHT], ukf, alpha, beta, kappa, xP[0], xP[1:], rows[0],
        rows[5 : 5 + m], rows[1], rows[5 + m :], rows[2], rows[3], work,
    )  # fmt: skip
