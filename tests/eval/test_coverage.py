"""σ coverage: the share of epochs whose error the reported σ covers."""

from __future__ import annotations

import numpy as np

from robustrtk.eval.cli_support import coverage_text
from robustrtk.eval.metrics import sigma_coverage
from robustrtk.io.solution import SolutionTable


def test_coverage_of_gaussian_errors_is_the_normal_fraction() -> None:
    rng = np.random.default_rng(0)
    std = np.abs(rng.normal(1.0, 0.3, (20000, 3))) + 0.1
    err = rng.normal(size=(20000, 3)) * std
    c = sigma_coverage(err, std)
    for a in range(3):  # P(|N(0,1)| ≤ 3) = 0.9973
        assert abs(c[f"axis{a}"] - 0.9973) < 0.002
    assert abs(c["all"] - 0.9973**3) < 0.003
    # σ ten times too small covers far less
    assert sigma_coverage(err, std / 10.0)["all"] < 0.05


def test_coverage_counts_axes_separately_and_skips_nan() -> None:
    err = np.array([[0.1, 0.0, 0.0], [0.0, 5.0, 0.0], [np.nan, 0.0, 0.0], [0.0, 0.0, 0.31]])
    std = np.full((4, 3), 0.1)
    c = sigma_coverage(err, std)
    assert c["n"] == 3
    assert c["axis0"] == 1.0 and abs(c["axis1"] - 2 / 3) < 1e-12 and abs(c["axis2"] - 2 / 3) < 1e-12
    assert abs(c["all"] - 1 / 3) < 1e-12


def test_coverage_table_per_status() -> None:
    n = 4
    sol = SolutionTable(
        t_s=np.arange(n, dtype=float), pos_m=np.zeros((n, 3)), std_m=np.full((n, 3), 0.01),
        status=np.array(["fixed", "fixed", "float", "fixed"]), n_used=np.zeros(n, int),
        ratio=np.zeros(n), n_fixed=np.zeros(n, int), n_amb=np.zeros(n, int),
    )  # fmt: skip
    err = np.zeros((n, 3))
    err[1, 0] = 2.0  # a fixed epoch 2 m off with a 1 cm σ
    text = coverage_text(sol, err)
    rows = {line.split()[0]: line.split() for line in text.splitlines()[3:]}
    assert rows["fixed"][1] == "3" and abs(float(rows["fixed"][2]) - 100.0 * 2 / 3) < 1e-3
    assert float(rows["float"][5]) == 100.0 and rows["all"][1] == "4"
    sol_nan = SolutionTable(**{**sol.__dict__, "std_m": np.full((n, 3), np.nan)})
    assert coverage_text(sol_nan, err) == ""
