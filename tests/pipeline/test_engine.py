"""The DD engine on synthetic rooms and real data: inputs, receivers, motion and lock-up."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk.core import ObsBatch, ObsEpoch
from robustrtk.estimation.adaptive import (
    InnovationAdaptiveFactor,
    MotionSelector,
    robust_innovation_ratio,
    yang_factor,
)
from robustrtk.estimation.integrity import IntegrityPolicy
from robustrtk.geometry.receivers import FixedPosition, TrajectoryPosition
from robustrtk.geometry.surveyed import SurveyedSource
from robustrtk.measurement.chi2 import chi2_ppf
from robustrtk.pipeline.config import Config
from robustrtk.pipeline.engine import DDEngine
from robustrtk.pipeline.results import EpochInputs

#: Six pseudolites on the walls and ceiling of a 20 m room (local frame, z up).
TX = {
    "PL1": [0.0, 0.0, 6.0], "PL2": [20.0, 0.0, 5.0], "PL3": [20.0, 20.0, 6.0], "PL4": [0.0, 20.0, 4.0],
    "PL5": [10.0, 10.0, 8.0], "PL6": [10.0, -5.0, 2.0],
}  # fmt: skip
BASE = np.array([2.0, 3.0, 1.0])


def _epoch(t: float, pos: np.ndarray, rng: np.random.Generator | None, sigma: float = 0.05) -> ObsEpoch:
    ids = tuple(TX)
    tx = np.array([TX[i] for i in ids])
    code = np.linalg.norm(tx - pos, axis=1)
    if rng is not None:
        code = code + rng.normal(0.0, sigma, code.size)
    n = len(ids)
    nan = np.full((n, 1), np.nan)
    return ObsEpoch(
        t, ids, ("P",) * n, ("L1",), code[:, None], nan.copy(), nan.copy(), np.full((n, 1), 45.0),
        np.zeros((n, 1), np.int8), np.full((n, 1), 0.19),
    )  # fmt: skip


def _run(
    cfg: Config, rover_track: np.ndarray, seed: int = 0, base: object = BASE, integrity: bool = True
) -> tuple[np.ndarray, list]:
    rng = np.random.default_rng(seed)
    eng = DDEngine(
        cfg, SurveyedSource(TX), base, rover_track[0], reference="PL5",  # type: ignore[arg-type]
        integrity=IntegrityPolicy(enabled=integrity),
    )  # fmt: skip
    pos, diag = [], []
    for k, p in enumerate(rover_track):
        res = eng.step(EpochInputs(_epoch(float(k), p, rng), _epoch(float(k), BASE, rng)))
        pos.append(res.solution.pos_m)
        diag.extend(res.diagnostics)
    return np.array(pos), diag


def test_trajectory_position_interpolates_and_refuses_gaps() -> None:
    tr = TrajectoryPosition(np.array([0.0, 1.0, 5.0]), np.array([[0, 0, 0], [2, 4, 6], [3, 3, 3]], float))
    np.testing.assert_allclose(tr.position(0.5), [1.0, 2.0, 3.0])
    np.testing.assert_allclose(tr.position(1.0), [2.0, 4.0, 6.0])
    assert np.isnan(tr.position(3.0)).all()  # a 4 s gap is not interpolated
    assert np.isnan(tr.position(-1.0)).all() and np.isnan(tr.position(6.0)).all()
    with pytest.raises(ValueError):
        TrajectoryPosition(np.zeros(2), np.zeros((3, 3)))


def test_a_base_position_source_equals_the_constant_base() -> None:
    """The base as data: a constant, a trajectory of the same point, or the per-epoch input."""
    track = np.tile([8.0, 9.0, 1.5], (30, 1))
    cfg = Config.of(robust="none", dynamics="kinematic")
    a, _ = _run(cfg, track)
    b, _ = _run(cfg, track, base=FixedPosition(BASE))
    c, _ = _run(cfg, track, base=TrajectoryPosition(np.arange(30.0), np.tile(BASE, (30, 1))))
    np.testing.assert_array_equal(a, b)
    np.testing.assert_allclose(a, c, atol=1e-12)
    # an unknown base position gives no solution, never a wrong one
    eng = DDEngine(cfg, SurveyedSource(TX), TrajectoryPosition(np.array([100.0]), BASE[None]), track[0])
    res = eng.step(EpochInputs(_epoch(0.0, track[0], None), _epoch(0.0, BASE, None)))
    assert res.solution.status == "none"


def test_wrong_dynamics_do_not_lock_up_the_filter() -> None:
    """A receiver that jumps 30 m under a static model: every row is rejected; after
    ``reinit_epochs`` such epochs the engine restarts from a single-epoch solution, says so
    in the diagnostics and converges on the new position. With the guard off it stays put
    (the integrity monitor off: it would catch the jump first, see the next test)."""
    track = np.vstack([np.tile([8.0, 9.0, 1.5], (15, 1)), np.tile([30.0, 25.0, 1.5], (25, 1))])
    cfg = Config.of(robust="postfit", dynamics="static", init_sigma_m=0.5, reinit_epochs=3)
    pos, diag = _run(cfg, track, integrity=False)
    events = [d for d in diag if d.kind == "event"]
    assert [d.dd for d in events] == ["reinit"] and 15 < events[0].t_s <= 15 + 4
    assert np.linalg.norm(pos[-1] - track[-1]) < 0.5
    stuck, diag_off = _run(cfg.updated(reinit_epochs=0), track, integrity=False)
    assert not [d for d in diag_off if d.kind == "event"]
    assert np.linalg.norm(stuck[-1] - track[-1]) > 5.0


def test_the_integrity_monitor_catches_a_jump_at_once() -> None:
    """The same 30 m jump with the monitor on (and the old guard off): the prediction fails
    its χ² test against the epoch's snapshot on the first epoch after the jump, the prior is
    widened (an ``integrity`` row with the test value), re-initialised from the snapshot when
    that does not reconcile them, and the filter is within 1.5 m of the new position three
    epochs after the jump (the pseudolites' weak vertical) and within 0.5 m at the end."""
    track = np.vstack([np.tile([8.0, 9.0, 1.5], (15, 1)), np.tile([30.0, 25.0, 1.5], (25, 1))])
    cfg = Config.of(robust="postfit", dynamics="static", init_sigma_m=0.5, reinit_epochs=0)
    pos, diag = _run(cfg, track)
    rows = [d for d in diag if d.kind == "integrity"]
    assert rows and rows[0].t_s == 15.0 and rows[0].std_residual > chi2_ppf(0.999, 3)
    assert all(np.linalg.norm(p - track[-1]) < 1.5 for p in pos[18:])
    assert np.linalg.norm(pos[-1] - track[-1]) < 0.5
    assert all(d.t_s >= 15.0 for d in rows)  # no false alarm before the jump


def test_auto_dynamics_average_a_parked_receiver_like_the_static_model() -> None:
    track = np.tile([8.0, 9.0, 1.5], (60, 1))
    static, _ = _run(Config.of(robust="none", dynamics="static"), track, seed=3)
    auto, _ = _run(Config.of(robust="none", dynamics="auto"), track, seed=3)
    # the IMM (algorithms.md §32) mixes in the moving models with their small probabilities:
    # within a centimetre of the static solution, and as accurate
    assert np.max(np.abs(auto - static)) < 0.02
    err = {
        k: np.sqrt(np.mean(np.sum((v[10:] - track[10:]) ** 2, axis=1)))
        for k, v in (("a", auto), ("s", static))
    }
    assert err["a"] <= 1.1 * err["s"]


def test_auto_dynamics_follow_a_moving_receiver() -> None:
    t = np.arange(80.0)
    track = np.c_[5.0 + 0.2 * t, 5.0 + 0.1 * t, np.full_like(t, 1.5)]  # 0.22 m/s after a stop
    track[:20] = track[20]
    cfg = Config.of(robust="none", dynamics="auto", sigma_acc_m_s2=0.5)
    auto, _ = _run(cfg, track, seed=4)
    static, _ = _run(Config.of(robust="none", dynamics="static"), track, seed=4, integrity=False)
    err_auto = np.linalg.norm(auto[40:] - track[40:], axis=1)
    err_static = np.linalg.norm(static[40:] - track[40:], axis=1)
    # a hard choice restarts the velocity from zero after each parked-looking epoch: a lag of
    # decimetres for a slow walker, where the static model drifts away by metres
    assert np.max(err_auto) < 1.0 and np.max(err_static) > 4.0


def test_yang_factor_reference_values() -> None:
    assert yang_factor(0.5, 1.0, 2.5) == 1.0
    assert yang_factor(1.0, 1.0, 2.5) == 1.0
    assert yang_factor(2.0, 1.0, 2.5) == pytest.approx(0.5 * (0.5 / 1.5) ** 2)
    assert yang_factor(3.0, 1.0, 2.5, floor=1e-3) == 1e-3
    assert yang_factor(float("nan"), 1.0, 2.5, floor=1e-3) == 1e-3


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**31 - 1), st.integers(8, 40))
def test_robust_innovation_ratio_is_one_for_right_priors_and_ignores_one_outlier(seed: int, m: int) -> None:
    rng = np.random.default_rng(seed)
    s = rng.uniform(0.2, 3.0, m)
    d = rng.normal(0.0, s)
    S = np.diag(s**2)
    r = robust_innovation_ratio(d, S)
    # r = median|zᵢ| / 0.6745 of m standard normals. Bounds it leaves with probability
    # below 1e-4 per example: 0.2 < r < 3 needs at least half the rows below |z| = 0.135
    # (p = 0.107 each) or above 2.02 (p = 0.043), about 1e-5 for m = 20 but 3e-3 for m = 8;
    # for fewer rows 0.05 < r < 4 (|z| below 0.034, p = 0.027, or above 2.7).
    lo, hi = (0.2, 3.0) if m >= 20 else (0.05, 4.0)
    assert lo < r < hi
    d_bad = d.copy()
    d_bad[0] += 1e4
    assert robust_innovation_ratio(d_bad, S) < 4.0  # a median: one gross row barely moves it
    assert robust_innovation_ratio(d + 50.0 * s, S) > 20.0  # a dynamics error moves every row
    assert not MotionSelector().moving(d, S) or r > 2.0
    assert InnovationAdaptiveFactor().scale(None, d + 50.0 * s, S, S) == pytest.approx(1e4)


