"""``robustrtk inject``: the command writes the copy and the log; bad input is one line, exit 2."""

from __future__ import annotations

import csv
from pathlib import Path

import click
import numpy as np
import pytest
from click.testing import CliRunner

from robustrtk.cli.inject import inject
from robustrtk.io.rinex_obs import read_rinex_obs

GEONET = "geonet_0759_3040_static_3km/07590920.05o"
MOSAIC = "mosaicx5_static_1m/rover.obs"


@click.group()
def cli() -> None:
    """Test group holding the command as the real CLI does."""


cli.add_command(inject)


def _run(args: list[str]) -> tuple[int, str, str]:
    r = CliRunner().invoke(cli, ["inject", *args])
    return r.exit_code, r.stdout, r.stderr


def test_inject_command_writes_file_and_default_log(shared_data: Path, tmp_path: Path) -> None:
    src = shared_data / MOSAIC
    out = tmp_path / "rover_faults.obs"
    code, stdout, stderr = _run(
        [
            str(src),
            "--phase",
            "G05:L1C:0.15:random20",
            "--code",
            "G07:C1C:10:random20",
            "--seed",
            "4",
            "--out",
            str(out),
        ]
    )
    assert code == 0, stderr
    assert "40 values changed (20 phase, 20 code)" in stdout
    log = Path(str(out) + ".inject.csv")
    with log.open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 40
    a, b = read_rinex_obs(src), read_rinex_obs(out)
    n5, n7, k = a.tx_ids.index("G05"), a.tx_ids.index("G07"), a.signals.index("1C")
    d_ph = np.nan_to_num(b.phase_cyc - a.phase_cyc)
    d_co = np.nan_to_num(b.code_m - a.code_m)
    ph_epochs = sorted(int(r["epoch_index"]) for r in rows if r["kind"] == "phase")
    co_epochs = sorted(int(r["epoch_index"]) for r in rows if r["kind"] == "code")
    assert np.flatnonzero(d_ph[:, n5, k]).tolist() == ph_epochs
    assert np.flatnonzero(d_co[:, n7, k]).tolist() == co_epochs
    assert np.count_nonzero(d_ph) == 20 and np.count_nonzero(d_co) == 20
    np.testing.assert_array_equal(a.lli, b.lli)
    # same seed, same output
    out2 = tmp_path / "again.obs"
    code, _, _ = _run(
        [
            str(src),
            "--phase",
            "G05:L1C:0.15:random20",
            "--code",
            "G07:C1C:10:random20",
            "--seed",
            "4",
            "--out",
            str(out2),
        ]
    )
    assert code == 0 and out2.read_bytes() == out.read_bytes()


def test_inject_command_hatanaka_output_slip_and_log_option(shared_data: Path, tmp_path: Path) -> None:
    src = shared_data / GEONET
    out = tmp_path / "07590920.05d"
    log = tmp_path / "faults.csv"
    code, stdout, stderr = _run(
        [
            str(src),
            "--slip",
            "G20:L1:2:60",
            "--slip",
            "G24:L2:-1:100",
            "--slip-lli",
            "--out",
            str(out),
            "--log",
            str(log),
        ]
    )
    assert code == 0, stderr
    assert "(hatanaka)" in stdout and log.is_file()
    a, b = read_rinex_obs(src), read_rinex_obs(out)
    assert b.meta["compression"] == "hatanaka"
    n, k = a.tx_ids.index("G20"), a.signals.index("1C")
    d = b.phase_cyc[:, n, k] - a.phase_cyc[:, n, k]
    have = ~np.isnan(d)
    assert np.all(d[:60][have[:60]] == 0) and np.allclose(d[60:][have[60:]], 2.0, atol=1e-6)
    assert np.argwhere(a.lli != b.lli).tolist() == [
        [60, n, k],
        [100, a.tx_ids.index("G24"), a.signals.index("2W")],
    ]


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["--phase", "G05:L1:0.15"], "--phase 'G05:L1:0.15': expected SAT:SIGNAL:SIZE_M:EPOCHS"),
        (["--code", "G05:C1:x:3"], "SIZE_M"),
        (["--slip", "G05:L1:1:2-3"], "EPOCH"),
        (["--phase", "G19:L1:0.15:0-400"], "epoch 120 out of range"),
        (["--phase", "G19:L1C:0.15:3"], "not in the header"),
        ([], "nothing to inject"),
    ],
)
def test_inject_command_errors_are_one_line(
    shared_data: Path, tmp_path: Path, args: list[str], needle: str
) -> None:
    out = tmp_path / "x.05o"
    code, stdout, stderr = _run([str(shared_data / GEONET), *args, "--out", str(out)])
    assert code == 2
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and needle in lines[0]
    assert "Traceback" not in stderr and not out.exists()


def test_inject_command_missing_input_and_same_output(tmp_path: Path) -> None:
    code, _, stderr = _run(
        [str(tmp_path / "absent.obs"), "--code", "G01:C1C:10:0", "--out", str(tmp_path / "o.obs")]
    )
    assert code == 2 and stderr.strip() == f"error: {tmp_path / 'absent.obs'}: file not found"
    src = tmp_path / "in.obs"
    src.write_text("x\n")
    code, _, stderr = _run([str(src), "--code", "G01:C1C:10:0", "--out", str(src)])
    assert code == 2 and "is also the input OBS" in stderr and src.read_text() == "x\n"
    code, _, stderr = _run([str(src), "--code", "G01:C1C:10:0", "--out", str(tmp_path / "no" / "o.obs")])
    assert code == 2 and len(stderr.strip().splitlines()) == 1
