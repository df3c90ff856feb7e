"""The Doppler velocity snapshot (algorithms.md §44): exact on noise-free rows built from
known satellite states, the weighted least squares of noisy rows, a gross row dropped, the
receiver clock drift absorbed, satellite rates from a central difference."""

from __future__ import annotations

import numpy as np
import pytest

from robustrtk.core import CLIGHT
from robustrtk.geometry.los import OMEGA_E_RAD_S
from robustrtk.measurement.doppler_velocity import (
    VelocityModel,
    doppler_rows,
    satellite_rates,
    velocity_snapshot,
)

RX = np.array([3774696.6, -596647.2, 5089480.9])  # ECEF (m)
LAM = CLIGHT / 1575.42e6


def _scene(n: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``n`` satellites above the receiver: positions, velocities (m/s), clock drifts (m/s)
    and elevations."""
    rng = np.random.default_rng(seed)
    up = RX / np.linalg.norm(RX)
    east = np.cross([0.0, 0.0, 1.0], up)
    east /= np.linalg.norm(east)
    north = np.cross(up, east)
    az = rng.uniform(0, 2 * np.pi, n)
    el = rng.uniform(np.deg2rad(15), np.deg2rad(85), n)
    d = (np.cos(el) * np.sin(az))[:, None] * east + (np.cos(el) * np.cos(az))[:, None] * north
    d += np.sin(el)[:, None] * up
    sp = RX + 2.2e7 * d
    sv = rng.normal(0.0, 2500.0, (n, 3))
    sd = rng.normal(0.0, 0.3, n)
    return sp, sv, sd, el


def _doppler(sp: np.ndarray, sv: np.ndarray, sd: np.ndarray, v: np.ndarray, drift: float) -> np.ndarray:
    """Doppler (Hz) of the model: −λD = u·(v_s − v) + Sagnac rate + drift − sat drift."""
    los = sp - RX
    u = los / np.linalg.norm(los, axis=1)[:, None]
    w = OMEGA_E_RAD_S / CLIGHT
    sag = w * (sv[:, 0] * RX[1] + sp[:, 0] * v[1] - sv[:, 1] * RX[0] - sp[:, 1] * v[0])
    rate = np.sum(u * (sv - v), axis=1) + sag + drift - sd
    return np.asarray(-rate / LAM)


def _rows(D: np.ndarray, sp: np.ndarray, sv: np.ndarray, sd: np.ndarray, el: np.ndarray, cn0: np.ndarray):  # type: ignore[no-untyped-def]
    n = D.size
    return doppler_rows(D, np.full(n, LAM), cn0, RX, sp, sv, sd, el, np.ones(n, bool), 0.05)


@pytest.mark.parametrize("drift", [0.0, 150.0, -3.0e4])
def test_noise_free_rows_give_the_velocity_whatever_the_drift(drift: float) -> None:
    sp, sv, sd, el = _scene(9, 1)
    v = np.array([12.0, -7.5, 0.8])
    rows = _rows(_doppler(sp, sv, sd, v, drift), sp, sv, sd, el, np.full(9, 45.0))
    snap = velocity_snapshot(rows)
    assert snap is not None
    np.testing.assert_allclose(snap.vel_m_s, v, atol=1e-6)
    assert snap.drift_m_s == pytest.approx(drift, abs=1e-5)
    assert snap.n_used == 9


def test_noisy_rows_equal_weighted_least_squares_by_brute_force() -> None:
    sp, sv, sd, el = _scene(10, 2)
    rng = np.random.default_rng(3)
    v = np.array([-3.0, 20.0, 1.0])
    cn0 = rng.uniform(30.0, 50.0, 10)
    rows = _rows(_doppler(sp, sv, sd, v, 40.0), sp, sv, sd, el, cn0)
    y = rows.y + rng.normal(0, 1, 10) * np.sqrt(rows.var_m2_s2)
    noisy = type(rows)(rows.A, y, rows.var_m2_s2, rows.rows)
    snap = velocity_snapshot(noisy)
    assert snap is not None and snap.n_used == 10
    # brute force: the normal equations of the whitened rows, solved by lstsq
    s = 1.0 / np.sqrt(noisy.var_m2_s2)
    x, *_ = np.linalg.lstsq(noisy.A * s[:, None], noisy.y * s, rcond=None)
    np.testing.assert_allclose(snap.vel_m_s, x[:3], atol=1e-9)
    N = (noisy.A * (s * s)[:, None]).T @ noisy.A
    s02 = float(np.sum(((noisy.y - noisy.A @ x) * s) ** 2)) / (10 - 4)
    np.testing.assert_allclose(snap.cov_m2_s2, np.linalg.inv(N)[:3, :3] * max(1.0, s02), rtol=1e-9)
    # the velocity error is covered by its σ
    err = snap.vel_m_s - v
    assert np.all(np.abs(err) <= 4.0 * np.sqrt(np.diag(snap.cov_m2_s2)))


def test_a_gross_row_is_dropped() -> None:
    sp, sv, sd, el = _scene(10, 4)
    v = np.array([5.0, 5.0, 0.0])
    D = _doppler(sp, sv, sd, v, 7.0)
    D[3] += 10.0 / LAM  # 10 m/s on one row
    snap = velocity_snapshot(_rows(D, sp, sv, sd, el, np.full(10, 45.0)))
    assert snap is not None and snap.n_used == 9
    np.testing.assert_allclose(snap.vel_m_s, v, atol=1e-6)


def test_too_few_rows_or_no_doppler_give_nothing() -> None:
    sp, sv, sd, el = _scene(4, 5)
    D = _doppler(sp, sv, sd, np.zeros(3), 0.0)
    assert velocity_snapshot(_rows(D, sp, sv, sd, el, np.full(4, 45.0))) is None
    sp, sv, sd, el = _scene(8, 5)
    D = np.full(8, np.nan)
    D[:4] = 1.0
    assert velocity_snapshot(_rows(D, sp, sv, sd, el, np.full(8, 45.0))) is None


class _Linear:
    """A source whose satellites move on straight lines with linear clocks."""

    def __init__(self, p0: np.ndarray, v: np.ndarray, c0: np.ndarray, cd: np.ndarray) -> None:
        self.p0, self.v, self.c0, self.cd = p0, v, c0, cd

    def positions(self, t_s: float, tx_ids: object, code_m: object = None) -> tuple[np.ndarray, np.ndarray]:
        return self.p0 + self.v * t_s, self.c0 + self.cd * t_s


def test_satellite_rates_from_the_source() -> None:
    rng = np.random.default_rng(6)
    p0, v = rng.normal(0, 2e7, (5, 3)), rng.normal(0, 3e3, (5, 3))
    src = _Linear(p0, v, rng.normal(0, 1e5, 5), rng.normal(0, 1, 5))
    vel, drift = satellite_rates(src, 1000.0, [f"G{i:02d}" for i in range(5)], np.full(5, 2e7))
    np.testing.assert_allclose(vel, src.v, rtol=1e-6)
    np.testing.assert_allclose(drift, src.cd, rtol=1e-6, atol=1e-8)


def test_velocity_model_reads_the_velocity_block() -> None:
    m = VelocityModel(np.array([1.0, 2.0, 3.0]), np.eye(3), slice(3, 6))
    x = np.arange(8.0)
    np.testing.assert_array_equal(m.h(x), [3.0, 4.0, 5.0])
    H = m.jacobian(x)
    assert H.shape == (3, 8)
    np.testing.assert_array_equal(H[:, 3:6], np.eye(3))
    assert np.count_nonzero(H) == 3


def test_doppler_prediction_is_exact_for_constant_acceleration() -> None:
    from robustrtk.measurement.doppler_velocity import doppler_prediction

    p0, v0, a, dt = np.array([1.0, 2.0, 3.0]), np.array([10.0, -4.0, 0.5]), np.array([2.0, 3.0, -1.0]), 0.7
    x_prev = np.concatenate([p0, v0, [42.0]])  # a seventh state is held
    P_prev = np.diag([1.0, 1.0, 1.0, 0.01, 0.01, 0.01, 5.0])
    v1 = v0 + a * dt
    C = np.eye(3) * 1e-4
    x, P = doppler_prediction(x_prev, P_prev, slice(0, 3), slice(3, 6), dt, v1, C, 0.0)
    np.testing.assert_allclose(x[:3], p0 + v0 * dt + 0.5 * a * dt**2, atol=1e-12)
    np.testing.assert_allclose(x[3:6], v1)
    assert x[6] == 42.0 and P[6, 6] == 5.0
    # position variance: the previous one, plus (dt/2)² of both velocities'
    np.testing.assert_allclose(np.diag(P)[:3], 1.0 + dt**2 / 4 * (0.01 + 1e-4))
    np.testing.assert_allclose(P[3:6, 3:6], C)
    assert np.all(np.linalg.eigvalsh(P) > 0)


def test_doppler_prediction_jerk_term_matches_monte_carlo() -> None:
    """The trapezoid's error under a white jerk of density q has variance q dt⁵/120."""
    from robustrtk.measurement.doppler_velocity import doppler_prediction

    rng = np.random.default_rng(7)
    q, dt, k, n = 4.0, 1.0, 400, 20000
    h = dt / k
    jerk = rng.normal(0.0, np.sqrt(q / h), (n, k))  # white jerk, one axis
    acc = np.cumsum(jerk, axis=1) * h
    vel = np.concatenate([np.zeros((n, 1)), np.cumsum(acc, axis=1) * h], axis=1)
    disp = (vel[:, :-1] + vel[:, 1:]).sum(axis=1) * h / 2
    err = disp - dt / 2 * (vel[:, 0] + vel[:, -1])
    _, P = doppler_prediction(
        np.zeros(6), np.zeros((6, 6)), slice(0, 3), slice(3, 6), dt, np.zeros(3), np.zeros((3, 3)), q
    )
    assert P[0, 0] == pytest.approx(q * dt**5 / 120)
    assert np.var(err) == pytest.approx(P[0, 0], rel=0.05)


def test_standing_is_the_chi_square_test_of_a_zero_velocity() -> None:
    from robustrtk.measurement.chi2 import chi2_ppf
    from robustrtk.measurement.doppler_velocity import standing

    R = np.diag([1e-4, 4e-4, 9e-4])  # σ 1, 2, 3 cm/s
    limit = chi2_ppf(0.999, 3)
    for v in ([0.0, 0.0, 0.0], [0.01, -0.02, 0.03], [0.1, 0.0, 0.0], [0.0, 0.0, 0.5]):
        z = np.array(v)
        m = VelocityModel(z, R, slice(3, 6))
        assert standing(m) == bool(z @ np.linalg.solve(R, z) <= limit)
    assert standing(VelocityModel(np.zeros(3), R, slice(3, 6)))
    assert not standing(VelocityModel(np.array([0.2, 0.0, 0.0]), R, slice(3, 6)))