def test_moving_base_rtk_gives_the_known_base_baseline(shared_data: Path) -> None:
    """mosaicx5 in moving-base mode (base position from its own SPP each epoch): the fixed
    baselines equal those of the known-base RTK to 1 cm (95 %)."""
    from robustrtk.geometry.frames import geodetic2ecef_deg
    from robustrtk.pipeline.base_position import own_solution_track
    from robustrtk.pipeline.gnss_inputs import load_obs, nav_source
    from robustrtk.pipeline.rtk_gnss import rtk_gnss_config, solve_rtk

    d = shared_data / "mosaicx5_static_1m"
    base = geodetic2ecef_deg(35.134707705, 136.977577939, 104.853)
    known = solve_rtk(d / "rover.obs", d / "base.obs", [d / "base.nav"], base, rtk_gnss_config())
    moving = solve_rtk(d / "rover.obs", d / "base.obs", [d / "base.nav"], None,
                       rtk_gnss_config(base_position="moving"))  # fmt: skip
    track = own_solution_track(load_obs(d / "base.obs", None), nav_source([d / "base.nav"]), 15.0)
    a = {s.t_s: s.pos_m - base for s in known.solutions if s.status == "fixed"}
    b = {s.t_s: s.pos_m - track.position(s.t_s) for s in moving.solutions if s.status == "fixed"}
    common = sorted(set(a) & set(b))
    diff = np.array([np.linalg.norm(a[t] - b[t]) for t in common])
    p95 = float(np.percentile(diff, 95))
    print(f"\nmoving base: {len(b)} fixed (known base {len(a)}); baseline difference p95 {p95:.4f} m")
    assert len(common) >= 0.9 * len(a)
    assert np.percentile(diff, 95) <= 0.01
    # the base really moved with its own solution (metres of SPP noise), yet the baseline held
    spread = np.nanstd(np.array([track.position(t) for t in common]), axis=0)
    assert np.max(spread) > 0.1


