"""Hostile input and signals through the command line: one-line errors (exit 2), clean
interrupts (130, 143), never a traceback."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from click.testing import CliRunner, Result

from robustrtk.cli import entry
from robustrtk.cli.main import main

DATA = Path(__file__).resolve().parents[1] / "io" / "data"
SRC = Path(__file__).resolve().parents[2] / "src"


@pytest.fixture(scope="module")
def room(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("room")
    res = CliRunner().invoke(main, ["simulate", "demo", "--seed", "1", "--out", str(out), "--epochs", "60"])
    assert res.exit_code == 0, res.output
    return out


def _invoke(args: list[str]) -> Result:
    return CliRunner().invoke(main, [str(a) for a in args])


def _refused(res: Result, *words: str) -> str:
    """The run exited 2 with one ``error:`` line containing every word; no traceback."""
    assert res.exit_code == 2, (res.exit_code, res.output, res.exception)
    assert not isinstance(res.exception, Exception) or isinstance(res.exception, SystemExit), res.exception
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert lines and lines[-1].startswith("error: "), res.output
    assert "Traceback" not in res.output
    for w in words:
        assert w in lines[-1], (w, lines[-1])
    return lines[-1]


def _geonet(shared_data: Path) -> Path:
    return shared_data / "geonet_0759_3040_static_3km"


# ------------------------------------------------------------------------------ tables
def test_non_utf8_csv_table_names_the_line(room: Path, tmp_path: Path) -> None:
    lines = (room / "obs.csv").read_bytes().split(b"\n")
    lines[40] = lines[40].replace(b"PL", b"P\xffL", 1)
    bad = tmp_path / "obs.csv"
    bad.write_bytes(b"\n".join(lines))
    res = _invoke(["solve", bad, "--site", room / "site.toml", "--out", tmp_path / "o.csv"])
    _refused(res, "obs.csv:41", "UTF-8")


def test_corrupted_parquet_is_refused(room: Path, tmp_path: Path) -> None:
    pytest.importorskip("pyarrow")
    import random

    from robustrtk.io.obstable import read_obs_table, write_obs_table

    pq = tmp_path / "obs.parquet"
    write_obs_table(read_obs_table(room / "obs.csv"), pq)
    raw = bytearray(pq.read_bytes())
    rng = random.Random(7)
    for k in range(8):
        bad = bytearray(raw)
        for _ in range(1 + k * 4):
            bad[rng.randrange(4, len(bad) - 4)] = rng.randrange(256)
        p = tmp_path / f"bad{k}.parquet"
        p.write_bytes(bytes(bad))
        res = _invoke(["solve", p, "--site", room / "site.toml", "--out", tmp_path / "o.csv"])
        assert res.exit_code in (0, 2), (res.exit_code, res.output, res.exception)
        if res.exit_code == 2:
            _refused(res, f"bad{k}.parquet")


# ------------------------------------------------------------------------------ options
def test_simulate_zero_epochs_is_refused(tmp_path: Path) -> None:
    _refused(_invoke(["simulate", "demo", "--out", tmp_path / "s", "--epochs", "0"]), "--epochs")
    _refused(_invoke(["simulate", "demo", "--out", tmp_path / "s", "--epochs", "-4"]), "--epochs")


@pytest.mark.parametrize("freqs", ["L9+Q", "L3", ",", "+"])
def test_bad_freqs_are_refused(room: Path, tmp_path: Path, freqs: str) -> None:
    cfg = tmp_path / "c.toml"
    cfg.write_text(f'freqs = "{freqs}"\n')
    res = _invoke(["solve", room / "obs.csv", "--site", room / "site.toml", "--config", cfg, "--show-config"])
    _refused(res, "freqs")


@pytest.mark.parametrize("value", ["1e-12", "1e300", "0", "nan", "inf"])
def test_code_sigma_out_of_range_is_refused(room: Path, tmp_path: Path, value: str) -> None:
    res = _invoke(
        [
            "solve",
            room / "obs.csv",
            "--site",
            room / "site.toml",
            "--code-sigma",
            value,
            "--out",
            tmp_path / "o.csv",
        ]
    )
    _refused(res, "--code-sigma")


@pytest.mark.parametrize("value", ["95", "nan", "-5", "90"])
def test_elevation_mask_out_of_range_is_refused(value: str, tmp_path: Path) -> None:
    cfg = tmp_path / "c.toml"
    cfg.write_text(f"elev_mask_deg = {value}\n")
    res = _invoke(["solve", DATA / "tiny_v304.rnx", "--config", cfg, "--show-config"])
    _refused(res, "elev_mask_deg")


# ------------------------------------------------------------------------------ RINEX
def _mutated_v3(tmp_path: Path, old: str, new: str, nth: int = 0) -> Path:
    text = (DATA / "tiny_v304.rnx").read_text()
    lines = text.splitlines(keepends=True)
    hits = [i for i, ln in enumerate(lines) if old in ln]
    i = hits[nth]
    lines[i] = lines[i].replace(old, new, 1)
    p = tmp_path / "m.rnx"
    p.write_text("".join(lines), encoding="latin-1")
    return p


def _mutated_v2(tmp_path: Path, line_no: int, col: int, new: str) -> Path:
    lines = (DATA / "tiny_v211.o").read_text().splitlines(keepends=True)
    ln = lines[line_no - 1]
    lines[line_no - 1] = ln[:col] + new + ln[col + len(new) :]
    p = tmp_path / "m.o"
    p.write_text("".join(lines), encoding="latin-1")
    return p


@pytest.mark.parametrize("sec", ["30.+000000", " 1.0e+0000", "-1.0000000", "99.0000000"])
def test_rinex3_bad_epoch_seconds(tmp_path: Path, sec: str) -> None:
    p = _mutated_v3(tmp_path, " 0.0000000  0  5", sec + "  0  5")
    _refused(_invoke(["info", p]), "m.rnx:", "epoch")


def test_rinex3_control_byte_in_epoch_flag(tmp_path: Path) -> None:
    p = _mutated_v3(tmp_path, " 0.0000000  0  5", " 0.0000000  \x01  5")
    _refused(_invoke(["info", p]), "m.rnx:", "flag")


def test_rinex2_bad_epoch_seconds(tmp_path: Path) -> None:
    p = _mutated_v2(tmp_path, 11, 15, "30.+00000")
    _refused(_invoke(["info", p]), "m.o:11", "epoch")


# ------------------------------------------------------------------------------ .pos
@pytest.mark.parametrize("field", [5, 6])
@pytest.mark.parametrize("value", ["nan", "inf", "-inf"])
def test_pos_with_non_finite_q_or_ns(tmp_path: Path, field: int, value: str) -> None:
    from robustrtk.io.solution_pos import read_pos

    row = "2005/04/02 00:00:00.000   35.0000000  135.0000000   10.0000   1   8   0.0100   0.0100"
    row += "   0.0200   0.0000   0.0000   0.0000   0.00    3.0\n"
    tok = row.split()
    tok[field] = value
    p = tmp_path / "s.pos"
    p.write_text(
        "% program: x\n%  GPST                  latitude(deg) longitude(deg)  height(m)   Q  ns   sdn(m)"
        "   sde(m)   sdu(m)  sdne(m)  sdeu(m)  sdun(m) age(s)  ratio\n" + " ".join(tok) + "\n"
    )
    from robustrtk.core import InputError

    with pytest.raises(InputError, match=r"s\.pos:3"):
        read_pos(p)
    truth = tmp_path / "truth.csv"
    truth.write_text("time,x,y,z\n0,0,0,0\n")
    res = _invoke(["evaluate", p, "--truth", truth])
    _refused(res, "s.pos:3")


# ------------------------------------------------------------------------------ signals
def test_keyboard_interrupt_is_a_clean_exit_130(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import robustrtk.sim.files as files

    def boom(*a: object, **k: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(files, "write_simulation", boom)
    prev = signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)
    try:
        status = entry.run(["simulate", "demo", "--out", "unused-dir", "--epochs", "3"])
    finally:
        signal.signal(signal.SIGINT, prev[0])
        signal.signal(signal.SIGTERM, prev[1])
    err = capsys.readouterr().err
    assert status == 130
    assert "interrupted" in err and "Traceback" not in err


def test_entry_keeps_one_line_errors_and_usage_errors(capsys: pytest.CaptureFixture[str]) -> None:
    prev = signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)
    try:
        assert entry.run(["simulate", "demo", "--out", "x", "--epochs", "0"]) == 2
        assert entry.run(["solve", "--no-such-option"]) == 2
        assert entry.run(["--version"]) == 0
    finally:
        signal.signal(signal.SIGINT, prev[0])
        signal.signal(signal.SIGTERM, prev[1])
    err = capsys.readouterr().err
    assert "error: --epochs" in err and "Traceback" not in err


@pytest.mark.parametrize(
    ("sig", "status", "word"), [(signal.SIGTERM, 143, "terminated"), (signal.SIGINT, 130, "interrupted")]
)
def test_signals_at_any_time_exit_cleanly(tmp_path: Path, sig: int, status: int, word: str) -> None:
    env = dict(os.environ, PYTHONPATH=str(SRC))
    for delay in (0.05, 0.6):
        proc = subprocess.Popen(
            [sys.executable, "-m", "robustrtk", "simulate", "dpl_static", "--out", str(tmp_path / "s")],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            env=env,
            cwd=tmp_path,
        )
        time.sleep(delay)
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=60)
        text = err.decode()
        if proc.returncode == 0:  # finished before the signal
            continue
        assert proc.returncode == status, (delay, text)
        assert word in text and "Traceback" not in text, text
    assert not list(tmp_path.rglob("*.tmp"))
