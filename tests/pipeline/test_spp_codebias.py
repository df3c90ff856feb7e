"""Per-satellite Gauss–Markov code-bias states of the Kalman SPP (docs/algorithms.md §43):
their transition, the estimate of σ_b and τ from code minus carrier, and the filter with
them on constructed geonet epochs (no bias: the old solution; one biased satellite: the
state takes the bias up and the position error drops)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from test_spp import _kalman_synthetic

from robustrtk.estimation.state import StateLayout
from robustrtk.geometry.frames import ecef2enu_rotation, ecef2geodetic
from robustrtk.geometry.los import elevation_rot
from robustrtk.pipeline.loop import EpochLoop
from robustrtk.pipeline.spp import solve_spp_kalman
from robustrtk.pipeline.spp_codebias import (
    ELEVATION_DELAY_KEY,
    CodeBiasModel,
    CodeBiasProcess,
    code_bias_from_cmc,
    code_bias_key,
    elevation_delay_coefficients,
    is_code_bias,
)
from robustrtk.pipeline.spp_dynamics import SppProcessModel, spp_layout
from robustrtk.pipeline.spp_kalman import KalmanSppStage


def test_transition_is_gauss_markov_for_code_biases_only() -> None:
    fixed = spp_layout(1, True, 0)
    keys = (("G01", 0, 0), code_bias_key("G01:P1"), code_bias_key("G02:P1"))
    layout = StateLayout(blocks=fixed.blocks, amb_keys=keys)
    inner = SppProcessModel()
    model = CodeBiasModel(sigma_m=2.0, tau_s=20.0)
    proc = CodeBiasProcess(inner, model, {keys[1]: 9.0})
    F0, Q0 = inner.transition(layout, 5.0)
    F, Q = proc.transition(layout, 5.0)
    nf = layout.n_fixed
    phi = np.exp(-5.0 / 20.0)
    assert F[nf, nf] == F0[nf, nf] == 1.0 and Q[nf, nf] == Q0[nf, nf]  # phase arc: random walk
    assert F[nf + 1, nf + 1] == pytest.approx(phi)
    assert Q[nf + 1, nf + 1] == pytest.approx(9.0 * (1 - phi**2))  # its own steady variance
    assert Q[nf + 2, nf + 2] == pytest.approx(4.0 * (1 - phi**2))  # the model's σ_b² otherwise
    np.testing.assert_array_equal(F[:nf, :nf], F0[:nf, :nf])
    # the steady state is kept: φ² s + q = s
    s = 9.0
    assert phi**2 * s + Q[nf + 1, nf + 1] == pytest.approx(s)
    assert is_code_bias(keys[1]) and not is_code_bias(keys[0])


def test_white_part_keeps_the_total_and_never_vanishes() -> None:
    m = CodeBiasModel(sigma_m=1.0, tau_s=10.0)
    assert m.white_var(9.0, 1.0) == pytest.approx(8.0)
    assert m.white_var(9.0 / 0.25, 0.5) == pytest.approx(36.0 - 4.0)
    assert m.white_var(0.5, 1.0) == pytest.approx(0.05)


def _gm(rng: np.random.Generator, n: int, sigma: float, tau: float, dt: float) -> np.ndarray:
    phi = np.exp(-dt / tau)
    x = np.empty(n)
    x[0] = rng.normal(0, sigma)
    w = rng.normal(0, sigma * np.sqrt(1 - phi**2), n)
    for k in range(1, n):
        x[k] = phi * x[k - 1] + w[k]
    return x


@pytest.mark.parametrize(("sigma_b", "tau_s"), [(1.0, 4.0), (2.0, 8.0)])
def test_cmc_estimate_recovers_a_gauss_markov_bias_under_clock_jumps(sigma_b: float, tau_s: float) -> None:
    """Twelve signals, 600 epochs at 1 s: white 0.4 m + Gauss–Markov (σ_b, τ) code error,
    one arbitrary constant per arc (arcs of 150 epochs), a common clock difference that
    jumps by tens of metres each epoch, a slow ionospheric drift."""
    rng = np.random.default_rng(11)
    T, R, dt = 600, 12, 1.0
    t = np.arange(T) * dt
    clock = np.cumsum(rng.normal(0, 30.0, T))
    cmc = np.empty((T, R))
    cont = np.ones((T, R), bool)
    for r in range(R):
        err = rng.normal(0, 0.4, T) + _gm(rng, T, sigma_b, tau_s, dt)
        arc_const = np.repeat(rng.uniform(-1e6, 1e6, T // 150), 150)
        cmc[:, r] = err + arc_const + clock + 0.002 * t * rng.uniform(-1, 1)
        cont[::150, r] = False
    est = code_bias_from_cmc(t, cmc, cont, np.ones((T, R)))
    assert est is not None
    sb, tau, white = est
    # the white σ also holds the Gauss–Markov part's one-step change (an upper bound),
    # so σ_b comes out somewhat low; both within a quarter, τ within a half
    assert 0.4 <= white < 0.4 * np.sqrt(1 + 2 * sigma_b**2 * (1 - np.exp(-dt / tau_s)) / (2 * 0.16)) + 0.05
    assert 0.75 * sigma_b < sb < 1.1 * sigma_b
    assert 0.5 * tau_s < tau < 1.5 * tau_s


def test_cmc_estimate_needs_arcs() -> None:
    t = np.arange(50.0)
    cmc = np.random.default_rng(1).normal(size=(50, 4))
    assert code_bias_from_cmc(t, cmc, np.ones((50, 4), bool), np.ones((50, 4))) is None


def _run(b, eph, cfg):  # type: ignore[no-untyped-def]
    stage = KalmanSppStage(b, eph, cfg)
    loop = EpochLoop(stage)
    sols = [loop.step(i) for i in range(len(b))]
    return stage, sols


def test_without_code_bias_the_states_stay_near_zero(shared_data: Path) -> None:
    b, eph, truth, cfg = _kalman_synthetic(shared_data)
    old = solve_spp_kalman(b, eph, cfg)
    on = cfg.updated(code_bias=True, code_bias_sigma_m=0.2, code_bias_tau_s=60.0)
    stage, new = _run(b, eph, on)
    assert stage.code_states is not None and stage.code_states.biases is not None
    for s0, s1 in zip(old, new, strict=True):
        assert s1.status == s0.status == "single"
        assert np.linalg.norm(s1.pos_ecef_m - s0.pos_ecef_m) < 0.01
    st = stage.state
    assert st is not None
    bias = [st.x[st.layout.amb_index(k)] for k in st.layout.amb_keys if is_code_bias(k)]
    assert len(bias) >= 5
    assert max(abs(v) for v in bias) < 0.01


def test_a_constant_bias_on_one_satellite_is_absorbed(shared_data: Path) -> None:
    """2 m on one satellite's code at every epoch, robust rejection off (the bias is not an
    outlier to reject but an error to model). Both runs start from the same least-squares
    fix, which the bias pulls 1 m off; over the ten epochs (4.5 min of slowly changing
    geometry) the plain filter drifts further off, while with the states the error shrinks
    and that satellite's state takes up the bias: the largest of all, of the right sign."""
    b, eph, truth, cfg = _kalman_synthetic(shared_data, code_fault_m=2.0)
    cfg = cfg.updated(robust="none")
    plain = solve_spp_kalman(b, eph, cfg)
    on = cfg.updated(code_bias=True, code_bias_sigma_m=0.3, code_bias_tau_s=3600.0)
    stage, sols = _run(b, eph, on)
    e_plain = [float(np.linalg.norm(s.pos_ecef_m - truth)) for s in plain]
    e_new = [float(np.linalg.norm(s.pos_ecef_m - truth)) for s in sols]
    assert e_plain[0] > 0.5 and e_plain[-1] > e_plain[0]
    assert e_new[-1] < e_new[0] < e_plain[-1]
    st = stage.state
    assert st is not None
    key = code_bias_key(f"{b.tx_ids[3]}:P1")
    others = [abs(st.x[st.layout.amb_index(k)]) for k in st.layout.amb_keys if is_code_bias(k) and k != key]
    assert st.x[st.layout.amb_index(key)] > 0.5 * 2.0
    assert st.x[st.layout.amb_index(key)] > 3 * max(others)


