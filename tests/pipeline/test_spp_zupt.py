"""The Kalman SPP's range-rate variance law and its zero-velocity test, on synthetic rows."""

from __future__ import annotations

import numpy as np
import pytest

from robustrtk.measurement.undifferenced import cn0_variance
from robustrtk.pipeline.spp_kalman import doppler_standing


def test_cn0_variance_follows_the_inverse_cn0_law() -> None:
    v = cn0_variance(0.05, np.array([45.0, 35.0, 25.0, np.nan, 48.0]), 45.0)
    assert v[0] == pytest.approx(0.05**2)
    assert v[1] == pytest.approx(10 * v[0])  # 10 dB less C/N0: ten times the variance
    assert v[2] == pytest.approx(100 * v[0])
    assert v[3] == pytest.approx(v[0])  # unknown C/N0 counts as the reference
    assert v[4] == pytest.approx(v[0] / 10**0.3)


def _rows(vel_m_s: np.ndarray, n: int = 8, seed: int = 1, sigma: float = 0.03) -> tuple:
    """Range-rate innovations of ``n`` satellites (spread in azimuth, at 20° and 60°) for a
    receiver moving at ``vel_m_s``,
    linearised at zero velocity, with a clock-drift error of 0.7 m/s and noise ``sigma``."""
    rng = np.random.default_rng(seed)
    az = np.deg2rad(np.arange(n) * 360.0 / n)
    el = np.deg2rad(np.where(np.arange(n) % 2, 60.0, 20.0))
    u = np.c_[np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)]  # receiver at a pole
    A = np.c_[-u, np.ones(n)]
    y = A @ np.r_[vel_m_s, 0.7] + rng.normal(scale=sigma, size=n)
    return A, y, np.full(n, sigma**2)


@pytest.mark.parametrize("seed", range(5))
def test_a_standing_receiver_is_detected_and_a_slow_one_is_not(seed: int) -> None:
    A, y, var = _rows(np.zeros(3), seed=seed)
    assert doppler_standing(A, y, var, np.zeros(3), 0.1)
    A, y, var = _rows(np.array([0.25, -0.1, 0.0]), seed=seed)
    assert not doppler_standing(A, y, var, np.zeros(3), 0.1)


def test_linearisation_velocity_is_added() -> None:
    """Rows linearised at 2 m/s whose innovations say −2 m/s: the receiver stands."""
    A, y, var = _rows(np.array([-2.0, 0.0, 0.0]))
    assert doppler_standing(A, y, var, np.array([2.0, 0.0, 0.0]), 0.1)
    assert not doppler_standing(A, y, var, np.zeros(3), 0.1)


def test_one_gross_range_rate_is_dropped_and_too_few_rows_decide_nothing() -> None:
    A, y, var = _rows(np.zeros(3), n=8)
    y_bad = y.copy()
    y_bad[3] += 5.0  # a multipath-hit Doppler of 5 m/s
    assert doppler_standing(A, y_bad, var, np.zeros(3), 0.1)
    # without the drop the bad row alone would shift the speed well past 0.1 m/s
    w = 1 / var
    delta = np.linalg.solve(A.T @ (A * w[:, None]), A.T @ (w * y_bad))
    assert np.linalg.norm(delta[:3]) > 0.1
    A5, y5, v5 = _rows(np.zeros(3), n=5)
    y5[0] += 5.0
    assert not doppler_standing(A5, y5, v5, np.zeros(3), 0.1)  # five rows, test fails: no decision
    assert not doppler_standing(A5[:4], y5[:4], v5[:4], np.zeros(3), 0.1)