def _room_batch(pos: np.ndarray, rng: np.random.Generator, n: int = 40) -> ObsBatch:
    """``n`` epochs at 1 s of one receiver at ``pos`` in the test room."""
    eps = [_epoch(float(k), pos, rng) for k in range(n)]
    e0 = eps[0]
    return ObsBatch(
        t_s=np.arange(float(n)), tx_ids=e0.tx_ids, system=e0.system, signals=e0.signals,
        code_m=np.stack([e.code_m for e in eps]), phase_cyc=np.stack([e.phase_cyc for e in eps]),
        doppler_hz=np.stack([e.doppler_hz for e in eps]), cn0_dbhz=np.stack([e.cn0_dbhz for e in eps]),
        lli=np.stack([e.lli for e in eps]), wavelength_m=np.stack([e.wavelength_m for e in eps]),
    )  # fmt: skip


def test_smoother_on_a_static_room_gives_every_epoch_the_final_estimate() -> None:
    """Static dynamics: the RTS-smoothed position of every epoch is (almost) the last
    forward estimate, which has seen all the data; forward epochs differ from it."""
    from robustrtk.pipeline.loop import run_dd

    rng = np.random.default_rng(7)
    truth = np.array([8.0, 9.0, 1.5])

    rover, base = _room_batch(truth, rng), _room_batch(BASE, rng)
    cfg = Config.of(robust="none", dynamics="static", init_sigma_m=5.0)
    # the forward covariance as the filter has it (no floor from each epoch's snapshot)
    off = IntegrityPolicy(enabled=False)
    eng = DDEngine(cfg, SurveyedSource(TX), BASE, truth + 1.0, reference="PL5", integrity=off)
    fwd = run_dd(rover, base, cfg, SurveyedSource(TX), BASE, truth + 1.0, engine=eng)
    cfg_s = cfg.updated(smoother=True)
    eng = DDEngine(cfg_s, SurveyedSource(TX), BASE, truth + 1.0, reference="PL5", integrity=off)
    smo = run_dd(rover, base, cfg_s, SurveyedSource(TX), BASE, truth + 1.0, engine=eng)
    f = np.array([s.pos_m for s in fwd.solutions])
    s = np.array([s.pos_m for s in smo.solutions])
    assert smo.info.get("smoothed") is True
    np.testing.assert_allclose(s[-1], f[-1], atol=1e-9)  # the last epoch: smoothed = filtered
    np.testing.assert_allclose(s, np.tile(f[-1], (40, 1)), atol=1e-3)
    assert np.max(np.linalg.norm(f - f[-1], axis=1)) > 0.01
    # and the smoothed covariance is that of all the data at every epoch
    np.testing.assert_allclose(smo.solutions[0].cov_m2, fwd.solutions[-1].cov_m2, rtol=1e-3)