def test_elevation_delay_column_is_zero_at_the_zenith_and_for_other_rows() -> None:
    up = np.array([0.0, 0.0, 1.0])
    pos = up * 6.4e6
    H = [-np.array([0.0, np.cos(e), np.sin(e)]) for e in np.deg2rad([90.0, 30.0, 15.0, 30.0])]
    c = elevation_delay_coefficients(["P", "P", "P", "L"], H, pos)
    np.testing.assert_allclose(c, [0.0, 1.0, 1.0 / np.sin(np.deg2rad(15.0)) - 1.0, 0.0], atol=1e-12)


def _with_elevation_delay(shared: Path, delay_m: float) -> tuple:  # type: ignore[type-arg]
    """The constructed geonet epochs with ``delay_m (1/sin el − 1)`` on every code (the
    elevation from the true position)."""
    b, eph, truth, cfg = _kalman_synthetic(shared)
    lat, lon, _ = ecef2geodetic(truth)
    rot = ecef2enu_rotation(float(lat), float(lon))
    for i in range(len(b)):
        have = np.flatnonzero(np.isfinite(b.code_m[i, :, 0]))
        pos, _ = eph.positions(float(b.t_s[i]), [b.tx_ids[j] for j in have], b.code_m[i, have, 0])
        el = elevation_rot(np.asarray(pos, float), truth, rot)
        b.code_m[i, have, 0] += delay_m * (1.0 / np.sin(el) - 1.0)
    return b, eph, truth, cfg


