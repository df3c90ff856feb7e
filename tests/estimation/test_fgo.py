"""Robust batch least squares: plain least squares on a linear problem, and an outlier switched off."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from robustrtk.estimation.fgo import FactorGroup, Linearized, robust_batch_solve


def _linear(A: np.ndarray, z: np.ndarray, sigma: np.ndarray) -> FactorGroup:
    J = sp.csr_matrix(A)
    return FactorGroup("rows", "igg3", lambda x: Linearized(z - A @ x, sigma, J))


def test_plain_solution_is_weighted_least_squares() -> None:
    rng = np.random.default_rng(0)
    A = rng.normal(size=(40, 6))
    z = rng.normal(size=40)
    sigma = rng.uniform(0.5, 2.0, size=40)
    J2 = sp.csr_matrix(np.eye(6)[:2])
    prior = FactorGroup("prior", "none", lambda x: Linearized(-x[:2], np.ones(2), J2))
    res = robust_batch_solve([_linear(A, z, sigma), prior], np.zeros(6), robust=False)
    Aw = np.vstack([A / sigma[:, None], np.eye(6)[:2]])
    zw = np.concatenate([z / sigma, np.zeros(2)])
    ref = np.linalg.lstsq(Aw, zw, rcond=None)[0]
    np.testing.assert_allclose(res.x, ref, atol=1e-9)
    assert res.converged and res.iterations <= 2


def test_an_outlier_is_switched_off() -> None:
    """A line through 30 points with 0.1 noise and one 200σ error: the error ends with weight
    0, the others keep theirs, and the fit is the clean one."""
    rng = np.random.default_rng(1)
    t = np.linspace(0.0, 1.0, 30)
    A = np.column_stack([np.ones_like(t), t])
    z = A @ np.array([2.0, -1.0]) + rng.normal(scale=0.1, size=30)
    z[17] += 20.0
    sigma = np.full(30, 0.1)
    res = robust_batch_solve([_linear(A, z, sigma)], np.zeros(2))
    w = res.weights["rows"]
    assert w[17] == 0.0
    assert np.sum(w == 0.0) <= 2
    clean = np.delete(np.arange(30), 17)
    ref = np.linalg.lstsq(A[clean], z[clean], rcond=None)[0]
    np.testing.assert_allclose(res.x, ref, atol=0.05)
    plain = robust_batch_solve([_linear(A, z, sigma)], np.zeros(2), robust=False)
    assert np.linalg.norm(plain.x - ref) > 5 * np.linalg.norm(res.x - ref)
