"""Long or surprising work is said: coop summary, smoothing stage, the --kalman hint, report spans."""

from __future__ import annotations

import io
from pathlib import Path
from types import SimpleNamespace

import numpy as np
from click.testing import CliRunner

from robustrtk.cli.coop import coop_summary
from robustrtk.cli.gnss import kalman_hint
from robustrtk.cli.main import main
from robustrtk.cli.progress import ProgressBar
from robustrtk.core import Solution
from robustrtk.eval.html_report import report_parts
from robustrtk.geometry.frames import geodetic2ecef
from robustrtk.io.solution import write_solution_csv


def test_bar_names_the_work_after_the_last_epoch() -> None:
    t = iter(np.arange(0.0, 100.0, 0.5))
    bar = ProgressBar("x", enabled=False, stream=io.StringIO(), after="RTS smoothing", clock=lambda: next(t))
    bar(5, 10)
    assert "RTS smoothing" not in bar.line()
    bar(10, 10)
    assert bar.line().endswith("RTS smoothing...")
    bar.close()
    assert "RTS smoothing" not in bar.line()  # the final frame states what was done


def _sols(center: np.ndarray, offsets_m: np.ndarray, sigma_m: float) -> list[Solution]:
    cov = np.eye(3) * sigma_m**2
    return [Solution(float(i), center + d, cov, "single", 6) for i, d in enumerate(offsets_m)]


def test_coop_summary_counts_and_spreads() -> None:
    c = np.array(geodetic2ecef(np.radians(35.0), np.radians(139.0), 50.0)).ravel()
    rng = np.random.default_rng(1)
    moved = _sols(c, rng.normal(0.0, 1.0, (200, 3)), 2.0)
    none = [Solution(0.0, np.full(3, np.nan), np.full((3, 3), np.nan), "none")]
    text = coop_summary({"peer": moved, "node": moved[:100] + none}, 3.25)
    lines = text.splitlines()
    assert lines[0].startswith("accuracy")
    assert "peer         200/200 epochs solved; σ_H median 2.83 m" in lines[1]  # sqrt(2) · 2 m
    assert "node         100/101 epochs solved" in lines[2]
    h95 = float(lines[1].split("H95 about its median position ")[1].split(" m")[0])
    assert 1.8 < h95 < 3.0  # Rayleigh 95 % of σ = 1 m horizontal: 2.45 m
    assert lines[-1] == "  time 3.2 s"


def _batch(doppler_share: float) -> SimpleNamespace:
    code = np.full((10, 8, 1), 2.2e7)
    dop = np.full(code.shape, np.nan)
    dop.reshape(-1)[: int(doppler_share * code.size)] = 100.0
    return SimpleNamespace(code_m=code, doppler_hz=dop)


def test_kalman_hint_on_doppler_or_phone_logs(tmp_path: Path) -> None:
    missing = str(tmp_path / "none.obs")
    assert kalman_hint(missing, _batch(0.0)) is None
    assert kalman_hint(missing, _batch(0.3)) is None
    hint = kalman_hint(missing, _batch(0.9))
    assert hint is not None and "--kalman" in hint and "Doppler" in hint
    # a phone log is named by its reader kind, whatever its observations
    log = tmp_path / "log.txt"
    log.write_text(
        "# Header\n# Raw,utcTimeMillis,TimeNanos,LeapSecond,TimeUncertaintyNanos,FullBiasNanos,BiasNanos,"
        "BiasUncertaintyNanos,DriftNanosPerSecond,DriftUncertaintyNanosPerSecond,HardwareClockDiscontinuityCount,"
        "Svid,TimeOffsetNanos,State,ReceivedSvTimeNanos,ReceivedSvTimeUncertaintyNanos,Cn0DbHz,"
        "PseudorangeRateMetersPerSecond,PseudorangeRateUncertaintyMetersPerSecond,ConstellationType\n"
    )
    hint = kalman_hint(str(log), _batch(0.0))
    assert hint is not None and "a phone log" in hint


def test_no_kalman_hint_for_the_batch_smoother(shared_data: Path, tmp_path: Path) -> None:
    """``--fgo`` already uses Doppler and carrier phase: no "least squares uses the code
    alone … --kalman" line for it (there is one for the plain least-squares run)."""
    d = shared_data / "gnsslogger_static_2016"
    args = ["solve", str(d / "pseudoranges_log_2016_08_22_14_45_50.txt"), "--nav", str(d / "hour2350.16n")]
    plain = CliRunner().invoke(main, [*args, "--out", str(tmp_path / "ls.pos")])
    assert plain.exit_code == 0, plain.output
    assert "--kalman" in plain.output
    fgo = CliRunner().invoke(main, [*args, "--fgo", "--out", str(tmp_path / "fgo.pos")])
    assert fgo.exit_code == 0, fgo.output
    assert "--kalman" not in fgo.output and "uses the code alone" not in fgo.output


def test_local_report_speaks_of_table_time(tmp_path: Path) -> None:
    sols = [Solution(float(t), np.array([1.0, 2.0, 0.5]), np.eye(3) * 1e-4, "float", 4) for t in range(5, 65)]
    p = tmp_path / "room.csv"
    write_solution_csv(sols, p)
    html = "".join(report_parts(p))
    assert "1980/01/06" not in html
    assert "span (table clock)" in html and "5 – 64 s" in html


def test_demo_announces_its_folder(tmp_path: Path, monkeypatch: object) -> None:
    import robustrtk.eval.demo as demo

    seen: list[str] = []

    def fake(out_dir: str, seed: int, progress: object = None) -> tuple[str, Path]:
        seen.append(out_dir)
        return "done", Path(out_dir) / "report.html"

    monkeypatch.setattr(demo, "run_full_demo", fake)  # type: ignore[attr-defined]
    res = CliRunner().invoke(main, ["demo", "--out", str(tmp_path / "d"), "--quiet"])
    assert res.exit_code == 0, res.output
    first = res.stdout.splitlines()[0]
    assert first == f"demo: writing every file under {tmp_path / 'd'} (--out to choose)"
    assert seen == [str(tmp_path / "d")]
