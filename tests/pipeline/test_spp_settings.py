"""Every SPP setting of the Config tree acts on real data (Pixel 5 drive, 200 epochs), the
estimator follows ``filter``, and the Kalman SPP's lock-up guard re-initialises it."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from robustrtk.core import InputError, ObsBatch
from robustrtk.estimation.integrity import IntegrityPolicy
from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.geometry.los import geometric_range
from robustrtk.io.rinex_nav import read_rinex_nav
from robustrtk.io.rinex_obs import read_rinex_obs
from robustrtk.pipeline.base_position import first_fix_position
from robustrtk.pipeline.config import Config, preset
from robustrtk.pipeline.gnss import solve_spp_file
from robustrtk.pipeline.spp import SppEpoch, select_band1, solve_spp, solve_spp_kalman

PIXEL = "gsdc2021_mtv1_pixel5_phone/Pixel5/supplemental"
GEONET = "geonet_0759_3040_static_3km"
LSQ = preset("spp")
KALMAN = preset("spp").updated(filter="ekf")


def _epochs(b: ObsBatch, s: slice) -> ObsBatch:
    return replace(
        b,
        t_s=b.t_s[s],
        code_m=b.code_m[s].copy(),
        phase_cyc=b.phase_cyc[s].copy(),
        doppler_hz=b.doppler_hz[s].copy(),
        cn0_dbhz=b.cn0_dbhz[s],
        lli=b.lli[s],
    )


@pytest.fixture(scope="module")
def drive(shared_data: Path) -> tuple[ObsBatch, EphemerisSource]:
    """Epochs 300-499 of the phone drive (the car moving, C/N0 recorded)."""
    b = read_rinex_obs(shared_data / PIXEL / "Pixel5_GnssLog.21o")
    eph = EphemerisSource(read_rinex_nav(shared_data / PIXEL / "hour1180.21n"))
    return _epochs(b, slice(300, 500)), eph


@pytest.fixture(scope="module")
def base_runs(drive: tuple) -> dict[str, list[SppEpoch]]:
    b, eph = drive
    return {"lsq": solve_spp(b, eph, LSQ), "kalman": solve_spp_kalman(b, eph, KALMAN)}


def _positions(sols: list[SppEpoch]) -> np.ndarray:
    return np.array([s.pos_ecef_m for s in sols])


def _max_change(a: list[SppEpoch], b: list[SppEpoch]) -> float:
    d = np.abs(_positions(a) - _positions(b))
    return float(np.nanmax(d)) if np.isfinite(d).any() else 0.0


KALMAN_SETTINGS = [
    {"code_sigma_m": 1.0},
    {"robust": "none"},
    {"robust": "igg3"},
    {"k0": 1.0, "k1": 2.0},
    {"elev_mask_deg": 25.0},
    {"snr_mask_dbhz": 30.0},
    {"tropo": "off"},
    {"iono": "off"},
    {"sigma_acc_m_s2": 0.3},
    {"phase_sigma_m": 0.5},
    {"doppler_weighting": "elevation"},
]


@pytest.mark.parametrize(
    "setting", KALMAN_SETTINGS, ids=lambda kw: ",".join(f"{k}={v}" for k, v in kw.items())
)
def test_kalman_setting_changes_the_track(drive: tuple, base_runs: dict, setting: dict) -> None:
    b, eph = drive
    changed = solve_spp_kalman(b, eph, KALMAN.updated(**setting))
    assert _max_change(base_runs["kalman"], changed) > 0.5


def test_kalman_doppler_sigma_sets_the_start_the_data_the_level(drive: tuple, base_runs: dict) -> None:
    """The Doppler rows' σ is rescaled by the running robust scale of their own residuals
    (algorithms.md §41): a configured σ ten times larger still changes the track (the first
    rows, before the scale has 50 residuals), but far less than the 0.5 m of the settings above."""
    b, eph = drive
    changed = solve_spp_kalman(b, eph, KALMAN.updated(doppler_cn0_sigma_m_s=0.5))
    assert 0.01 < _max_change(base_runs["kalman"], changed) < 0.5


def test_kalman_ukf_differs_from_ekf_only_by_linearisation(drive: tuple, base_runs: dict) -> None:
    """The UKF runs (its own update) but the rows are linearised at the prior, so it agrees
    with the EKF to well under a millimetre."""
    b, eph = drive
    ukf = solve_spp_kalman(b, eph, KALMAN.updated(filter="ukf"))
    change = _max_change(base_runs["kalman"], ukf)
    assert 0.0 < change < 1e-3


LSQ_SETTINGS = [
    {"elev_mask_deg": 25.0},
    {"snr_mask_dbhz": 30.0},
    {"tropo": "off"},
    {"iono": "off"},
]


@pytest.mark.parametrize("setting", LSQ_SETTINGS, ids=lambda kw: ",".join(f"{k}={v}" for k, v in kw.items()))
def test_lsq_setting_changes_the_positions(drive: tuple, base_runs: dict, setting: dict) -> None:
    b, eph = drive
    changed = solve_spp(b, eph, LSQ.updated(**setting))
    assert _max_change(base_runs["lsq"], changed) > 0.5


def test_lsq_code_sigma_scales_the_covariance_and_the_fde_test(drive: tuple, base_runs: dict) -> None:
    """A common σ leaves the weighted solution alone but scales its covariance by σ² and
    makes the chi-square test stricter (more exclusions)."""
    b, eph = drive
    base = base_runs["lsq"]
    tight = solve_spp(b, eph, LSQ.updated(code_sigma_m=1.0))
    ratio = [t.cov_m2[0, 0] / s.cov_m2[0, 0] for s, t in zip(base, tight, strict=True) if not t.excluded]
    assert np.allclose(ratio, 1.0 / 9.0, rtol=1e-6)
    assert sum(len(t.excluded) for t in tight) > sum(len(s.excluded) for s in base)


def test_lsq_robust_none_turns_fde_off(drive: tuple) -> None:
    b, eph = drive
    cfg = LSQ.updated(code_sigma_m=1.0)
    fde = solve_spp(b, eph, cfg)
    none = solve_spp(b, eph, cfg.updated(robust="none"))
    assert any(s.excluded for s in fde)
    assert not any(s.excluded for s in none)
    assert _max_change(fde, none) > 0.5


def test_filter_picks_the_estimator(shared_data: Path, drive: tuple, base_runs: dict) -> None:
    b, eph = drive
    lsq = solve_spp_file(b, eph, LSQ)
    kalman = solve_spp_file(b, eph, KALMAN)
    assert _max_change(lsq, solve_spp(select_band1(b), eph, LSQ)) == 0.0
    assert _max_change(kalman, base_runs["kalman"]) == 0.0
    assert kalman[50].vel_ecef_m_s is not None and lsq[50].vel_ecef_m_s is None
    with pytest.raises(InputError, match="ekf or ukf"):
        solve_spp_kalman(b, eph, LSQ)


def test_first_fix_position_uses_the_mask(shared_data: Path) -> None:
    b = read_rinex_obs(shared_data / GEONET / "07590920.05o")
    eph = EphemerisSource(read_rinex_nav(shared_data / GEONET / "30400920.05n"))
    truth = np.array([-3976219.1879, 3382371.6056, 3652511.1425])
    p15 = first_fix_position(b, eph, 15.0)
    assert np.linalg.norm(p15 - truth) < 15.0
    assert np.linalg.norm(first_fix_position(b, eph, 30.0) - p15) > 0.1


def _teleport(
    shared: Path, jump_epoch: int
) -> tuple[ObsBatch, EphemerisSource, np.ndarray, np.ndarray, Config]:
    """Twenty geonet epochs of noise-free code of a receiver that jumps 374 m at
    ``jump_epoch`` (code only, no atmosphere), and a Kalman config whose near-zero
    acceleration noise makes the filter reject the new position's codes."""
    eph = EphemerisSource(read_rinex_nav(shared / GEONET / "30400920.05n"))
    b = _epochs(select_band1(read_rinex_obs(shared / GEONET / "07590920.05o")), slice(0, 20))
    b.phase_cyc[:] = np.nan
    b.doppler_hz[:] = np.nan
    start = np.array([-3976219.1879, 3382371.6056, 3652511.1425])
    jump = np.array([300.0, -200.0, 100.0])
    truth = np.array([start + (jump if i >= jump_epoch else 0.0) for i in range(len(b))])
    for i in range(len(b)):
        have = np.isfinite(b.code_m[i, :, 0])
        ids = [b.tx_ids[j] for j in np.flatnonzero(have)]
        code = b.code_m[i, have, 0]
        for _ in range(3):
            pos, sat_clk = eph.positions(float(b.t_s[i]), ids, code)
            rng, _ = geometric_range(pos, truth[i])
            code = rng + 1000.0 - sat_clk
        b.code_m[i, have, 0] = code
    cfg = KALMAN.updated(
        iono="off", tropo="off", code_sigma_m=0.3, use_cn0=False, elev_mask_deg=0.0, use_doppler=False,
        use_phase=False, dual_frequency=False, sigma_acc_m_s2=1e-4, sigma_acc_up_m_s2=1e-4, reinit_m=100.0,
    )  # fmt: skip
    return b, eph, truth, start, cfg


