"""Validation of integer ambiguity candidates: ratio test and fixed-failure-rate ratio test.

Both tests use the squared norms ``s1 ≤ s2`` of the best and second-best ILS candidates
(:func:`robustrtk.ambiguity.lambda_.lambda_search`) and the RTKLIB convention
``ratio = s2 / s1`` (accept when ``ratio ≥ threshold``; ``threshold ≥ 1``).

The fixed-failure-rate ratio test (FFRT, Teunissen & Verhagen 2009) chooses the threshold
so that the probability of accepting a *wrong* integer solution stays below ``pf``. Its
threshold depends on the model (n and the geometry of ``Qz``), so it is computed here by a
Monte Carlo over the model's own decorrelated covariance rather than from a published
look-up table: see :func:`ffrt_threshold`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from robustrtk.ambiguity.lambda_ import ltdl, reduce_ops, search

FloatArray = npt.NDArray[np.float64]

__all__ = ["RatioTest", "ffrt_threshold", "ratio_of", "ratio_test"]

#: RTKLIB's default ratio threshold.
DEFAULT_RATIO_THRESHOLD = 3.0


@dataclass(frozen=True)
class RatioTest:
    """Outcome of a ratio test.

    Attributes
    ----------
    ratio : float
        ``s2 / s1`` (``inf`` when ``s1 == 0`` and ``s2 > 0``).
    threshold : float
        Threshold used (fixed, or the FFRT value).
    accepted : bool
        ``ratio ≥ threshold``.
    """

    ratio: float
    threshold: float
    accepted: bool


def ratio_of(s: npt.ArrayLike) -> float:
    """Ratio ``s2 / s1`` of the two smallest squared norms.

    Parameters
    ----------
    s : array_like, shape (2,) or longer
        Squared norms, ascending.

    Returns
    -------
    float
        ``s[1] / s[0]``; ``inf`` if ``s[0] == 0 < s[1]``; ``1`` if both are zero.
    """
    sv = np.asarray(s, dtype=np.float64).reshape(-1)
    if sv.shape[0] < 2:
        raise ValueError("the ratio test needs the two best squared norms")
    s1, s2 = float(sv[0]), float(sv[1])
    if s1 > 0.0:
        return s2 / s1
    return math.inf if s2 > 0.0 else 1.0


def ratio_test(s: npt.ArrayLike, threshold: float = DEFAULT_RATIO_THRESHOLD) -> RatioTest:
    """Classic ratio test: accept the best candidate when ``s2 / s1 ≥ threshold``.

    Parameters
    ----------
    s : array_like, shape (2,)
        Best and second-best squared norms (ascending).
    threshold : float
        Critical value (≥ 1); 3.0 is RTKLIB's default.

    Returns
    -------
    RatioTest
    """
    if not threshold >= 1.0:
        raise ValueError(f"ratio threshold must be >= 1, got {threshold}")
    r = ratio_of(s)
    return RatioTest(ratio=r, threshold=float(threshold), accepted=bool(r >= threshold))


def ffrt_threshold(
    Q: npt.ArrayLike,
    pf: float = 1e-3,
    rng: np.random.Generator | None = None,
    n_samples: int = 2000,
    max_threshold: float = 1e6,
) -> float:
    """Fixed-failure-rate ratio threshold by Monte Carlo over the model's own ``Qz``.

    Parameters
    ----------
    Q : array_like, shape (n, n)
        Covariance of the float ambiguities (cycles²).
    pf : float
        Tolerated failure rate ``P(accept ∧ wrong)``, in (0, 1).
    rng : numpy.random.Generator
        Random source (required; injected for reproducibility).
    n_samples : int
        Monte Carlo sample size. The estimate of ``P(accept ∧ wrong)`` resolves
        rates down to about ``10 / n_samples``; for ``pf = 1e-3`` use ≥ 10 000 for a
        stable value (the default is a compromise for per-epoch use).
    max_threshold : float
        Returned when no sampled threshold reaches ``pf`` (no candidate accepted).

    Returns
    -------
    float
        The smallest ``μ ≥ 1`` (on ``ratio = s2/s1``) with
        ``#{wrong ∧ ratio ≥ μ} / n_samples ≤ pf``.

    Notes
    -----
    Float ambiguities are drawn as ``ẑ = Lᵀ diag(√d) w`` with ``w ~ N(0, I)`` in the
    decorrelated space (``Qz = Lᵀ diag(d) L``, true integer vector 0; ILS pull-in regions
    are integer-translation invariant, so the true value is immaterial). Each draw is
    solved by ILS; a draw *fails* when its best candidate is not 0. The threshold is
    the smallest ratio that leaves at most ``⌊pf · n_samples⌋`` failures accepted. This
    replaces the published FFRT look-up tables (Verhagen & Teunissen 2013) by the same
    definition evaluated on the actual model.
    """
    if rng is None:
        raise ValueError("ffrt_threshold needs an injected numpy.random.Generator")
    if not 0.0 < pf < 1.0:
        raise ValueError(f"pf must be in (0, 1), got {pf}")
    if n_samples < 1:
        raise ValueError("n_samples must be positive")
    L0, d0 = ltdl(Q)
    _, L, d = reduce_ops(L0, d0, full=False)
    n = d.shape[0]
    W = rng.standard_normal((n_samples, n)) * np.sqrt(d)[None, :]
    Zs = W @ L  # rows: (Lᵀ diag(√d) w)ᵀ
    ratios_fail: list[float] = []
    for zh in Zs:
        shift = np.round(zh)
        Zfix, s = search(L, d, zh - shift, 2)
        best = Zfix[:, 0] + shift
        if np.any(best != 0.0):
            ratios_fail.append(ratio_of(s))
    allowed = int(math.floor(pf * n_samples))
    if len(ratios_fail) <= allowed:
        return 1.0
    r = np.sort(np.asarray(ratios_fail))[::-1]  # descending
    # accept ratio >= μ; need #{r_i >= μ} <= allowed → μ just above r[allowed]
    mu = float(np.nextafter(r[allowed], np.inf))
    return float(min(max(mu, 1.0), max_threshold))
