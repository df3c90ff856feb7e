"""The robust UKF on the demo pseudolite room does not diverge at a gross code error.

The room's four DD code rows over-determine the position by one; a 10 m error on one of them
at t = 583 s pulled the integrity snapshot's Gauss–Newton off to 10⁸ m with a covariance of
10¹⁷ m², the test against it came out infinite and the prior was widened 10¹² times — the
filter then sat hundreds of kilometres away to the end of the run. A snapshot with a
degenerate geometry (every row seen the same way from where the fit wandered) is no snapshot
(``estimation.integrity.robust_snapshot``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from robustrtk.eval.cli_support import read_truth_csv
from robustrtk.pipeline.config import Config
from robustrtk.pipeline.solve import solve_pseudolite
from robustrtk.sim.files import run_simulate


def test_robust_ukf_stays_in_the_room_through_every_fault(tmp_path: Path) -> None:
    run_simulate("demo", 1, tmp_path)
    t_truth, p_truth = read_truth_csv(tmp_path / "truth.csv")
    cfg = Config.of(mode="dpl", robust="igg3", ar="par", dynamics="kinematic")
    res = solve_pseudolite(tmp_path / "obs.csv", tmp_path / "site.toml", cfg)
    truth = {round(float(t), 3): p for t, p in zip(t_truth, p_truth, strict=True)}
    err = np.array([np.linalg.norm(s.pos_m - truth[round(s.t_s, 3)]) for s in res.solutions])
    assert err.size >= 590
    # the room is metres across: no epoch may leave it, and the faults move the track little
    assert err.max() < 10.0
    assert np.percentile(err, 95) < 3.0