def test_state_adaptive_factor_follows_a_walker_under_a_static_model() -> None:
    """A walker (0.22 m/s after a 20 s stop) filtered with the static model and the robust
    post-fit test: without the factor the filter drifts 13 m behind; with ``adaptive = state``
    it lags by at most about two σ of a single-epoch fit (algorithms.md §23: the passes widen
    the prior to the floor once the discrepancy exceeds ~2 c0 σ̃; here 1.2 m). One
    ``adaptive`` row per epoch: the prediction is widened while walking."""
    t = np.arange(80.0)
    track = np.c_[5.0 + 0.2 * t, 5.0 + 0.1 * t, np.full_like(t, 1.5)]
    track[:20] = track[20]
    cfg = Config.of(robust="postfit", dynamics="static", reinit_epochs=0)
    off, diag_off = _run(cfg, track, seed=4, integrity=False)
    on, diag = _run(cfg.updated(adaptive="state"), track, seed=4, integrity=False)
    err_off = np.linalg.norm(off[40:] - track[40:], axis=1)
    err_on = np.linalg.norm(on[40:] - track[40:], axis=1)
    assert np.max(err_off) > 10.0 and np.max(err_on) < 1.5 and np.mean(err_on) < 1.0
    rows = [d for d in diag if d.kind == "adaptive"]
    assert [d.t_s for d in rows] == list(t) and not [d for d in diag_off if d.kind == "adaptive"]
    widen = np.array([d.factor for d in rows])
    assert np.all(widen >= 1.0) and np.all([d.situation == 0 for d in rows])
    assert np.mean(widen[25:] > 1.0) > 0.1 and np.all(widen <= 1e3 * (1 + 1e-9))


