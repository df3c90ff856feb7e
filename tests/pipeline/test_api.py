"""The top-level API: lazy import, SolutionSeries, settings, and agreement with the CLI."""

from __future__ import annotations

import subprocess
import sys
import types
from dataclasses import astuple
from datetime import datetime, timedelta
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as hst

import robustrtk
from robustrtk.core import InputError, Solution
from robustrtk.io.solution import read_pos, read_solution_csv
from robustrtk.pipeline.api import resolve_config
from robustrtk.pipeline.config import preset
from robustrtk.pipeline.results import DiagRow, RowTally
from robustrtk.pipeline.series import SolutionSeries, summarize

SRC = Path(__file__).resolve().parents[2] / "src"
GEONET_BASE = [-3978241.958, 3382840.234, 3649900.853]


def test_import_robustrtk_loads_no_numerical_library() -> None:
    code = (
        "import sys, robustrtk\n"
        "heavy = sorted(m for m in sys.modules\n"
        "    if m.split('.')[0] in ('numpy', 'scipy', 'matplotlib', 'click'))\n"
        "print(','.join(heavy))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, env={"PYTHONPATH": str(SRC)}
    )
    assert out.stdout.strip() == ""


def test_lazy_names_resolve_to_the_pipeline_objects() -> None:
    from robustrtk.pipeline import api

    assert robustrtk.solve_rtk is api.solve_rtk
    assert robustrtk.SolutionSeries is api.SolutionSeries
    assert "solve_dgnss" in dir(robustrtk)
    with pytest.raises(AttributeError, match="no attribute 'solve_nothing'"):
        _ = robustrtk.solve_nothing  # type: ignore[attr-defined]


def _ecef_solutions(rng: np.random.Generator, n: int = 40) -> list[Solution]:
    base = np.array([-3976219.1879, 3382371.6056, 3652511.1425])
    statuses = rng.choice(["fixed", "float", "partial", "none"], size=n, p=[0.5, 0.3, 0.1, 0.1])
    out = []
    for i, st in enumerate(statuses):
        a = rng.normal(size=(3, 3)) * 0.01
        pos = base + rng.normal(size=3) * 0.05 if st != "none" else np.full(3, np.nan)
        out.append(
            Solution(
                t_s=1.3e9 + 30.0 * i,
                pos_m=pos,
                cov_m2=a @ a.T + 1e-6 * np.eye(3),
                status=str(st),
                n_used=int(rng.integers(4, 20)),
                ratio=float(rng.uniform(1, 9)),
            )
        )
    return out


def test_series_arrays_and_counts_equal_a_recount() -> None:
    rng = np.random.default_rng(5)
    sols = _ecef_solutions(rng)
    s = SolutionSeries.from_solutions(sols, "rtk", frame="ecef")
    assert s.frame == "ecef" and len(s) == len(sols)
    for i, sol in enumerate(sols):
        assert s.status[i] == sol.status
        np.testing.assert_allclose(s.sigma_m[i], np.sqrt(np.diag(sol.cov_m2)))
    fixed = [x for x in sols if x.status in ("fixed", "partial")]
    assert s.fix_rate() == pytest.approx(len(fixed) / len(sols))
    assert s.time_to_first_fix_s() == pytest.approx(fixed[0].t_s - sols[0].t_s)
    summ = s.summary()
    assert summ.solved == sum(x.status != "none" for x in sols)
    assert sum(summ.by_status.values()) == len(sols)
    # σ east/north/up: the trace is rotation-invariant
    ok = s.solved
    np.testing.assert_allclose(
        np.sum(s.sigma_enu_m()[ok] ** 2, axis=1), np.trace(s.cov_m2[ok], axis1=1, axis2=2), rtol=1e-9
    )


def test_summary_counts_robust_flags_per_row_and_epoch() -> None:
    sols = [Solution(t_s=float(t), pos_m=np.zeros(3), cov_m2=np.eye(3), status="float") for t in range(3)]

    def row(t: float, factor: float, kind: str = "code") -> DiagRow:
        return DiagRow(t, "P2-P1", kind, 0.0, 0.0, 0.0, 0.0, factor, 0)

    diag = [
        row(0, 1.0),
        row(0, 2.5),
        row(1, float("inf")),
        row(1, 1.0),
        row(2, float("nan"), "event"),
        row(2, 1.0),
    ]
    summ = summarize(sols, diag)
    assert (summ.rows_downweighted, summ.rows_rejected, summ.epochs_flagged) == (1, 1, 2)
    assert np.isnan(summ.time_to_first_fix_s) and summ.fix_rate == 0.0


_FACTORS = hst.sampled_from([1.0, 1.0, 1.0, 1.5, 3.0, float("inf"), float("nan")])


