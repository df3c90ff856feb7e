"""Chi-square quantiles in plain Python (no scipy import on the solve path).

The fault-detection test of single-point positioning compares ``vᵀ W v`` with the
``1 − α`` quantile of a chi-square distribution with ``m − n`` degrees of freedom.
Importing :mod:`scipy.stats` for that one number costs about half a second and 70 MiB at
start-up, so the quantile is computed here from the regularized incomplete gamma function
(algorithms.md §18).
"""

from __future__ import annotations

import math
from functools import lru_cache

#: Relative tolerance of the Newton iteration on the quantile.
_REL_TOL = 4.0e-16
_MAX_ITER = 200


def _gamma_p_series(a: float, x: float) -> float:
    """``P(a, x)`` by its power series, for ``x < a + 1``."""
    term = 1.0 / a
    total = term
    ap = a
    for _ in range(10_000):
        ap += 1.0
        term *= x / ap
        total += term
        if abs(term) < abs(total) * 1e-17:
            break
    return total * math.exp(-x + a * math.log(x) - math.lgamma(a))


def _gamma_q_fraction(a: float, x: float) -> float:
    """``Q(a, x) = 1 − P(a, x)`` by its continued fraction (modified Lentz), for ``x ≥ a + 1``."""
    tiny = 1e-300
    b = x + 1.0 - a
    c = 1.0 / tiny
    d = 1.0 / b
    h = d
    for i in range(1, 10_000):
        an = -i * (i - a)
        b += 2.0
        d = an * d + b
        if abs(d) < tiny:
            d = tiny
        c = b + an / c
        if abs(c) < tiny:
            c = tiny
        d = 1.0 / d
        delta = d * c
        h *= delta
        if abs(delta - 1.0) < 1e-17:
            break
    return h * math.exp(-x + a * math.log(x) - math.lgamma(a))


def gamma_p(a: float, x: float) -> float:
    """Regularized lower incomplete gamma function ``P(a, x) = γ(a, x) / Γ(a)``.

    Parameters
    ----------
    a : float
        Shape, ``a > 0``.
    x : float
        Argument, ``x ≥ 0``.

    Returns
    -------
    float
        ``P(a, x)`` in [0, 1].
    """
    if a <= 0.0 or x < 0.0 or math.isnan(x):
        raise ValueError(f"gamma_p needs a > 0 and x >= 0, got a={a}, x={x}")
    if x == 0.0:
        return 0.0
    if x < a + 1.0:
        return _gamma_p_series(a, x)
    return 1.0 - _gamma_q_fraction(a, x)


def gamma_q(a: float, x: float) -> float:
    """Regularized upper incomplete gamma function ``Q(a, x) = 1 − P(a, x)`` (accurate in the tail)."""
    if a <= 0.0 or x < 0.0 or math.isnan(x):
        raise ValueError(f"gamma_q needs a > 0 and x >= 0, got a={a}, x={x}")
    if x == 0.0:
        return 1.0
    if x < a + 1.0:
        return 1.0 - _gamma_p_series(a, x)
    return _gamma_q_fraction(a, x)


@lru_cache(maxsize=512)
def chi2_ppf(q: float, dof: int) -> float:
    """Quantile ``x`` with ``F(x; k) = q`` of the chi-square distribution with ``k`` degrees of freedom.

    Parameters
    ----------
    q : float
        Probability in (0, 1).
    dof : int
        Degrees of freedom ``k ≥ 1``.

    Returns
    -------
    float
        ``x ≥ 0`` with ``P(k/2, x/2) = q`` (dimensionless, same units as ``vᵀ W v``).

    Notes
    -----
    ``F(x; k) = P(k/2, x/2)`` with ``P`` the regularized lower incomplete gamma function
    (series below ``a + 1``, continued fraction above). Start: Wilson–Hilferty
    ``x₀ = k (1 − 2/(9k) + z √(2/(9k)))³`` with ``z`` the normal quantile; then Newton steps
    on ``F(x) − q`` with ``F'(x) = x^{k/2−1} e^{−x/2} / (2^{k/2} Γ(k/2))``, the upper tail
    ``Q`` used when ``q > 1/2`` so the residual keeps its digits (algorithms.md §18).
    Relative agreement with :func:`scipy.stats.chi2.ppf` is about 1e-14 (tested).
    """
    if not 0.0 < q < 1.0:
        raise ValueError(f"chi2_ppf needs 0 < q < 1, got {q}")
    if dof < 1:
        raise ValueError(f"chi2_ppf needs dof >= 1, got {dof}")
    k = float(dof)
    a = 0.5 * k
    z = _normal_ppf(q)
    c = 2.0 / (9.0 * k)
    x = k * max(1.0 - c + z * math.sqrt(c), 0.05) ** 3
    log_norm = a * math.log(2.0) + math.lgamma(a)
    upper = q > 0.5
    target = 1.0 - q if upper else q
    for _ in range(_MAX_ITER):
        f = gamma_q(a, 0.5 * x) if upper else gamma_p(a, 0.5 * x)
        resid = (target - f) if upper else (f - target)
        pdf = math.exp((a - 1.0) * math.log(x) - 0.5 * x - log_norm)
        if pdf <= 0.0:
            break
        step = resid / pdf
        x_new = x - step
        if x_new <= 0.0:
            x_new = 0.5 * x
        if abs(x_new - x) <= _REL_TOL * x:
            x = x_new
            break
        x = x_new
    return x


def _normal_ppf(p: float) -> float:
    """Standard normal quantile for the starting value (Acklam's rational fit, ~1e-9)."""
    a = (-3.969683028665376e01, 2.209460984245205e02, -2.759285104469687e02,
         1.383577518672690e02, -3.066479806614716e01, 2.506628277459239e00)  # fmt: skip
    b = (-5.447609879822406e01, 1.615858368580409e02, -1.556989798598866e02,
         6.680131188771972e01, -1.328068155288572e01)  # fmt: skip
    c = (-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e00,
         -2.549732539343734e00, 4.374664141464968e00, 2.938163982698783e00)  # fmt: skip
    d = (7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e00, 3.754408661907416e00)
    lo = 0.02425
    if p < lo:
        r = math.sqrt(-2.0 * math.log(p))
        return (((((c[0] * r + c[1]) * r + c[2]) * r + c[3]) * r + c[4]) * r + c[5]) / (
            (((d[0] * r + d[1]) * r + d[2]) * r + d[3]) * r + 1.0
        )
    if p > 1.0 - lo:
        r = math.sqrt(-2.0 * math.log(1.0 - p))
        return -(((((c[0] * r + c[1]) * r + c[2]) * r + c[3]) * r + c[4]) * r + c[5]) / (
            (((d[0] * r + d[1]) * r + d[2]) * r + d[3]) * r + 1.0
        )
    r = p - 0.5
    s = r * r
    return (
        (((((a[0] * s + a[1]) * s + a[2]) * s + a[3]) * s + a[4]) * s + a[5])
        * r
        / (((((b[0] * s + b[1]) * s + b[2]) * s + b[3]) * s + b[4]) * s + 1.0)
    )


__all__ = ["chi2_ppf", "gamma_p", "gamma_q"]
