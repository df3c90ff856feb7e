"""The ``prior`` AR scheme (``docs/algorithms.md`` §20): known-point start, then each
epoch's float solution takes the previous epoch's coordinate as its prior with
``σ = prior_sigma_m``; ambiguities carried or re-estimated; AR every epoch, no hold."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from robustrtk.core import InputError
from robustrtk.estimation.state import GaussianState, StateLayout
from robustrtk.geometry.surveyed import SurveyedSource
from robustrtk.pipeline.config import Config
from robustrtk.pipeline.engine import DDEngine, align_epochs
from robustrtk.pipeline.results import EpochInputs
from robustrtk.pipeline.rtk_fix import coordinate_prior
from robustrtk.sim.pseudolite import SimResult, simulate
from robustrtk.sim.scenario import load_scenario

N_EPOCHS = 40


def _clean_static(seed: int, n: int = N_EPOCHS) -> SimResult:
    sc = dataclasses.replace(load_scenario("li2019_rtk_static"), gross=())
    return simulate(sc, np.random.default_rng(seed), n_epochs=n)


def _run(sim: SimResult, cfg: Config) -> tuple[np.ndarray, list[str]]:
    site = sim.site
    assert site.rover_initial_pos_m is not None
    eng = DDEngine(
        cfg, SurveyedSource(site.transmitters), site.base_pos_m, np.asarray(site.rover_initial_pos_m),
        reference=site.reference,
    )  # fmt: skip
    rov, bas = sim.batches["rover"], sim.batches["base"]
    sols = [eng.step(EpochInputs(rov.epoch(i), bas.epoch(j))).solution for i, j in align_epochs(rov, bas)]
    return np.array([s.pos_m for s in sols]), [s.status for s in sols]


def _cfg(**kw: object) -> Config:
    base: dict[str, object] = dict(mode="rtk", robust="none", ar="off", ar_scheme="prior")
    base.update(kw)
    return Config.of(**base).validate()


def test_coordinate_prior_resets_position_block_only() -> None:
    st = GaussianState(x=np.arange(3.0), P=np.eye(3), t_s=0.0, layout=StateLayout(blocks=(("pos", 3),)))
    st = st.add_ambiguities(["a", "b"], np.array([4.0, 5.0]), 1.0)
    A = np.random.default_rng(1).standard_normal((5, 5))
    st = st.with_(P=A @ A.T + np.eye(5))
    out = coordinate_prior(st, 0.2)
    np.testing.assert_array_equal(out.x, st.x)
    np.testing.assert_allclose(out.P[:3, :3], 0.04 * np.eye(3))
    np.testing.assert_array_equal(out.P[:3, 3:], 0.0)
    np.testing.assert_array_equal(out.P[3:, :3], 0.0)
    np.testing.assert_array_equal(out.P[3:, 3:], st.P[3:, 3:])
    # "add": σ² on the position's diagonal, every correlation kept
    added = coordinate_prior(st, 0.2, "add")
    np.testing.assert_array_equal(added.x, st.x)
    np.testing.assert_allclose(added.P - st.P, np.diag([0.04, 0.04, 0.04, 0.0, 0.0]), atol=1e-15)
    with pytest.raises(ValueError, match="reset or add"):
        coordinate_prior(st, 0.2, "keep")


def test_prior_covariance_is_a_prior_scheme_setting() -> None:
    assert _cfg(prior_covariance="add").ar.prior_covariance == "add"
    with pytest.raises(InputError, match="prior_covariance"):
        Config.of(mode="rtk", prior_covariance="sometimes").validate()


def test_reestimated_ambiguities_float_position_is_the_prior() -> None:
    """New ambiguities every epoch absorb every DD phase: without AR the float position
    never leaves the known point, whatever σ (EKF: exactly; the UKF adds its O(σ²/range)
    second-order mean shift, ~1e-9 m per epoch at σ = 2 cm); carried ambiguities do move
    it (control)."""
    sim = _clean_static(0)
    x0 = np.asarray(sim.site.rover_initial_pos_m)
    for sigma in (0.02, 0.5):
        pos, status = _run(sim, _cfg(prior_sigma_m=sigma, prior_ambiguities="reestimate", filter="ekf"))
        assert set(status) == {"float"}
        assert np.max(np.abs(pos - x0)) < 1e-9
    pos, _ = _run(sim, _cfg(prior_sigma_m=0.02, prior_ambiguities="reestimate"))
    assert np.max(np.abs(pos - x0)) < 1e-6
    pos, _ = _run(sim, _cfg(prior_sigma_m=0.05, prior_ambiguities="carry"))
    assert np.max(np.linalg.norm(pos - x0, axis=1)) > 1e-3


def test_tiny_sigma_float_position_equals_previous_coordinate() -> None:
    """σ → 0: each epoch's float position is its prior, the previous coordinate."""
    sim = _clean_static(1)
    pos, _ = _run(sim, _cfg(prior_sigma_m=1e-6, prior_ambiguities="carry"))
    assert np.max(np.linalg.norm(np.diff(pos, axis=0), axis=1)) < 1e-5
    pos, _ = _run(sim, _cfg(prior_sigma_m=0.05, prior_ambiguities="carry"))
    assert np.max(np.linalg.norm(np.diff(pos, axis=0), axis=1)) > 1e-3


