"""The command line: simulate → solve → evaluate, config files, one-line errors."""

from __future__ import annotations

import csv
import re
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from robustrtk.cli.main import main


@pytest.fixture(scope="module")
def room(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("room")
    res = CliRunner().invoke(main, ["simulate", "demo", "--seed", "3", "--out", str(out), "--epochs", "200"])
    assert res.exit_code == 0, res.output
    return out


def _read_sol(path: Path) -> list[dict[str, str]]:
    with path.open() as fh:
        return list(csv.DictReader(fh))


def test_simulate_writes_all_files(room: Path) -> None:
    for name in ("obs.csv", "site.toml", "truth.csv", "ambiguities.csv", "faults.csv"):
        assert (room / name).stat().st_size > 0
    with (room / "truth.csv").open() as fh:
        assert sum(1 for _ in fh) == 201


def test_solve_and_evaluate(room: Path, tmp_path: Path) -> None:
    sol, diag = tmp_path / "sol.csv", tmp_path / "diag.csv"
    r = CliRunner().invoke(
        main,
        [
            "solve",
            str(room / "obs.csv"),
            "--site",
            str(room / "site.toml"),
            "--mode",
            "dpl",
            "--filter",
            "ukf",
            "--robust",
            "igg3",
            "--dynamics",
            "kinematic",
            "--out",
            str(sol),
            "--diagnostics",
            str(diag),
        ],
    )
    assert r.exit_code == 0, r.output
    assert re.search(r"reference\s+PL6 \(site\)", r.output), r.output
    rows = _read_sol(sol)
    assert len(rows) == 200
    assert set(rows[0]) >= {"time", "x", "y", "z", "sx", "sy", "sz", "status", "n_used"}
    assert {row["status"] for row in rows} == {"code"}
    drows = _read_sol(diag)
    assert len(drows) == 4 * 200 and {d["dd"] for d in drows} == {"PL1-PL6", "PL4-PL6", "PL5-PL6", "PL8-PL6"}
    plots = tmp_path / "plots"
    r = CliRunner().invoke(
        main,
        [
            "evaluate",
            str(sol),
            "--truth",
            str(room / "truth.csv"),
            "--diagnostics",
            str(diag),
            "--faults",
            str(room / "faults.csv"),
            "--plots",
            str(plots),
        ],
    )
    assert r.exit_code == 0, r.output
    assert "3D RMS" in r.output and "All DDs" in r.output or "all" in r.output.lower()
    assert (plots / "errors.png").stat().st_size > 10_000
    # the printed 3D RMS equals the one computed from the files
    truth = np.loadtxt(room / "truth.csv", delimiter=",", skiprows=1)
    pos = np.array([[float(r_[k]) for k in "xyz"] for r_ in rows])
    rms = np.sqrt(np.mean(np.sum((pos - truth[:, 1:]) ** 2, axis=1)))
    assert f"{rms:.3f}" in r.output


def test_config_file_and_flags_override(room: Path, tmp_path: Path) -> None:
    cfg = tmp_path / "c.toml"
    cfg.write_text('mode = "rtk"\nrobust = "none"\nar = "lambda"\n')
    out = tmp_path / "s.csv"
    r = CliRunner().invoke(
        main,
        [
            "solve",
            str(room / "obs.csv"),
            "--site",
            str(room / "site.toml"),
            "--config",
            str(cfg),
            "--robust",
            "igg3",
            "--out",
            str(out),
        ],
    )
    assert r.exit_code == 0, r.output
    assert "mode rtk" in r.output and "robust=igg3" in r.output
    assert {row["status"] for row in _read_sol(out)} <= {"fixed", "partial", "float"}


@pytest.mark.parametrize(
    "setup, expect",
    [
        (lambda d: (d / "c.toml").write_text('robust = "tukey"\n'), "robust: expected one of"),
        (lambda d: (d / "c.toml").write_text("bogus = 1\n"), "unknown key 'bogus'"),
        (lambda d: (d / "c.toml").write_text('k0 = "two"\n'), "k0: expected float"),
        (lambda d: (d / "c.toml").write_text("robust = \n"), "invalid TOML"),
    ],
)
def test_bad_config_is_one_line(room: Path, tmp_path: Path, setup, expect) -> None:
    setup(tmp_path)
    r = CliRunner().invoke(
        main,
        [
            "solve",
            str(room / "obs.csv"),
            "--site",
            str(room / "site.toml"),
            "--config",
            str(tmp_path / "c.toml"),
            "--out",
            str(tmp_path / "s.csv"),
        ],
    )
    assert r.exit_code == 2
    err = r.output.strip()
    assert err.startswith("error: ") and "\n" not in err and expect in err
    assert "Traceback" not in r.output
    assert not (tmp_path / "s.csv").exists()


def test_bad_inputs_are_one_line(room: Path, tmp_path: Path) -> None:
    bad = tmp_path / "bad.csv"
    bad.write_text("time,receiver,transmitter,code_m\n0,base,PL1,abc\n")
    r = CliRunner().invoke(
        main, ["solve", str(bad), "--site", str(room / "site.toml"), "--out", str(tmp_path / "s.csv")]
    )
    assert r.exit_code == 2 and "bad.csv:2" in r.output and "Traceback" not in r.output
    r = CliRunner().invoke(
        main,
        [
            "solve",
            str(tmp_path / "missing.csv"),
            "--site",
            str(room / "site.toml"),
            "--out",
            str(tmp_path / "s.csv"),
        ],
    )
    assert r.exit_code == 2 and "missing.csv" in r.output
    r = CliRunner().invoke(main, ["solve", str(room / "obs.csv"), "--out", str(tmp_path / "s.csv")])
    assert r.exit_code == 2 and "--site" in r.output
    r = CliRunner().invoke(
        main,
        [
            "solve",
            str(room / "obs.csv"),
            "--site",
            str(room / "site.toml"),
            "--reference",
            "PL99",
            "--out",
            str(tmp_path / "s.csv"),
        ],
    )
    assert r.exit_code == 2 and "PL99" in r.output
    r = CliRunner().invoke(main, ["simulate", "no_such_preset", "--out", str(tmp_path / "x")])
    assert r.exit_code == 2 and "no_such_preset" in r.output


@pytest.mark.slow  # the whole demo, real-data RTK and report included (tens of seconds)
def test_demo_runs_and_rukf_beats_sukf(tmp_path: Path) -> None:
    r = CliRunner().invoke(main, ["demo", "--out", str(tmp_path / "demo")])
    assert r.exit_code == 0, r.output
    table: dict[str, list[str]] = {}
    for line in r.output.splitlines():  # the first table: name epochs |x| |y| |z| rms p95 max
        if line.startswith(("DPL ", "RTK ")):
            table.setdefault(line.split("  ")[0].strip(), line.split())
    rms = {k: float(v[-3]) for k, v in table.items()}
    assert rms["DPL RUKF"] < rms["DPL SUKF"]
    assert rms["RTK RUKF+PAR"] < 0.05
    assert (tmp_path / "demo" / "plots" / "dpl_errors.png").stat().st_size > 10_000


def test_gnss_dgnss_to_pos_and_info(shared_data: Path, tmp_path: Path) -> None:
    from robustrtk.io.solution import read_pos

    d = shared_data / "geonet_0759_3040_static_3km"
    out = tmp_path / "g.pos"
    r = CliRunner().invoke(
        main,
        [
            "solve",
            str(d / "07590920.05o"),
            "--base",
            str(d / "30400920.05o"),
            "--nav",
            str(d / "07590920.05n"),
            "--mode",
            "dgnss",
            "--base-pos=-3978241.958,3382840.234,3649900.853",
            "--out",
            str(out),
        ],
    )
    assert r.exit_code == 0, r.output
    sol = read_pos(out)
    truth = np.array([-3976219.1879, 3382371.6056, 3652511.1425])
    err = np.linalg.norm(sol.pos_m - truth, axis=1)
    assert len(sol.t_s) >= 100 and np.percentile(err, 95) < 0.6
    r = CliRunner().invoke(main, ["info", str(d / "30400920.05o")])
    assert r.exit_code == 0 and "120" in r.output and "RINEX 2.10" in r.output
    # RTK on RINEX needs a base file: one-line error
    r = CliRunner().invoke(
        main,
        [
            "solve",
            str(d / "30400920.05o"),
            "--nav",
            str(d / "07590920.05n"),
            "--mode",
            "rtk",
            "--out",
            str(tmp_path / "x.pos"),
        ],
    )
    assert r.exit_code == 2 and "RTK needs a base" in r.output and r.output.count("\n") == 1
    r = CliRunner().invoke(
        main,
        [
            "solve",
            str(d / "30400920.05o"),
            "--nav",
            str(d / "07590920.05n"),
            "--mode",
            "dpl",
            "--out",
            str(tmp_path / "x.pos"),
        ],
    )
    assert r.exit_code == 2 and "spp, dgnss or rtk" in r.output


def test_gnss_rtk_cli_writes_fixed_pos(shared_data: Path, tmp_path: Path) -> None:
    from robustrtk.io.solution import read_pos

    d = shared_data / "geonet_0759_3040_static_3km"
    out = tmp_path / "rtk.pos"
    diag = tmp_path / "diag.csv"
    r = CliRunner().invoke(
        main,
        [
            "solve",
            str(d / "07590920.05o"),
            "--base",
            str(d / "30400920.05o"),
            "--nav",
            str(d / "07590920.05n"),
            "--mode",
            "rtk",
            "--diagnostics",
            str(diag),
            "--base-pos=-3978241.958,3382840.234,3649900.853",
            "--out",
            str(out),
        ],
    )
    assert r.exit_code == 0, r.output
    sol = read_pos(out)
    truth = np.array([-3976219.1879, 3382371.6056, 3652511.1425])
    fixed = sol.status == "fixed"
    assert fixed.mean() > 0.842  # RTKLIB fix-and-hold: 84.2 % of the 120 rover epochs
    err = np.linalg.norm(sol.pos_m[fixed] - truth, axis=1)
    assert np.percentile(err, 95) < 0.03
    text = diag.read_text().splitlines()
    assert len(text) > 120 and "G" in text[1]


def test_phone_kalman_spp_through_the_cli_meets_the_score(shared_data: Path, tmp_path: Path) -> None:
    """The CLI path gives the Kalman SPP all signals (L5, phase): GSDC score <= 4 m."""
    from robustrtk.geometry.frames import ecef2enu_deg
    from robustrtk.io.solution import read_pos

    d = shared_data / "gsdc2021_mtv1_pixel5_phone" / "Pixel5"
    out = tmp_path / "phone.pos"
    r = CliRunner().invoke(
        main,
        [
            "solve",
            str(d / "supplemental" / "Pixel5_GnssLog.21o"),
            "--nav",
            str(d / "supplemental" / "hour1180.21n"),
            "--mode",
            "spp",
            "--kalman",
            "--quiet",
            "--out",
            str(out),
        ],
    )
    assert r.exit_code == 0, r.output
    sol = read_pos(out)
    gt = np.genfromtxt(d / "ground_truth.csv", delimiter=",", skip_header=1, usecols=(2, 3, 4, 5))
    tg = gt[:, 0] / 1000.0
    errs = []
    for t, p in zip(sol.t_s, sol.pos_m, strict=True):
        j = int(np.argmin(np.abs(tg - t)))
        if abs(tg[j] - t) < 0.05:
            e = ecef2enu_deg(p, gt[j, 1], gt[j, 2], gt[j, 3])
            errs.append(np.hypot(e[0], e[1]))
    assert len(errs) > 1800
    p50, p95 = np.percentile(errs, [50, 95])
    assert (p50 + p95) / 2 <= 4.0
