"""Array kernels of the Gaussian state operations (no layout, no state objects).

:class:`robustrtk.estimation.state.GaussianState` exposes these as methods; they are kept
here as plain functions so that other packages (ambiguity resolution) can apply them to
bare ``(x, P)`` pairs with exactly the same numbers.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from robustrtk.core import FloatArray, identity

F64 = npt.NDArray[np.float64]


def linear_transform(T: npt.ArrayLike, x: FloatArray, P: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Image of ``N(x, P)`` under the linear map ``T``.

    Parameters
    ----------
    T : array_like, shape (k, n)
    x : ndarray, shape (n,)
    P : ndarray, shape (n, n)

    Returns
    -------
    x_t : ndarray, shape (k,)
        ``T x``.
    P_t : ndarray, shape (k, k)
        ``(T P Tᵀ + (T P Tᵀ)ᵀ)/2``.
    """
    Tm = np.asarray(T, dtype=np.float64)
    if Tm.ndim != 2 or Tm.shape[1] != x.shape[0]:
        raise ValueError(f"T has shape {Tm.shape}, expected (k, {x.shape[0]})")
    M = Tm @ P @ Tm.T
    return Tm @ x, 0.5 * (M + M.T)


def cholesky_solve(L: FloatArray, B: npt.ArrayLike) -> F64:
    """Solve ``L Lᵀ X = B`` given the lower Cholesky factor ``L``.

    Parameters
    ----------
    L : ndarray, shape (m, m)
        Lower-triangular factor with a positive diagonal (``np.linalg.cholesky``).
    B : array_like, shape (m,) or (m, r)
        Right-hand side(s).

    Returns
    -------
    X : ndarray, same shape as ``B``
        ``(L Lᵀ)⁻¹ B`` by forward substitution ``L y = B`` then back substitution ``Lᵀ X = y``.

    Notes
    -----
    Two LAPACK solves (``numpy.linalg.solve`` on ``L`` and on ``Lᵀ``; partial pivoting
    leaves a triangular system's rows in place unless an off-diagonal entry dominates,
    and is stable either way). No scipy import on the solve path (algorithms.md §18).
    """
    Lm = np.asarray(L, dtype=np.float64)
    Y = np.asarray(B, dtype=np.float64)
    m = Lm.shape[0]
    if Lm.shape != (m, m) or Y.shape[0] != m:
        raise ValueError(f"L has shape {Lm.shape} and B {Y.shape}; expected (m, m) and (m, ...)")
    if m == 0:
        return Y.copy()
    return np.linalg.solve(Lm.T, np.linalg.solve(Lm, Y))


