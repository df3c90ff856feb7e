"""``robustrtk coop``: outputs (.pos of the node and of every node, diagnostics), TOML
settings, and one-line errors with exit status 2 for bad input."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from robustrtk.cli.main import main
from robustrtk.io.solution import read_pos

DATA = Path(__file__).resolve().parents[2] / ".." / "shared" / "data" / "geonet_0759_3040_static_3km"
BASE = "-3978241.958,3382840.234,3649900.853"
RANGE_M = 3335.389  # RTK baseline length of the pair (tests/pipeline/test_coop.py checks it)
needs_data = pytest.mark.skipif(
    not (DATA / "07590920.05o").exists(), reason="geonet data not in ../shared/data"
)


def _short(tmp: Path) -> tuple[Path, Path]:
    """The first 10 epochs of both files (RINEX 2: header, then 9 lines per epoch here)."""
    out = []
    for name in ("07590920.05o", "30400920.05o"):
        lines = (DATA / name).read_text().splitlines(keepends=True)
        h = next(i for i, ln in enumerate(lines) if "END OF HEADER" in ln) + 1
        body, n_ep, k = [], 0, h
        while k < len(lines) and n_ep < 10:
            n_sat = int(lines[k][29:32])
            body.extend(lines[k : k + 1 + n_sat * ((4 + 4) // 5)])
            k += 1 + n_sat * ((4 + 4) // 5)
            n_ep += 1
        p = tmp / name
        p.write_text("".join(lines[:h] + body))
        out.append(p)
    return out[0], out[1]


def _invoke(args: list[str]):
    return CliRunner().invoke(main, ["coop", *args], catch_exceptions=False)


@needs_data
def test_coop_cli_writes_node_and_peer_solutions(tmp_path):
    rover, base = _short(tmp_path)
    out = tmp_path / "n2.pos"
    diag = tmp_path / "diag.csv"
    args = [str(rover), "--peer", str(base), "--nav", str(DATA / "07590920.05n"), "--filter", "ekf"]
    args += ["--range-m", str(RANGE_M), "--range-sigma-m", "0.01", "--windowsill", "3"]
    args += ["--out", str(out), "--nodes", str(tmp_path / "nodes"), "--diagnostics", str(diag)]
    res = _invoke(args)
    assert res.exit_code == 0, res.output
    assert "solved 10/10" in res.output
    sol = read_pos(out)
    assert len(sol.t_s) == 10
    truth = np.array([-3976219.1879, 3382371.6056, 3652511.1425])
    assert np.max(np.linalg.norm(sol.pos_m - truth, axis=1)) < 30.0
    assert {p.name for p in (tmp_path / "nodes").iterdir()} == {"07590920.pos", "30400920.pos"}
    rows = list(csv.DictReader(diag.open()))
    assert len(rows) == 20
    me = [r for r in rows if r["node"] == "07590920"]
    assert all(r["n_sats"] == "3" and r["n_ranges"] == "1" for r in me)
    # alone with three satellites: no epoch
    args_off = [str(rover), "--peer", str(base), "--nav", str(DATA / "07590920.05n"), "--windowsill", "3"]
    res = _invoke([*args_off, "--cooperation", "off", "--out", str(tmp_path / "off.pos")])
    assert res.exit_code == 0
    assert "solved 0/10" in res.output


@needs_data
def test_coop_cli_config_file(tmp_path):
    rover, base = _short(tmp_path)
    cfgp = tmp_path / "c.toml"
    cfgp.write_text('[coop]\ncoop_filter = "pf"\nn_particles = 300\nseed = 4\nsigma_set_m = 1.5\n')
    args = [str(rover), "--peer", str(base), "--nav", str(DATA / "07590920.05n"), "--range-m", str(RANGE_M)]
    args += [
        "--out",
        str(tmp_path / "a.pos"),
        "--config",
        str(cfgp),
        "--diagnostics",
        str(tmp_path / "d.csv"),
    ]
    res = _invoke(args)
    assert res.exit_code == 0, res.output
    assert "coop pf/improved" in res.output
    ess = [float(r["ess"]) for r in csv.DictReader((tmp_path / "d.csv").open()) if r["ess"] != "nan"]
    assert ess and all(1.0 <= e <= 300.0 for e in ess)
    # the range σ̂ of 'improved' with σ_set = 1.5 m: sqrt(0.05² + 4 · 1.5²)
    sig = [
        float(r["range_sigma_m"]) for r in csv.DictReader((tmp_path / "d.csv").open()) if r["n_ranges"] == "1"
    ]
    assert any(s == pytest.approx(np.sqrt(0.05**2 + 4 * 1.5**2), abs=1e-4) for s in sig)


@needs_data
@pytest.mark.parametrize(
    "extra, message",
    [
        (["--range-m", "10", "--range-from-rtk"], "exactly one range source"),
        ([], "exactly one range source"),
        (["--range-m", "-3"], "must be positive"),
        (["--range-m", "10", "--peer-pos", "1,2"], "--peer-pos"),
        (["--range-m", "10", "--session-range"], "--session-range"),
        (["--range-m", "10", "--cooperation", "off"], "does not apply"),
        (["--range-m", "10", "--filter", "ekf", "--particles", "100"], "only to --filter pf"),
        (["--range", "MISSING.txt"], "MISSING.txt"),
        (["--range-m", "10", "--config", "BAD.toml"], "BAD.toml"),
    ],
)
def test_coop_cli_bad_input_is_one_line(tmp_path, extra, message):
    rover, base = _short(tmp_path)
    (tmp_path / "BAD.toml").write_text("[coop]\ncoop_filter = 3\n")
    extra = [str(tmp_path / e) if e.endswith((".txt", ".toml")) else e for e in extra]
    args = [
        str(rover),
        "--peer",
        str(base),
        "--nav",
        str(DATA / "07590920.05n"),
        "--out",
        str(tmp_path / "o.pos"),
    ]
    res = CliRunner().invoke(main, ["coop", *args, *extra])
    assert res.exit_code == 2, res.output
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error:")
    assert message in lines[0]
    assert "Traceback" not in res.output
    assert not (tmp_path / "o.pos").exists()


def test_coop_cli_unknown_config_key(tmp_path):
    cfgp = tmp_path / "c.toml"
    cfgp.write_text("[coop]\nparticles = 3\n")
    res = CliRunner().invoke(
        main,
        [
            "coop",
            "x.obs",
            "--peer",
            "y.obs",
            "--nav",
            "n",
            "--range-m",
            "1",
            "--out",
            "o.pos",
            "--config",
            str(cfgp),
        ],
    )
    assert res.exit_code == 2
    assert "'particles': unknown key" in res.output and "c.toml" in res.output
