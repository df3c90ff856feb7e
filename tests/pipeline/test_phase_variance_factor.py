"""The a-posteriori variance factor of a fixed solution's phase rows (algorithms.md §37)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from robustrtk.estimation.integrity import phase_variance_factor
from robustrtk.pipeline.rtk_fix import fixed_phase_factor


def _dd_cov(m: int, sigma_m: float) -> np.ndarray:
    # DD rows sharing one reference: σ² (I + 1 1ᵀ)
    return sigma_m**2 * (np.eye(m) + np.ones((m, m)))


@pytest.mark.parametrize("scale", [1.0, 3.0, 10.0])
def test_the_factor_estimates_the_variance_ratio(scale: float) -> None:
    """Residuals drawn with ``scale`` times the modelled σ: the factor is ``scale²`` within its
    sampling error (χ²_f / f over many rows)."""
    rng = np.random.default_rng(7)
    m = 4000
    R = _dd_cov(m, 0.003)
    v = scale * np.linalg.cholesky(R) @ rng.standard_normal(m)
    f = phase_variance_factor(v, R, m - 3)
    assert f == pytest.approx(max(1.0, scale**2), rel=0.06)


def test_the_factor_is_never_below_one_nor_defined_without_redundancy() -> None:
    R = _dd_cov(5, 0.003)
    assert phase_variance_factor(np.zeros(5), R, 2) == 1.0  # perfect residuals: model kept
    assert phase_variance_factor(np.full(5, 0.1), R, 0) == 1.0  # no redundancy
    assert phase_variance_factor(np.full(5, 0.1), np.zeros((5, 5)), 2) == 1.0  # singular R
    assert phase_variance_factor(np.full(5, np.nan), R, 2) == 1.0
    assert phase_variance_factor(np.full(5, 0.03), R, 2) > 1.0


def test_fixed_factor_leaves_out_rejected_rows_and_counts_float_ones() -> None:
    """A rejected row (γ = ∞) does not enter; a down-weighted row enters with γ R; a row whose
    ambiguity stays float takes one degree of freedom."""
    m, sig = 8, 0.003
    R = np.eye(m) * sig**2
    v = np.full(m, 2.0 * sig)
    v[0] = 100.0 * sig  # gross: rejected by the robust update
    model = SimpleNamespace(z=v.copy(), R=R, h=lambda x: np.zeros(m))
    state = SimpleNamespace(x=np.zeros(3))
    g = np.ones(m)
    g[0] = np.inf
    none_float = np.array([-1])
    # 7 rows at 2σ, redundancy 7 − 3 = 4: 7·4 / 4 = 7
    assert fixed_phase_factor(model, state, g, none_float) == pytest.approx(7.0)  # type: ignore[arg-type]
    # one more row float (row 3): redundancy 3
    assert fixed_phase_factor(model, state, g, np.array([3])) == pytest.approx(28.0 / 3.0)  # type: ignore[arg-type]
    # a float ambiguity on the rejected row changes nothing
    assert fixed_phase_factor(model, state, g, np.array([0])) == pytest.approx(7.0)  # type: ignore[arg-type]
    g[1] = 4.0  # down-weighted: its squared residual counts a quarter
    assert fixed_phase_factor(model, state, g, none_float) == pytest.approx((6 * 4 + 1) / 4.0)  # type: ignore[arg-type]