def condition_on(
    x: npt.ArrayLike,
    P: npt.ArrayLike,
    idx_fixed: npt.ArrayLike,
    values: npt.ArrayLike,
) -> tuple[F64, F64]:
    """Condition a Gaussian ``N(x, P)`` on ``x[f] = values`` exactly.

    Parameters
    ----------
    x : array_like, shape (k,)
        State mean (e.g. baseline in m and ambiguities in cycles).
    P : array_like, shape (k, k)
        State covariance.
    idx_fixed : array_like of int, shape (m,)
        Indices ``f`` of the fixed components (distinct).
    values : array_like, shape (m,)
        Their fixed values.

    Returns
    -------
    x_c : ndarray, shape (k,)
        ``x − P[:, f] P[f, f]⁻¹ (x[f] − values)``; ``x_c[f] = values`` exactly.
    P_c : ndarray, shape (k, k)
        ``P − P[:, f] P[f, f]⁻¹ P[f, :]``, symmetrised; rows and columns ``f`` are 0.

    Raises
    ------
    ValueError
        Shapes do not match, indices repeat or are out of range, or ``P[f, f]`` is not
        positive definite.

    Notes
    -----
    Li et al. (2019) eqs. 16–19 (algorithms.md §8) written for the whole state at once,
    so the baseline and the unfixed ambiguities are updated together. ``P[f, f]`` is
    checked positive definite by its Cholesky factorisation and ``P[f, f]⁻¹`` applied
    by one LAPACK solve.
    """
    xv = np.asarray(x, dtype=np.float64).reshape(-1)
    Pm = np.asarray(P, dtype=np.float64)
    k = xv.shape[0]
    if Pm.shape != (k, k):
        raise ValueError(f"P has shape {Pm.shape}, expected ({k}, {k})")
    f = np.asarray(idx_fixed, dtype=np.int64).reshape(-1)
    v = np.asarray(values, dtype=np.float64).reshape(-1)
    if f.shape != v.shape:
        raise ValueError("idx_fixed and values must have the same length")
    if f.shape[0] == 0:
        return xv.copy(), Pm.copy()
    fl = f.tolist()
    if min(fl) < 0 or max(fl) >= k or len(set(fl)) != len(fl):
        raise ValueError("idx_fixed must hold distinct indices in [0, len(x))")
    Pf = Pm[f[:, None], f]  # Pm[f][:, f]
    Pff = 0.5 * (Pf + Pf.T)
    if not np.isfinite(Pff).all():
        raise ValueError("P[f, f] must be finite")
    try:
        L = np.linalg.cholesky(Pff)
    except np.linalg.LinAlgError as err:
        raise ValueError("P[f, f] is not positive definite") from err
    Pxf = Pm[:, f]
    del L  # the factorisation checked positive definiteness; one LU solve of the block
    # serves both right-hand sides [x[f] − values, P[f, :]] (LAPACK, as fast as two
    # triangular solves through numpy, which has no triangular solver)
    W = np.linalg.solve(Pff, np.column_stack([xv[f] - v, Pxf.T]))
    x_c = xv - Pxf @ W[:, 0]
    P_c = Pm - Pxf @ W[:, 1:]
    P_c = 0.5 * (P_c + P_c.T)
    x_c[f] = v
    P_c[f, :] = 0.0
    P_c[:, f] = 0.0
    return x_c, P_c


def pseudo_observation_update(
    x: FloatArray,
    P: FloatArray,
    idx: npt.ArrayLike,
    values: npt.ArrayLike,
    sigma: float | npt.ArrayLike,
) -> tuple[FloatArray, FloatArray]:
    """Kalman update with the pseudo-observations ``z = x[idx] = values``, ``σ`` each.

    Parameters
    ----------
    x : ndarray, shape (n,)
    P : ndarray, shape (n, n)
    idx : array_like of int, shape (m,)
        Constrained components.
    values : array_like, shape (m,)
        Their observed values.
    sigma : float or array_like, shape (m,)
        Standard deviation of each pseudo-observation (units of the state).

    Returns
    -------
    x⁺ : ndarray, shape (n,)
        ``x + K (z − H x)``, ``K = P Hᵀ (H P Hᵀ + R)⁻¹``, ``H = I[idx]``,
        ``R = σ² I`` (``diag σ²`` for a vector).
    P⁺ : ndarray, shape (n, n)
        Joseph form ``(I − K H) P (I − K H)ᵀ + K R Kᵀ``, symmetrised.

    Notes
    -----
    The operations are those of the EKF update with a
    :class:`~robustrtk.estimation.models.LinearMeasurement` and no robust policy, in the
    same order, so the result is bit-identical to
    ``EKF().update(state, LinearMeasurement(H, values, R)).state``.
    """
    ii = np.asarray(idx, dtype=int).reshape(-1)
    m = ii.size
    n = x.shape[0]
    if m == 0:
        return x, P
    H = np.zeros((m, n))
    H[np.arange(m), ii] = 1.0
    z = np.asarray(values, float)
    sg = np.asarray(sigma, float)
    R = identity(m) * sg**2 if sg.ndim == 0 else np.diag(sg.reshape(m) ** 2)
    PHt = P @ H.T
    y_hat = x @ H.T
    Pyy0 = H @ PHt
    d = z - y_hat
    # the filter's factors are all 1 and every row is kept: R̄ = R and the row selections
    # are the whole arrays (the same numbers without their copies)
    Sk = Pyy0 + R
    K = np.linalg.solve(Sk, PHt.T).T
    x_new = x + K @ d
    IKH = identity(n) - K @ H
    P_new = IKH @ P @ IKH.T + K @ R @ K.T
    return x_new, 0.5 * (P_new + P_new.T)


__all__ = ["cholesky_solve", "condition_on", "linear_transform", "pseudo_observation_update"]