def test_elevation_delay_stays_zero_without_one(shared_data: Path) -> None:
    b, eph, truth, cfg = _kalman_synthetic(shared_data)
    old = solve_spp_kalman(b, eph, cfg)
    stage, new = _run(b, eph, cfg.updated(code_elevation_delay=True, code_bias_sigma_m=1.0))
    for s0, s1 in zip(old, new, strict=True):
        assert s1.status == "single"
        assert np.linalg.norm(s1.pos_ecef_m - s0.pos_ecef_m) < 0.01
    st = stage.state
    assert st is not None
    assert abs(st.x[st.layout.amb_index(ELEVATION_DELAY_KEY)]) < 0.01


def test_an_elevation_dependent_delay_is_taken_up(shared_data: Path) -> None:
    """1 m (1/sin el − 1) on every code (3 m at 19°), no robust rejection: the plain filter
    is pulled 3.6 m off by it; with the state (both start from the same least-squares fix)
    the error shrinks at every epoch, to under a quarter of the plain filter's, as the
    state takes up the delay."""
    b, eph, truth, cfg = _with_elevation_delay(shared_data, 1.0)
    cfg = cfg.updated(robust="none")
    plain = solve_spp_kalman(b, eph, cfg)
    stage, sols = _run(b, eph, cfg.updated(code_elevation_delay=True, code_bias_sigma_m=1.0))
    e_plain = np.array([np.linalg.norm(s.pos_ecef_m - truth) for s in plain])
    e_new = np.array([np.linalg.norm(s.pos_ecef_m - truth) for s in sols])
    assert e_plain.min() > 0.3
    assert np.all(e_new[1:] < e_plain[1:])
    assert np.all(np.diff(e_new[1:]) < 0.0)
    assert e_new[-1] < 0.25 * e_plain[-1]
    st = stage.state
    assert st is not None
    assert 0.5 < st.x[st.layout.amb_index(ELEVATION_DELAY_KEY)] < 1.2