@settings(max_examples=200, deadline=None)
@given(hst.lists(hst.lists(hst.tuples(_FACTORS, hst.booleans()), max_size=6), max_size=8))
def test_row_tally_counts_as_summarize_counts_the_rows(epochs: list[list[tuple[float, bool]]]) -> None:
    """A run that keeps no rows reports what the rows would have given: the tally, epoch by
    epoch, against :func:`summarize` over all rows (events, NaN factors, repeated flags)."""
    sols = [
        Solution(t_s=float(t), pos_m=np.zeros(3), cov_m2=np.eye(3), status="float")
        for t in range(len(epochs))
    ]
    tally = RowTally()
    rows: list[DiagRow] = []
    for t, epoch in enumerate(epochs):
        mine = [
            DiagRow(float(t), "G05-G02", "event" if ev else "phase", 0.0, 0.0, 0.0, 0.0, g, 1)
            for g, ev in epoch
        ]
        tally.add_epoch(mine)
        rows += mine
    counts = ("rows_downweighted", "rows_rejected", "epochs_flagged")
    from_rows = summarize(sols, rows)
    from_tally = summarize(sols, (), row_tally=tally.as_dict())
    assert [getattr(from_tally, k) for k in counts] == [getattr(from_rows, k) for k in counts]
    brute_down = sum(1 for d in rows if d.kind != "event" and 1.0 < d.factor < float("inf"))
    assert tally.rows_downweighted == brute_down


@pytest.mark.parametrize("mode", ["rtk", "dgnss"])
def test_a_run_that_keeps_no_rows_solves_and_summarizes_the_same(shared_data: Path, mode: str) -> None:
    d = shared_data / "geonet_0759_3040_static_3km"
    args = (d / "07590920.05o", d / "30400920.05o", d / "07590920.05n", GEONET_BASE)
    solve = robustrtk.solve_rtk if mode == "rtk" else robustrtk.solve_dgnss
    kept = solve(*args)
    lean = solve(*args, keep_diagnostics=False)
    assert len(kept.diagnostics) > len(kept) and lean.diagnostics == ()
    np.testing.assert_array_equal(lean.pos_m, kept.pos_m)
    assert list(lean.status) == list(kept.status)
    same = [
        a == b or (a != a and b != b)
        for a, b in zip(astuple(lean.summary()), astuple(kept.summary()), strict=True)
    ]
    assert all(same)  # NaN (no fix in DGNSS) counts as equal to NaN
    assert kept.summary().rows_downweighted + kept.summary().rows_rejected > 0  # the counts are tested


def test_to_pos_and_to_csv_read_back(tmp_path: Path) -> None:
    sols = _ecef_solutions(np.random.default_rng(7))
    s = SolutionSeries.from_solutions(sols, "rtk", frame="ecef")
    s.to_pos(tmp_path / "a.pos")
    s.to_csv(tmp_path / "a.csv")
    pos = read_pos(tmp_path / "a.pos")
    ok = s.solved
    np.testing.assert_allclose(pos.t_s, s.t_s[ok])
    np.testing.assert_allclose(pos.pos_m, s.pos_m[ok], atol=2e-4)  # 9 decimals of a degree
    assert list(pos.status) == [{"partial": "fixed"}.get(x, x) for x in s.status[ok]]
    csv = read_solution_csv(tmp_path / "a.csv")
    np.testing.assert_allclose(csv.pos_m[np.isfinite(csv.pos_m[:, 0])], s.pos_m[ok], atol=1e-4)


def test_local_series_refuses_geodetic_output(tmp_path: Path) -> None:
    sols = [Solution(t_s=0.0, pos_m=np.array([1.0, 2.0, 0.5]), cov_m2=np.eye(3), status="code")]
    s = SolutionSeries.from_solutions(sols, "dpl", frame="local")
    assert s.frame == "local"
    with pytest.raises(InputError, match="local frame"):
        s.to_pos(tmp_path / "x.pos")
    assert not (tmp_path / "x.pos").exists()
    assert list(s.columns())[:4] == ["t_s", "x_m", "y_m", "z_m"]


def test_series_frame_is_the_producers_not_a_guess(tmp_path: Path) -> None:
    """One wild epoch (far off the Earth) leaves an ECEF series ECEF: it is written with
    the others; a frame other than ecef/local is refused."""
    sols = _ecef_solutions(np.random.default_rng(11), 6)
    sols[2] = Solution(t_s=sols[2].t_s, pos_m=np.array([4.0e7, 1.0, 2.0]), cov_m2=np.eye(3), status="single")
    s = SolutionSeries.from_solutions(sols, "spp", frame="ecef")
    assert s.frame == "ecef"
    s.to_pos(tmp_path / "w.pos")
    assert read_pos(tmp_path / "w.pos").t_s.size == int(s.solved.sum())
    with pytest.raises(InputError, match="frame"):
        SolutionSeries.from_solutions(sols, "spp", frame="enu")


def test_columns_geodetic_and_gpst() -> None:
    s = SolutionSeries.from_solutions(_ecef_solutions(np.random.default_rng(3)), "rtk", frame="ecef")
    cols = s.columns()
    assert all(len(v) == len(s) for v in cols.values())
    # calendar arithmetic of the standard library, independent of numpy's datetime64
    want = datetime(1980, 1, 6) + timedelta(seconds=float(s.t_s[-1]))
    assert str(cols["gpst"][-1]) == want.strftime("%Y-%m-%dT%H:%M:%S.000000000")
    ok = s.solved
    assert np.all(np.abs(cols["lat_deg"][ok] - 35.16086) < 1e-3) and np.all(
        np.abs(cols["height_m"][ok] - 68) < 5
    )


