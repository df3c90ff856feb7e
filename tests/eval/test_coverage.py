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


def test_coverage_compares_errors_in_the_frame_of_the_sigmas(tmp_path) -> None:
    """A GNSS solution's σ are ECEF: the errors the evaluator covers with them are ECEF too
    (ENU errors against ECEF σ would mix the axes). A point 3 m east of the truth with
    σ_E = 1.5 m and centimetre σ on the other local axes is covered (2σ east)."""
    from robustrtk.eval.cli_support import frame_errors
    from robustrtk.geometry.frames import ecef2enu_rotation, ecef2geodetic

    truth = np.array([-3976219.1879, 3382371.6056, 3652511.1425])
    lat, lon, _ = ecef2geodetic(truth)
    R = ecef2enu_rotation(float(lat), float(lon))
    cov_ecef = R.T @ np.diag([1.5**2, 0.01**2, 0.01**2]) @ R
    sol = SolutionTable(
        t_s=np.zeros(1), pos_m=(truth + R.T @ np.array([3.0, 0.0, 0.0]))[None],
        std_m=np.sqrt(np.diag(cov_ecef))[None],
        status=np.array(["single"]), n_used=np.zeros(1, int), ratio=np.zeros(1), n_fixed=np.zeros(1, int),
        n_amb=np.zeros(1, int),
    )  # fmt: skip
    p = tmp_path / "truth.txt"
    p.write_text(f"rover_xyz {truth[0]} {truth[1]} {truth[2]}   # a trailing comment\nbase_xyz 1 2 3\n")
    err = frame_errors(sol, p)
    np.testing.assert_allclose(err[0], R.T @ np.array([3.0, 0.0, 0.0]), atol=1e-6)
    assert sigma_coverage(err, sol.std_m)["all"] == 1.0
