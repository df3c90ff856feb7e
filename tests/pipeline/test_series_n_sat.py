"""``SolutionSeries.n_sat``: satellites used per epoch, the ``ns`` column of its ``.pos``."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from robustrtk.core import Solution
from robustrtk.io.solution import read_pos
from robustrtk.pipeline.series import SolutionSeries

_POS = np.array([-3961904.9, 3348993.8, 3698211.8])


def _sol(k: int, status: str, n_used: int, n_sat: int) -> Solution:
    return Solution(
        t_s=1.4e9 + k, pos_m=_POS + k, cov_m2=np.eye(3) * 1e-4, status=status, n_used=n_used, n_sat=n_sat
    )


def test_n_sat_counts_satellites_not_dd_rows(tmp_path: Path) -> None:
    """DD epochs count satellites (52 DD rows on 20 satellites give 20); single-point epochs,
    whose producer leaves ``n_sat`` 0, count their rows, which are satellites; the ``.pos``
    ``ns`` column and the DataFrame columns say the same."""
    sols = [_sol(0, "fixed", 52, 20), _sol(1, "float", 30, 12), _sol(2, "single", 8, 0)]
    s = SolutionSeries.from_solutions(sols, "rtk", frame="ecef")
    np.testing.assert_array_equal(s.n_sat, [20, 12, 8])
    np.testing.assert_array_equal(s.n_used, [52, 30, 8])
    np.testing.assert_array_equal(s.columns()["n_sat"], s.n_sat)
    s.to_pos(tmp_path / "x.pos")
    np.testing.assert_array_equal(read_pos(tmp_path / "x.pos").n_used, s.n_sat)


def test_n_sat_without_records_is_n_used() -> None:
    sols = [_sol(0, "single", 7, 0)]
    s = SolutionSeries.from_solutions(sols, "spp", frame="ecef")
    bare = SolutionSeries(s.t_s, s.pos_m, s.cov_m2, s.status, s.n_used, s.ratio, "ecef", "spp")
    np.testing.assert_array_equal(bare.n_sat, [7])
