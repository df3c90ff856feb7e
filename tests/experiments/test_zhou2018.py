"""``robustrtk experiment zhou2018``: results.json and report.md recounted from runs.npz.

The recount below is written independently of :mod:`robustrtk.experiments.zhou2018.metrics`
(explicit loops over runs and epochs); the claims are re-derived from the recounted numbers.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from click.testing import CliRunner

from robustrtk.cli.main import main as cli_main
from robustrtk.experiments.zhou2018.metrics import axis_rms

FILTERS = ("ls", "ekf", "ukf", "pf")
TIE = 0.99  # a claim A < B needs A below 99 % of B
MODES = ("off", "traditional", "improved")


def test_axis_rms_brute_force() -> None:
    rng = np.random.default_rng(0)
    e = rng.normal(0, 3, (4, 9, 3))
    e[1, 2] = np.nan
    e[3, :, :] = np.nan
    rows = [r for r in e.reshape(-1, 3) if np.all(np.isfinite(r))]
    want = [math.sqrt(sum(r[j] ** 2 for r in rows) / len(rows)) for j in range(3)]
    np.testing.assert_allclose(axis_rms(e), want, rtol=1e-12)
    assert np.all(np.isnan(axis_rms(np.full((2, 3), np.nan))))


def _rms3(pos: np.ndarray, truth: np.ndarray) -> tuple[list[float], float, float]:
    """Per-axis RMS, 3D RMS and solved fraction over (R, T, 3) by explicit loops."""
    ss = [0.0, 0.0, 0.0]
    n = tot = 0
    for r in range(pos.shape[0]):
        for k in range(pos.shape[1]):
            tot += 1
            e = pos[r, k] - truth[r]
            if np.all(np.isfinite(e)):
                n += 1
                for j in range(3):
                    ss[j] += float(e[j]) ** 2
    rms = [math.sqrt(v / n) if n else math.nan for v in ss]
    return rms, math.sqrt(sum(v * v for v in rms)), n / tot


@pytest.fixture(scope="module")
def quick_run(shared_data: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, Any]]:
    out = tmp_path_factory.mktemp("zhou2018")
    nav = shared_data / "mosaicx5_static_1m" / "base.nav"
    res = CliRunner().invoke(
        cli_main,
        ["experiment", "zhou2018", "--quick", "--runs", "2", "--workers", "1", "--no-progress"]
        + ["--out", str(out), "--nav", str(nav)],
    )
    assert res.exit_code == 0, res.output
    return out, json.loads((out / "results.json").read_text(encoding="utf-8"))


@pytest.mark.slow
def test_results_recounted_from_runs(quick_run: tuple[Path, dict[str, Any]]) -> None:
    out, res = quick_run
    npz = np.load(out / "runs.npz")
    assert list(npz["seeds"]) == res["seeds"] == [0, 1]
    recount: dict[str, dict[str, float]] = {}
    for sc in ("clean", "degraded"):
        for f in FILTERS:
            for m in MODES:
                key = f"{f}/{m}"
                rms, r3, solved = _rms3(npz[f"{sc}/{key}/pos2"], npz[f"{sc}/truth2"])
                cell = res["stats"][sc][key]
                for a, b in zip(rms, cell["rms_xyz_m"], strict=True):
                    assert (b is None and math.isnan(a)) or a == pytest.approx(b, rel=1e-9)
                assert solved == pytest.approx(cell["solved_fraction"])
                per_run = [
                    _rms3(npz[f"{sc}/{key}/pos2"][r : r + 1], npz[f"{sc}/truth2"][r : r + 1])[1]
                    for r in range(2)
                ]
                for a, b in zip(per_run, cell["per_run_rms_3d_m"], strict=True):
                    assert (b is None and math.isnan(a)) or a == pytest.approx(b, rel=1e-9)
                recount.setdefault(sc, {})[key] = r3
    claims = {c["name"]: c for c in res["claims"]}
    for sc in ("clean", "degraded"):
        r = recount[sc]
        for m in ("traditional", "improved"):
            assert claims[f"PF best ({m}, {sc})"]["holds"] == (
                r[f"pf/{m}"] < min(r[f"ekf/{m}"], r[f"ukf/{m}"])
            )
            assert claims[f"UKF better than EKF ({m}, {sc})"]["holds"] == (
                r[f"ukf/{m}"] < TIE * r[f"ekf/{m}"]
            )
        for f in FILTERS:
            want = r[f"{f}/improved"] < TIE * r[f"{f}/traditional"]
            assert claims[f"improved better than traditional ({f}, {sc})"]["holds"] == want
    for f in ("ekf", "ukf", "pf"):
        ratio = recount["degraded"][f"{f}/improved"] / recount["clean"][f"{f}/improved"]
        assert claims[f"reset protects node 2 from node 1's fault ({f})"]["holds"] == (ratio <= 1.5)
        # node 1 with both cooperating, against its solution alone
        _, tr, _ = _rms3(npz[f"mutual/{f}/traditional/pos1"], npz["clean/truth1"])
        _, im, _ = _rms3(npz[f"mutual/{f}/improved/pos1"], npz["clean/truth1"])
        mu = res["node1_and_mutual"]["mutual"]
        assert mu[f"{f}/traditional"]["node1_rms_3d_m"] == pytest.approx(tr, rel=1e-9)
        assert claims[f"improved limits the mutual influence on node 1 ({f}, both cooperating)"]["holds"] == (
            im < tr
        )
    # the node-1 fault: exactly the spec's epochs, and the visibility summary
    assert np.flatnonzero(npz["degraded/fault1"][0]).tolist() == list(range(8, 14))
    assert res["visibility"]["node2_gps_max"] == int(npz["clean/n_gps2"].max()) <= 3


@pytest.mark.slow
def test_report_has_table2_beside_ours(quick_run: tuple[Path, dict[str, Any]]) -> None:
    out, res = quick_run
    rep = (out / "report.md").read_text(encoding="utf-8")
    for fn in res["figures"]:
        assert (out / fn).stat().st_size > 1000
    row = next(line for line in rep.splitlines() if line.startswith("| improved PF |"))
    assert "0.31 / 2.18 / 1.78" in row  # the paper's Table 2
    x, y, z = res["stats"]["clean"]["pf/improved"]["rms_xyz_m"]
    assert f"{x:.2f} / {y:.2f} / {z:.2f}" in row  # ours beside it
    n_claims = sum(
        1 for line in rep.splitlines() if line.startswith("| ") and (" | yes |" in line or " | NO |" in line)
    )
    assert n_claims == len(res["claims"])


def test_cli_bad_arguments(tmp_path: Path) -> None:
    r = CliRunner().invoke(cli_main, ["experiment", "zhou2018", "--runs", "0", "--out", str(tmp_path)])
    assert r.exit_code == 2 and r.output.strip().count("\n") == 0 and "--runs" in r.output
    r = CliRunner().invoke(
        cli_main,
        ["experiment", "zhou2018", "--nav", str(tmp_path / "none.nav"), "--out", str(tmp_path / "o")],
    )
    assert r.exit_code == 2 and "navigation file not found" in r.output and "Traceback" not in r.output


def test_the_seeds_on_dask_give_the_local_pool_s_runs(shared_data: Path, tmp_path: Path) -> None:
    """``--engine dask`` (a local cluster of two workers) against the process pool: the same
    runs, bit for bit; a scheduler with the local engine is refused in one line."""
    pytest.importorskip("distributed")
    nav = shared_data / "mosaicx5_static_1m" / "base.nav"
    if not nav.is_file():
        pytest.skip(f"mosaicx5 navigation file not found in {shared_data}")
    runs = {}
    for engine in ("local", "dask"):
        out = tmp_path / engine
        res = CliRunner().invoke(
            cli_main,
            ["experiment", "zhou2018", "--quick", "--runs", "2", "--workers", "2", "--engine", engine]
            + ["--no-progress", "--out", str(out), "--nav", str(nav)],
        )
        assert res.exit_code == 0, res.output
        with np.load(out / "runs.npz") as npz:
            runs[engine] = {k: npz[k] for k in npz.files}
    assert runs["local"].keys() == runs["dask"].keys()
    for k, v in runs["local"].items():
        np.testing.assert_array_equal(v, runs["dask"][k], err_msg=k)
    r = CliRunner().invoke(
        cli_main,
        ["experiment", "zhou2018", "--engine", "local", "--scheduler", "tcp://127.0.0.1:1"]
        + ["--out", str(tmp_path / "x"), "--nav", str(nav)],
    )
    assert r.exit_code == 2 and r.output.strip().count("\n") == 0 and "--scheduler" in r.output