def _dd_phase(sim: SimResult, i: int) -> tuple[list[str], np.ndarray]:
    """DD phase (cycles, rover − base, transmitter − reference) of epoch ``i`` by hand."""
    ref = sim.site.reference
    rov, bas = sim.batches["rover"].epoch(i), sim.batches["base"].epoch(i)
    ids = list(rov.tx_ids)
    r = ids.index(ref)
    sd = rov.phase_cyc[:, 0] - bas.phase_cyc[:, 0]
    others = [t for t in ids if t != ref]
    return others, np.array([sd[ids.index(t)] - sd[r] for t in others])


def _dd_range(sim: SimResult, tx: list[str], x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """DD geometric range (m) and its Jacobian (m/m) at rover position ``x``."""
    tr = sim.site.transmitters
    ref = sim.site.reference
    b = sim.site.base_pos_m

    def rng(p: np.ndarray, t: str) -> float:
        return float(np.linalg.norm(tr[t] - p))

    def u(t: str) -> np.ndarray:
        return (x - tr[t]) / rng(x, t)

    rho = np.array([(rng(x, t) - rng(x, ref)) - (rng(b, t) - rng(b, ref)) for t in tx])
    H = np.array([u(t) - u(ref) for t in tx])
    return rho, H


def test_fixed_position_equals_independent_least_squares() -> None:
    """With re-estimated ambiguities the fixed position is
    argmin ‖z − ρ(x) − λŇ‖²_R + ‖x − x̌_{k−1}‖²/σ²  (§20), solved here by Gauss–Newton
    with the true integers and ``R = 2σ_φ²(I + 11ᵀ)`` (equal weighting)."""
    sigma_p = 0.03
    cfg = _cfg(prior_sigma_m=sigma_p, prior_ambiguities="reestimate", ar="lambda", filter="ekf")
    sim = _clean_static(2, 30)
    pos, status = _run(sim, cfg)
    lam = sim.site.wavelength_m
    s2 = cfg.measurement.phase_sigma_m**2
    checked = 0
    dists = []
    for k in range(1, len(pos)):
        tx, z = _dd_phase(sim, k)
        rho_t, _ = _dd_range(sim, tx, sim.truth_pos_m[k])
        N = np.round(z - rho_t / lam)
        R = 2 * s2 * (np.eye(len(tx)) + np.ones((len(tx), len(tx))))
        W = np.linalg.inv(R)
        xp = pos[k - 1]
        sol = []
        for w_prior in (1.0 / sigma_p**2, 0.0):  # with the prior, and σ → ∞
            x = xp.copy()
            for _ in range(10):
                rho, H = _dd_range(sim, tx, x)
                r = z * lam - rho - lam * N
                A = H.T @ W @ H + np.eye(3) * w_prior
                x = x + np.linalg.solve(A, H.T @ W @ r - (x - xp) * w_prior)
            sol.append(x)
        if status[k] == "fixed":
            dists.append([float(np.linalg.norm(pos[k] - x)) for x in sol])
            checked += 1
    assert checked >= 20
    d = np.array(dists)
    assert d[:, 0].max() < 2e-4
    # the prior matters: single-epoch least squares (σ → ∞) is not what the engine gives
    assert d[:, 1].max() > 10 * d[:, 0].max()


def test_prior_scheme_refuses_instantaneous() -> None:
    with pytest.raises(InputError, match="ar_scheme"):
        Config.of(mode="rtk", ar_scheme="prior", instantaneous=True).validate()


def test_fixed_residual_test_limits() -> None:
    """``fix_residual_k``: a huge threshold changes nothing against the test off (k = 0); a
    tiny one rejects every fix (a fixed solution always leaves some residual)."""
    sim = _clean_static(3, 30)
    cfg = _cfg(prior_sigma_m=0.05, ar="lambda")
    pos0, st0 = _run(sim, cfg)
    pos1, st1 = _run(sim, cfg.updated(fix_residual_k=1e6))
    assert st0 == st1 and st0.count("fixed") >= 20
    np.testing.assert_array_equal(pos0, pos1)
    _, st2 = _run(sim, cfg.updated(fix_residual_k=1e-6))
    assert "fixed" not in st2 and "partial" not in st2
