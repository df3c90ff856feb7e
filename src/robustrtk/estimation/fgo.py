"""Robust batch least squares over a whole track (a factor graph solved as one sparse problem).

The unknowns ``x`` (length ``n``) are every epoch's states at once. Each factor group ``g``
contributes rows ``r_g(x) = z_g − h_g(x)`` with standard deviations ``σ_g`` and a sparse
Jacobian ``J_g = ∂h_g/∂x``; the solver minimises (docs/algorithms.md §36)::

    Σ_g Σ_i w_g,i (r_g,i / σ_g,i)²

by Gauss–Newton: at the current ``x``, ``(Aᵀ A) δ = Aᵀ b`` with ``A`` the rows of ``J``
scaled by ``√w / σ`` and ``b`` the scaled residuals, solved as one sparse system
(:func:`scipy.sparse.linalg.spsolve`; the normal matrix of a track is banded, a few dozen
wide, so the factorisation is linear in the track length), until the largest step is below
``tol`` (ten times ``tol`` in the Huber stage), or ``max_iter`` per stage. The weights are
re-computed from the standardised residuals ``u = r/σ`` at every iteration (iteratively
reweighted least squares) with the group's kernel: first Huber (``γ = |u|/k0`` beyond
``k0``: convex, so the first stage converges from any start to its one minimum), then
IGG-III from there (``γ`` of :func:`robustrtk.estimation.robust.igg3_factor`: rows beyond ``k1``
get weight 0; a row rejected at two iterations in a row is switched off for good — it stays
inconsistent with the track the others define — which also ends the back-and-forth of rows
on the threshold that keeps a redescending IRLS from settling). A group with kernel
``"none"`` keeps weight 1 (priors whose σ is the model), ``"huber"`` stays with Huber in the
second stage.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from robustrtk.core import FloatArray
from robustrtk.estimation.robust import huber_factor, igg3_factor

Kernel = Literal["igg3", "huber", "none"]


@dataclass(frozen=True)
class Linearized:
    """One group's rows at the current point.

    Attributes
    ----------
    r : ndarray, shape (m,)
        Residuals ``z − h(x)``.
    sigma : ndarray, shape (m,)
        Standard deviations (same unit as ``r``).
    J : scipy.sparse matrix, shape (m, n)
        ``∂h/∂x``.
    """

    r: FloatArray
    sigma: FloatArray
    J: sp.csr_matrix


@dataclass(frozen=True)
class FactorGroup:
    """A named set of rows with one robust kernel and a function linearising them at ``x``."""

    name: str
    kernel: Kernel
    linearize: Callable[[FloatArray], Linearized]


@dataclass
class BatchResult:
    """Outcome of :func:`robust_batch_solve`.

    Attributes
    ----------
    x : ndarray, shape (n,)
    weights : dict str -> ndarray
        Final weight ``1/γ`` of every row per group (0 = switched off).
    std_residual : dict str -> ndarray
        Final ``r/σ`` per group.
    iterations : int
        Gauss–Newton iterations over both stages.
    converged : bool
    normal : scipy.sparse matrix, shape (n, n)
        ``Aᵀ A`` at the solution (the information matrix under the final weights).
    """

    x: FloatArray
    weights: dict[str, FloatArray] = field(default_factory=dict)
    std_residual: dict[str, FloatArray] = field(default_factory=dict)
    iterations: int = 0
    converged: bool = False
    normal: sp.csc_matrix | None = None


def _weights(u: FloatArray, kernel: Kernel, stage: int, k0: float, k1: float) -> FloatArray:
    if kernel == "none":
        return np.ones_like(u)
    if kernel == "huber" or stage == 0:
        g = huber_factor(u, k0)
    else:
        g = igg3_factor(u, k0, k1)
    with np.errstate(divide="ignore"):
        return np.where(np.isinf(g), 0.0, 1.0 / g)


def robust_batch_solve(
    groups: Sequence[FactorGroup],
    x0: FloatArray,
    *,
    k0: float = 1.5,
    k1: float = 3.0,
    tol: float = 1e-3,
    max_iter: int = 20,
    settle: float = 1e-3,
    robust: bool = True,
    ordering: str = "COLAMD",
) -> BatchResult:
    """Minimise the weighted sum of squares of ``groups`` from ``x0`` (module docstring).

    Parameters
    ----------
    groups : sequence of FactorGroup
    x0 : ndarray, shape (n,)
    k0, k1 : float
        Kernel thresholds on ``|r/σ|`` (Huber uses ``k0``).
    tol : float
        Convergence: the largest ``|δ|`` of an iteration (units of ``x``) below ``tol`` ...
    settle : float
        ... and at most this fraction of the rows changed weight by more than 0.01 (a few
        rows on an IGG-III threshold may flip back and forth forever).
    max_iter : int
        Iterations per stage.
    robust : bool
        False: plain Gauss–Newton least squares (every weight 1).
    ordering : str
        SuperLU's column ordering of the normal matrix: ``"COLAMD"`` (``spsolve``'s default),
        or ``"MMD_AT_PLUS_A"``: minimum degree on ``N + Nᵀ`` with diagonal pivots, the
        symmetric positive definite factorisation, for problems where unknowns couple many
        epochs.

    Returns
    -------
    BatchResult
    """
    x = np.asarray(x0, float).copy()
    n = x.size
    stages = (0, 1) if robust else (-1,)
    total = 0
    converged = False
    w_prev: dict[str, FloatArray] = {}
    off_count: dict[str, np.ndarray] = {}
    switched: dict[str, np.ndarray] = {}
    N = sp.csc_matrix((n, n))
    for stage in stages:
        converged = False
        for _ in range(max_iter):
            lin = [g.linearize(x) for g in groups]
            blocks, rhs = [], []
            changed, rows = 0, 0
            for g, li in zip(groups, lin, strict=True):
                u = li.r / li.sigma
                w = np.ones_like(u) if stage < 0 else _weights(u, g.kernel, stage, k0, k1)
                old = w_prev.get(g.name)
                if stage == 1 and old is not None and old.shape == w.shape:
                    # a row rejected at two iterations in a row stays switched off
                    off = off_count.setdefault(g.name, np.zeros(w.size, int))
                    off[:] = np.where(w == 0.0, off + 1, 0)
                    gone = switched.setdefault(g.name, np.zeros(w.size, bool))
                    gone |= off >= 2
                    w[gone] = 0.0
                rows += w.size
                changed += (
                    w.size if old is None or old.shape != w.shape else int(np.sum(np.abs(w - old) > 0.01))
                )
                w_prev[g.name] = w
                s = np.sqrt(w) / li.sigma
                blocks.append(sp.diags(s) @ li.J)
                rhs.append(s * li.r)
            A = sp.vstack(blocks, format="csr")
            b = np.concatenate(rhs)
            N = (A.T @ A).tocsc()
            if ordering == "COLAMD":
                dx = spla.spsolve(N, A.T @ b, permc_spec=ordering)
            else:
                lu = spla.splu(N, permc_spec=ordering, diag_pivot_thresh=0.0, options={"SymmetricMode": True})
                dx = lu.solve(A.T @ b)
            x = x + dx
            total += 1
            if float(np.max(np.abs(dx))) < (tol if stage != 0 else 10 * tol) and changed <= settle * rows:
                converged = True
                break
    out = BatchResult(x=x, iterations=total, converged=converged, normal=N)
    for g in groups:
        li = g.linearize(x)
        out.std_residual[g.name] = li.r / li.sigma
        out.weights[g.name] = w_prev.get(g.name, np.ones_like(li.r))
    return out


__all__ = ["BatchResult", "FactorGroup", "Kernel", "Linearized", "robust_batch_solve"]
