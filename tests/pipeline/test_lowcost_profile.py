"""The ``lowcost`` receiver profile: DGNSS of a u-blox M8P pair (galway s1, L1) with the code σ
the receivers' own code minus carrier shows — an honest σ where the geodetic preset's 0.3 m
hides metres of patch-antenna multipath."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from robustrtk.pipeline.config import PROFILES, profiled
from robustrtk.pipeline.gnss import dgnss_config, solve_dgnss

ROVER_TRUTH = np.array([3774088.6834, -601663.0382, 5089318.2298])
BASE = np.array([3774088.9004, -601662.8325, 5089318.0783])


def test_the_command_line_offers_every_profile() -> None:
    from robustrtk.cli.main import solve

    opt = next(p for p in solve.params if p.name == "profile")
    assert sorted(opt.type.choices) == sorted(PROFILES)  # type: ignore[attr-defined]


def test_the_code_estimate_is_on_in_dgnss_and_the_lowcost_profile() -> None:
    """The DGNSS preset estimates the code σ (used only where the configured one would have
    the robust test reject rows at one σ of the data, algorithms.md §38); the profile too."""
    cfg = dgnss_config()
    assert cfg.measurement.code_sigma_from_data
    assert profiled(cfg, "lowcost").measurement.code_sigma_from_data


@pytest.mark.slow
def test_lowcost_dgnss_sigma_covers_the_error(shared_data: Path) -> None:
    s1 = shared_data / "galway_m8p_l1_lowcost" / "s1_static"
    if not (s1 / "rover-20181004-1237.obs").is_file():
        pytest.skip(f"galway_m8p_l1_lowcost not found in {shared_data}")
    rover, base, nav = (
        s1 / f for f in ("rover-20181004-1237.obs", "base-20181004-1236_rtcm.obs", "rover-20181004-1237.nav")
    )

    def run(cfg: object) -> tuple[float, float, float]:
        res = solve_dgnss(rover, base, nav, BASE, cfg=cfg)  # type: ignore[arg-type]
        sols = [s for s in res.solutions if s.status != "none"]
        err = np.array([s.pos_m - ROVER_TRUTH for s in sols])
        sig = np.sqrt(np.array([np.diag(s.cov_m2) for s in sols]))
        covered = float(np.mean(np.all(np.abs(err) <= 3.0 * sig, axis=1)))
        return covered, float(np.sqrt(np.mean(np.sum(err**2, axis=1)))), float(res.info["code_sigma_m"])

    plain = run(dgnss_config(freqs="L1", code_sigma_from_data=False))
    low = run(profiled(dgnss_config(freqs="L1"), "lowcost"))
    assert plain[2] == pytest.approx(0.3) and low[2] > 1.0  # metres of patch-antenna code noise
    assert low[0] >= 0.99  # 3σ covers the error on every axis (84 % with the 0.3 m σ)
    assert low[1] < 0.5 * plain[1]  # and the weights it gives are better: 3-D RMS 4.4 m → 1.5 m
    assert run(dgnss_config(freqs="L1")) == low  # the DGNSS preset does the same