def test_state_adaptive_factor_leaves_a_parked_receiver_alone() -> None:
    track = np.tile([8.0, 9.0, 1.5], (60, 1))
    cfg = Config.of(robust="postfit", dynamics="static")
    off, _ = _run(cfg, track, seed=3)
    on, diag = _run(cfg.updated(adaptive="state"), track, seed=3)
    widen = np.array([d.factor for d in diag if d.kind == "adaptive"])
    assert widen.size == 60 and np.mean(widen > 1.0) < 0.1
    np.testing.assert_allclose(on[20:], off[20:], atol=0.02)


def test_reindex_moves_rows_and_fills_the_missing_ones() -> None:
    from robustrtk.pipeline.engine import reindex

    rng = np.random.default_rng(3)
    src = ("G01", "G02", "E05", "G02")  # a repeated name: its first row is taken
    n = len(src)

    def cells() -> np.ndarray:
        return rng.normal(size=(n, 2))

    ep = ObsEpoch(
        t_s=12.5, tx_ids=src, system=("G", "G", "E", "G"), signals=("1C", "2W"), code_m=cells(),
        phase_cyc=cells(), doppler_hz=cells(), cn0_dbhz=cells(),
        lli=rng.integers(0, 3, (n, 2)).astype(np.int8), wavelength_m=cells(), code_sigma_m=cells(),
        phase_sigma_cyc=None,
    )  # fmt: skip
    dst = ("E05", "C01", "G02", "G01")
    for _ in range(2):  # the second call takes the remembered row map
        out = reindex(ep, dst)
        assert out.tx_ids == dst and out.system == ("E", "P", "G", "G")
        assert out.t_s == ep.t_s and out.signals == ep.signals and out.phase_sigma_cyc is None
        for name in ("code_m", "phase_cyc", "doppler_hz", "cn0_dbhz", "wavelength_m", "code_sigma_m"):
            a, b = getattr(ep, name), getattr(out, name)
            np.testing.assert_array_equal(b[[0, 2, 3]], a[[2, 1, 0]])
            assert np.all(np.isnan(b[1]))
        assert out.lli.dtype == np.int8
        np.testing.assert_array_equal(
            out.lli, np.stack([ep.lli[2], np.zeros(2, np.int8), ep.lli[1], ep.lli[0]])
        )
    assert reindex(ep, src) is ep


def test_auto_dynamics_with_the_smoother_smooths() -> None:
    """``auto`` runs the IMM forward; with the RTS smoother on it runs the one-model selector
    the smoother can follow, so the smoothed static room is closer to the truth than the
    forward pass (the IMM mixture's spread would leave the smoother without gain)."""
    from robustrtk.pipeline.loop import run_dd

    rng = np.random.default_rng(11)
    truth = np.array([8.0, 9.0, 1.5])

    rover, base = _room_batch(truth, rng), _room_batch(BASE, rng)
    cfg = Config.of(robust="none", dynamics="auto", init_sigma_m=5.0)
    off = IntegrityPolicy(enabled=False)
    eng = DDEngine(cfg, SurveyedSource(TX), BASE, truth + 1.0, reference="PL5", integrity=off)
    assert eng.imm is not None
    fwd = run_dd(rover, base, cfg, SurveyedSource(TX), BASE, truth + 1.0, engine=eng)
    cfg_s = cfg.updated(smoother=True)
    eng = DDEngine(cfg_s, SurveyedSource(TX), BASE, truth + 1.0, reference="PL5", integrity=off)
    assert eng.imm is None
    smo = run_dd(rover, base, cfg_s, SurveyedSource(TX), BASE, truth + 1.0, engine=eng)
    assert smo.info.get("smoothed") is True
    err_f = np.linalg.norm(np.array([s.pos_m for s in fwd.solutions]) - truth, axis=1)
    err_s = np.linalg.norm(np.array([s.pos_m for s in smo.solutions]) - truth, axis=1)
    assert np.mean(err_s[:20]) < 0.5 * np.mean(err_f[:20])