def test_kalman_integrity_monitor_catches_a_teleport_at_once(shared_data: Path) -> None:
    """The same 374 m jump with the old guard off: the predicted position fails its χ² test
    against the epoch's least squares on the jump epoch itself, the prior is widened (an
    ``inflate`` event with the test value) and no epoch is more than 0.2 m off."""
    b, eph, truth, _, cfg = _teleport(shared_data, jump_epoch=8)
    events: list = []
    sols = solve_spp_kalman(b, eph, cfg.updated(reinit_epochs=0), events=events)
    err = np.linalg.norm(_positions(sols) - truth, axis=1)
    assert np.all(err < 0.2)
    t8 = float(b.t_s[8])
    assert events and events[0][0] == t8 and events[0][1].kind == "inflate"
    assert events[0][1].test > IntegrityPolicy().threshold
    assert all(t >= t8 for t, _ in events)  # no false alarm before the jump


def test_kalman_lockup_guard_reinitialises_after_reinit_epochs(shared_data: Path) -> None:
    b, eph, truth, _, cfg = _teleport(shared_data, jump_epoch=8)

    def errors(reinit: int) -> np.ndarray:  # the integrity monitor off: it would catch the jump first
        sols = solve_spp_kalman(
            b, eph, cfg.updated(reinit_epochs=reinit), integrity=IntegrityPolicy(enabled=False)
        )
        return np.linalg.norm(_positions(sols) - truth, axis=1)

    never, two, five = errors(0), errors(2), errors(5)
    assert np.all(never[:8] < 0.01) and np.all(never[8:] > 300.0)  # locked on the old position
    # re-initialised from least squares at the reinit_epochs-th epoch in a row that disagrees
    assert np.all(two[8:9] > 300.0) and np.all(two[9:] < 0.01)
    assert np.all(five[8:12] > 300.0) and np.all(five[12:] < 0.01)