def test_to_dataframe_without_pandas_says_how(monkeypatch: pytest.MonkeyPatch) -> None:
    s = SolutionSeries.from_solutions(_ecef_solutions(np.random.default_rng(1), 3), "rtk", frame="ecef")
    monkeypatch.setitem(sys.modules, "pandas", None)
    with pytest.raises(ImportError, match="pip install pandas"):
        s.to_dataframe()


def test_to_dataframe_hands_pandas_the_columns(monkeypatch: pytest.MonkeyPatch) -> None:
    s = SolutionSeries.from_solutions(_ecef_solutions(np.random.default_rng(1), 3), "rtk", frame="ecef")
    fake = types.ModuleType("pandas")
    fake.DataFrame = lambda data: ("frame", data)  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "pandas", fake)
    kind, data = s.to_dataframe()
    assert kind == "frame" and list(data) == list(s.columns())
    np.testing.assert_array_equal(data["status"], s.status)


def test_resolve_config_forms_agree_and_refuse(tmp_path: Path) -> None:
    (tmp_path / "c.toml").write_text("[ar]\nratio = 2.5\n")
    want = preset("rtk").updated(ratio=2.5)
    assert resolve_config(tmp_path / "c.toml", "rtk") == want
    assert resolve_config({"ratio": 2.5}, "rtk") == want
    assert resolve_config(want, "rtk") == want
    assert resolve_config(None, "dgnss") == preset("dgnss")
    with pytest.raises(InputError, match="does not apply to mode rtk"):
        resolve_config({"max_exclusions": 1}, "rtk")
    with pytest.raises(InputError, match="mode 'spp' given to the rtk"):
        resolve_config(preset("spp"), "rtk")
    with pytest.raises(InputError, match="unknown setting"):
        resolve_config({"ratoi": 2.0}, "rtk")


def test_api_rtk_equals_the_solve_command(shared_data: Path, tmp_path: Path) -> None:
    from robustrtk.cli.entry import run

    d = shared_data / "geonet_0759_3040_static_3km"
    rover, base, nav = d / "07590920.05o", d / "30400920.05o", d / "07590920.05n"
    sol = robustrtk.solve_rtk(rover, base, nav, GEONET_BASE, {"ratio": 2.5})
    xyz = ",".join(map(str, GEONET_BASE))
    out = tmp_path / "cli.pos"
    argv = ["solve", str(rover), "--base", str(base), "--nav", str(nav), "--base-pos", xyz, "--mode", "rtk",
            "--ratio", "2.5", "--quiet", "--out", str(out)]  # fmt: skip
    assert run(argv) == 0
    cli = read_pos(out)
    ok = sol.solved
    np.testing.assert_allclose(cli.pos_m, sol.pos_m[ok], atol=2e-4)
    assert list(cli.status) == [{"partial": "fixed"}.get(x, x) for x in sol.status[ok]]


def test_api_refuses_a_base_position_far_from_the_base(shared_data: Path) -> None:
    d = shared_data / "geonet_0759_3040_static_3km"
    far = np.array(GEONET_BASE) + [500.0, 0.0, 0.0]
    with pytest.raises(InputError, match="from the base's own single-point solution"):
        robustrtk.solve_dgnss(d / "07590920.05o", d / "30400920.05o", d / "07590920.05n", far)


class _Recorder:
    """A progress callback with the ``epoch`` method: gets each epoch's status."""

    def __init__(self) -> None:
        self.calls: list[tuple[int, int, str]] = []

    def __call__(self, done: int, total: int) -> None:  # pragma: no cover - epoch() is preferred
        raise AssertionError("the status-aware method should have been called")

    def epoch(self, done: int, total: int, status: str) -> None:
        self.calls.append((done, total, status))


def test_progress_gets_each_epochs_status_pseudolite() -> None:
    from robustrtk.sim.pseudolite import simulate
    from robustrtk.sim.scenario import load_scenario

    room = simulate(load_scenario("demo"), np.random.default_rng(0), n_epochs=60)
    rec = _Recorder()
    sol = robustrtk.solve_dpl(room.batches, room.site, {"ar": "lambda"}, mode="rtk", progress=rec)
    assert [c[0] for c in rec.calls] == list(range(1, len(sol) + 1))
    assert all(c[1] == len(sol) for c in rec.calls)
    assert [c[2] for c in rec.calls] == list(sol.status)


def test_progress_gets_each_epochs_status_spp(shared_data: Path) -> None:
    d = shared_data / "geonet_0759_3040_static_3km"
    rec = _Recorder()
    sol = robustrtk.solve_spp(d / "07590920.05o", d / "07590920.05n", progress=rec)
    assert [c[2] for c in rec.calls] == list(sol.status) and len(rec.calls) == len(sol)
