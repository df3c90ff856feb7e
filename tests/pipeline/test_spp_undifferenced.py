"""Undifferenced SPP helpers on synthetic data: least squares, FDE, variance model, and the
Kalman SPP's process model with a layout change."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from robustrtk.estimation.models import ConstantVelocityModel
from robustrtk.estimation.state import GaussianState, StateLayout
from robustrtk.geometry.frames import ecef2enu_rotation, ecef2geodetic
from robustrtk.geometry.los import geometric_range
from robustrtk.measurement.undifferenced import (
    EpochGeometry,
    LsqSettings,
    atmosphere,
    elevation_cn0_variance,
    lsq_fde,
    lsq_solve,
)
from robustrtk.pipeline.spp_kalman import Relayout, SppProcessModel, predict_relayout, spp_layout

TRUTH = np.array([-3976219.1879, 3382371.6056, 3652511.1425])
CLOCKS = {"G": 12345.6, "E": -789.0}
T_S = 1112832000.0 + 3600.0
#: Klobuchar coefficients of the geonet navigation file (any values serve).
NAV: Any = SimpleNamespace(
    ion_gps_alpha=np.array([1.1180e-08, 1.4900e-08, -5.9600e-08, -5.9600e-08]),
    ion_gps_beta=np.array([8.8060e04, 1.6380e04, -1.9660e05, -1.3110e05]),
)
SETTINGS = LsqSettings(elev_mask_deg=5.0, code_sigma_m=0.3, use_cn0=False)


def _geometry(fault_m: float = 0.0, fault_row: int = 4) -> EpochGeometry:
    """Nine satellites (six GPS, three Galileo) around ``TRUTH``; noise-free pseudoranges
    with range, receiver clock per system, satellite clock and the modelled atmosphere."""
    az = np.deg2rad([10.0, 75.0, 140.0, 200.0, 260.0, 320.0, 30.0, 170.0, 290.0])
    el = np.deg2rad([70.0, 35.0, 20.0, 45.0, 15.0, 55.0, 25.0, 60.0, 40.0])
    sys = ("G",) * 6 + ("E",) * 3
    lat, lon, _ = ecef2geodetic(TRUTH)
    rot = ecef2enu_rotation(float(lat), float(lon))
    los_enu = np.column_stack([np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)])
    sat = TRUTH + 2.2e7 * los_enu @ rot
    sat_clk = np.linspace(-3e4, 2e4, 9)
    rng, _ = geometric_range(sat, TRUTH)
    atm = atmosphere(T_S, sat, TRUTH, NAV, "saastamoinen", "klobuchar")
    code = rng + np.array([CLOCKS[s] for s in sys]) - sat_clk + atm.code_delay_m
    code[fault_row] += fault_m
    n = len(sys)
    return EpochGeometry(
        ids=tuple(f"{s}{k:02d}" for k, s in enumerate(sys)),
        sys=sys,
        code_m=code,
        cn0_dbhz=np.full(n, 45.0),
        rate_m_s=np.full(n, np.nan),
        freq_hz=np.full(n, 1575.42e6),
        sat_pos_m=sat,
        sat_vel_m_s=np.zeros((n, 3)),
        sat_clk_m=sat_clk,
        sat_drift_m_s=np.zeros(n),
        ok=np.ones(n, bool),
    )


def test_lsq_recovers_position_and_clocks_exactly() -> None:
    g = _geometry()
    sol = lsq_solve(T_S, g, g.ok.copy(), NAV, SETTINGS)
    assert sol is not None
    assert np.linalg.norm(sol.pos - TRUTH) < 1e-6
    for s, c in CLOCKS.items():
        assert sol.clk[s] == pytest.approx(c, abs=1e-6)
    assert np.max(np.abs(sol.v)) < 1e-6
    assert sol.n_unknowns == 5 and sol.rows.size == 9


def test_lsq_is_none_when_under_determined() -> None:
    g = _geometry()
    use = np.zeros(9, bool)
    use[:4] = True  # four GPS rows: 3 + 1 unknowns, fine
    assert lsq_solve(T_S, g, use, NAV, SETTINGS) is not None
    use[:] = False
    use[[0, 1, 2, 6]] = True  # four rows, two systems: five unknowns
    assert lsq_solve(T_S, g, use, NAV, SETTINGS) is None


def test_fde_excludes_one_injected_50_m_error() -> None:
    g = _geometry(fault_m=50.0, fault_row=4)
    off = LsqSettings(elev_mask_deg=5.0, code_sigma_m=0.3, use_cn0=False, fde=False)
    plain, excl0, _ = lsq_fde(T_S, g, NAV, off)
    assert plain is not None and excl0 == []
    assert np.linalg.norm(plain.pos - TRUTH) > 1.0
    sol, excluded, ok = lsq_fde(T_S, g, NAV, SETTINGS)
    assert sol is not None and ok
    assert excluded == [g.ids[4]]
    assert np.linalg.norm(sol.pos - TRUTH) < 1e-6
    assert 4 not in sol.rows


def test_fde_passes_clean_data_untouched() -> None:
    sol, excluded, ok = lsq_fde(T_S, _geometry(), NAV, SETTINGS)
    assert sol is not None and ok and excluded == []


def test_variance_model_monotone_in_elevation_and_cn0() -> None:
    el = np.deg2rad(np.linspace(0.0, 90.0, 91))
    v = elevation_cn0_variance(0.5, el)
    assert np.all(np.diff(v) <= 0.0)  # higher satellites: smaller variance
    assert np.all(np.diff(v[5:]) < 0.0)  # strictly above the 5 degree floor
    assert np.all(v[:6] == v[5])  # floored below 5 degrees
    assert v[-1] == pytest.approx(0.25)  # sigma^2 at zenith
    cn0 = np.linspace(20.0, 55.0, 36)
    w = elevation_cn0_variance(0.5, np.full(cn0.size, np.pi / 2), cn0, cn0_ref_dbhz=45.0)
    assert np.all(np.diff(w) <= 0.0)  # stronger signals: smaller variance
    assert np.all(np.diff(w[cn0 <= 45.0]) < 0.0)
    assert np.all(w[cn0 >= 45.0] == pytest.approx(0.25))  # no down-weighting above the reference
    assert w[0] == pytest.approx(0.25 * 10**2.5)  # 25 dB below: 10^(25/10)
    nan = elevation_cn0_variance(0.5, np.array([np.pi / 2]), np.array([np.nan]))
    assert nan[0] == pytest.approx(0.25)


def test_process_model_with_a_layout_change_matches_a_hand_computation() -> None:
    """Arcs A, B, D before; B (with a slip variance), C (new) after; code clock restarted."""
    dt, s_h, s_up = 2.0, 3.0, 0.5
    q_clk, q_pclk, q_d, q_ifb, q_amb = 1000.0, 100.0, 10.0, 1e-4, 1e-4
    fixed = spp_layout(1, True, 1)  # pos 0-2, vel 3-5, clk 6, drift 7, pclk 8, ifb 9
    assert fixed.blocks == (("pos", 3), ("vel", 3), ("clk", 1), ("drift", 1), ("pclk", 1), ("ifb", 1))
    old = StateLayout(blocks=fixed.blocks, amb_keys=("A", "B", "D"))
    new = StateLayout(blocks=fixed.blocks, amb_keys=("B", "C"))
    inner = SppProcessModel(s_h, s_up, q_clk, q_pclk, q_d, q_ifb, q_amb)
    change = Relayout(
        inner, new, start={"C": 5.0}, start_var=1e4, extra_var={"B": 0.01}, restart={6: (42.0, 9.0)}
    )
    F, Q = change.transition(old, dt)
    assert F.shape == (12, 13) and Q.shape == (12, 12)

    Fh = np.zeros((12, 13))
    Fh[:10, :10] = np.eye(10)
    Fh[0:3, 3:6] = dt * np.eye(3)
    Fh[8, 7] = dt  # phase clock driven by the drift
    Fh[10, 11] = 1.0  # B carried
    Fh[6, :] = 0.0  # code clock restarted (would be Fh[6, 7] = dt)
    np.testing.assert_array_equal(F, Fh)

    qa = s_h**2 * np.eye(3)  # isotropic without a reference position
    Qh = np.zeros((12, 12))
    Qh[0:3, 0:3] = qa * dt**3 / 3
    Qh[0:3, 3:6] = Qh[3:6, 0:3] = qa * dt**2 / 2
    Qh[3:6, 3:6] = qa * dt
    Qh[8, 8] = q_d * dt**3 / 3 + q_pclk * dt
    Qh[8, 7] = Qh[7, 8] = q_d * dt**2 / 2
    Qh[7, 7] = q_d * dt
    Qh[9, 9] = q_ifb * dt
    Qh[10, 10] = q_amb * dt + 0.01
    Qh[11, 11] = 1e4
    Qh[6, 6] = 9.0
    np.testing.assert_allclose(Q, Qh, rtol=1e-12, atol=0.0)
    u = change.offset()
    assert u[6] == 42.0 and u[11] == 5.0 and np.count_nonzero(u) == 2

    # the prior of a state with that layout
    rng = np.random.default_rng(1)
    A = rng.normal(size=(13, 13))
    state = GaussianState(x=rng.normal(size=13), P=A @ A.T + np.eye(13), t_s=10.0, layout=old)
    prior, F2 = predict_relayout(state, change, 10.0 + dt)
    np.testing.assert_array_equal(F2, F)
    assert prior.layout == new and prior.t_s == 12.0
    np.testing.assert_allclose(prior.x, Fh @ state.x + u, rtol=1e-12)
    np.testing.assert_allclose(prior.P, Fh @ state.P @ Fh.T + Qh, rtol=1e-12)
    assert prior.x[new.amb_index("B")] == state.x[old.amb_index("B")]
    assert prior.P[6, :6].tolist() == [0.0] * 6  # a restarted state keeps no correlation


def test_process_model_splits_horizontal_and_vertical_acceleration() -> None:
    model = SppProcessModel(sigma_acc_m_s2=3.0, sigma_acc_up_m_s2=0.5).at(TRUTH)
    F, Q = model.transition(spp_layout(2, False, 0), 1.0)
    lat, lon, _ = ecef2geodetic(TRUTH)
    rot = ecef2enu_rotation(float(lat), float(lon))
    np.testing.assert_allclose(rot @ Q[3:6, 3:6] @ rot.T, np.diag([9.0, 9.0, 0.25]), atol=1e-12)
    assert F.shape == (9, 9) and F[6, 8] == 1.0 and F[7, 8] == 1.0  # both code clocks follow the drift


def test_relayout_wraps_any_process_model() -> None:
    old = StateLayout(blocks=(("pos", 3), ("vel", 3)), amb_keys=("a", "b"))
    new = StateLayout(blocks=old.blocks, amb_keys=("b",))
    F, Q = Relayout(ConstantVelocityModel(sigma_m_s2=0.1, q_amb_cyc2_s=0.5), new).transition(old, 1.0)
    F0, Q0 = ConstantVelocityModel(sigma_m_s2=0.1, q_amb_cyc2_s=0.5).transition(old, 1.0)
    keep = [0, 1, 2, 3, 4, 5, 7]
    np.testing.assert_array_equal(F, F0[keep])
    np.testing.assert_array_equal(Q, Q0[np.ix_(keep, keep)])
    with pytest.raises(ValueError, match="start value"):
        Relayout(ConstantVelocityModel(), StateLayout(blocks=old.blocks, amb_keys=("c",))).transition(
            old, 1.0
        )
