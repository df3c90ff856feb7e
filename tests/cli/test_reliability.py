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
    # "early" = just after the interpreter is up and the entry imported (no program can
    # handle a signal that arrives before that): timed here, since a busy machine starts
    # processes several times slower than a quiet one
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", "import robustrtk.cli.entry"], env=env, check=True, timeout=60)
    early = max(0.05, 1.5 * (time.perf_counter() - t0))
    for delay in (early, early + 0.6):
        for _ in range(5):
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
            if proc.returncode != -sig:
                break
            # killed by the signal's default action: it came before the entry was imported
            # (the process started slower than the timed one), which no program can handle;
            # a little later
            delay *= 1.5
        text = err.decode()
        if proc.returncode == 0:  # finished before the signal
            continue
        assert proc.returncode == status, (delay, text)
        assert word in text and "Traceback" not in text, text
    assert not list(tmp_path.rglob("*.tmp"))


# ------------------------------------------------------------------------------ silent garbage
@pytest.mark.parametrize(
    ("old", "new", "words"),
    [
        ("22000000.125", "         nan", ("m.rnx:18", "C1C")),
        ("22000000.125", "        -inf", ("m.rnx:18", "C1C")),
        ("115000000.50017", "115000000.500X7", ("m.rnx:18", "LLI")),
        ("  2024     6    24", "  2024    13    24", ("m.rnx:13", "TIME OF FIRST OBS")),
        ("  2024     6    24", "  20x4     6    24", ("m.rnx:13", "TIME OF FIRST OBS")),
    ],
)
def test_rinex3_bad_fields_are_refused(tmp_path: Path, old: str, new: str, words: tuple[str, ...]) -> None:
    _refused(_invoke(["info", _mutated_v3(tmp_path, old, new)]), *words)


@pytest.mark.parametrize("new", ["G   17 C1C", "G   15 C1C"])
def test_rinex3_type_count_off_by_its_list_is_read(tmp_path: Path, new: str) -> None:
    """As RTKLIB: the types are read up to the declared count (records are one line)."""
    res = _invoke(["info", _mutated_v3(tmp_path, "G   16 C1C", new)])
    assert res.exit_code == 0 and "GPS" in res.output, res.output


def test_rinex2_wrong_types_count_and_lli_letter(tmp_path: Path) -> None:
    # 7 types listed (two lines per record), 5 declared (one line): the records cannot be read
    _refused(_invoke(["info", _mutated_v2(tmp_path, 7, 0, "     5")]), "m.o:10", "declares 5")
    # 6 declared: the same two lines per record; the first six types are read, as RTKLIB
    assert _invoke(["info", _mutated_v2(tmp_path, 7, 0, "     6")]).exit_code == 0
    _refused(_invoke(["info", _mutated_v2(tmp_path, 13, 14, "X")]), "m.o:13", "LLI")


def test_table_time_out_of_range_is_refused(room: Path, tmp_path: Path) -> None:
    text = (room / "obs.csv").read_text().splitlines()
    text.append("1e300,base,PL1,17251.3,414763.4,42.35,0")
    p = tmp_path / "obs.csv"
    p.write_text("\n".join(text) + "\n")
    res = _invoke(["solve", p, "--site", room / "site.toml", "--out", tmp_path / "o.csv"])
    _refused(res, f"obs.csv:{len(text)}", "time")


def test_site_with_coinciding_transmitters_is_refused(room: Path, tmp_path: Path) -> None:
    site = (room / "site.toml").read_text()
    lines = site.splitlines()
    first = next(ln for ln in lines if ln.startswith("PL1 "))
    pos = first.split("=", 1)[1]
    bad = "\n".join(ln if not ln.startswith("PL4 ") else "PL4 =" + pos for ln in lines) + "\n"
    (tmp_path / "site.toml").write_text(bad)
    res = _invoke(["solve", room / "obs.csv", "--site", tmp_path / "site.toml", "--out", tmp_path / "o.csv"])
    _refused(res, "site.toml", "PL4", "PL1")


def test_output_in_an_unwritable_place_names_the_output(room: Path) -> None:
    res = _invoke(["solve", room / "obs.csv", "--site", room / "site.toml", "--out", "/proc/x.csv"])
    msg = _refused(res, "/proc/x.csv")
    assert ".tmp" not in msg


def test_solution_and_diagnostics_written_together(room: Path, tmp_path: Path) -> None:
    sol, diag = tmp_path / "sol.csv", tmp_path / "diag.csv"
    res = _invoke(
        [
            "solve",
            room / "obs.csv",
            "--site",
            room / "site.toml",
            "--out",
            sol,
            "--diagnostics",
            diag,
            "--quiet",
        ]
    )
    assert res.exit_code == 0, res.output
    assert sol.stat().st_size > 0 and diag.stat().st_size > 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["diag.csv", "sol.csv"]


def test_interrupt_during_the_write_leaves_the_previous_outputs(
    room: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import robustrtk.cli.gnss as cli_gnss

    sol, diag = tmp_path / "sol.csv", tmp_path / "diag.csv"
    sol.write_text("old solution\n")
    diag.write_text("old diagnostics\n")

    def boom(*a: object, **k: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(cli_gnss, "write_solutions", boom)
    res = _invoke(
        [
            "solve",
            room / "obs.csv",
            "--site",
            room / "site.toml",
            "--out",
            sol,
            "--diagnostics",
            diag,
            "--quiet",
        ]
    )
    assert res.exit_code != 0  # CliRunner: click turns the interrupt into Abort
    assert sol.read_text() == "old solution\n" and diag.read_text() == "old diagnostics\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["diag.csv", "sol.csv"]


def test_header_only_observation_and_nav_files(shared_data: Path, tmp_path: Path) -> None:
    d = _geonet(shared_data)
    obs, nav = d / "30400920.05o", d / "30400920.05n"
    for src, name in ((obs, "h.o"), (nav, "h.n")):
        lines = src.read_text().splitlines(keepends=True)
        end = next(i for i, ln in enumerate(lines) if "END OF HEADER" in ln)
        (tmp_path / name).write_text("".join(lines[: end + 1]))
    _refused(
        _invoke(["solve", tmp_path / "h.o", "--nav", nav, "--out", tmp_path / "o.pos"]), "h.o", "no observ"
    )
    _refused(
        _invoke(["solve", obs, "--nav", tmp_path / "h.n", "--out", tmp_path / "o.pos"]), "--nav", "ephemeris"
    )


def test_nav_of_another_time_is_refused(shared_data: Path, tmp_path: Path) -> None:
    d = _geonet(shared_data)
    other = shared_data / "kamakura_kinematic_5km" / "SEPT2650.21P"
    res = _invoke(["solve", d / "30400920.05o", "--nav", other, "--out", tmp_path / "o.pos"])
    _refused(res, "--nav", "covers none")


def test_nothing_solved_exits_3_with_causes(shared_data: Path, tmp_path: Path) -> None:
    d = _geonet(shared_data)
    out = tmp_path / "o.pos"
    res = _invoke(
        ["solve", d / "30400920.05o", "--nav", d / "30400920.05n", "--elev-mask", "89.5", "--out", out]
    )
    assert res.exit_code == 3, res.output
    assert "no epoch solved of 120" in res.output and "no usable observation" in res.output
    assert not out.exists()


def test_base_position_far_from_the_base_is_refused_fast(shared_data: Path, tmp_path: Path) -> None:
    d = _geonet(shared_data)
    args = ["solve", d / "07590920.05o", "--base", d / "30400920.05o", "--nav", d / "30400920.05n"]
    args += ["--mode", "dgnss", "--out", tmp_path / "o.pos", "--quiet"]
    t0 = time.perf_counter()
    res = _invoke([*args, "--base-pos", "-3878241.958,3382840.234,3649900.853"])
    msg = _refused(res, "--base-pos", "m from the base's own single-point solution", "--force")
    assert "99999" in msg and time.perf_counter() - t0 < 30
    _refused(_invoke([*args, "--base-pos", "1e30,0,0"]), "--base-pos", "Earth")
    ok = _invoke([*args, "--base-pos", "-3978241.958,3382840.234,3649900.853"])
    assert ok.exit_code == 0, ok.output
    forced = _invoke([*args, "--base-pos", "-3978241.958,3382840.234,3650100.853", "--force"])
    assert forced.exit_code == 0, forced.output


def test_table_rows_for_transmitters_the_site_lacks_are_refused(tmp_path: Path) -> None:
    from click.testing import CliRunner

    from robustrtk.cli.main import main
    from robustrtk.sim.files import run_simulate

    out = tmp_path / "room"
    run_simulate("dpl_static", 1, out)
    text = (out / "obs.csv").read_text().splitlines()
    header, first = text[0], text[1]
    cols = header.split(",")
    row = first.split(",")
    row[cols.index("transmitter")] = "PL99"
    (out / "obs.csv").write_text("\n".join([header, *text[1:], ",".join(row)]) + "\n")
    res = CliRunner().invoke(main, ["solve", str(out / "obs.csv"), "--site", str(out / "site.toml"),
                                    "--out", str(tmp_path / "sol.csv"), "--quiet"])  # fmt: skip
    assert res.exit_code == 2
    assert "PL99" in res.output and "site file" in res.output
    assert not (tmp_path / "sol.csv").exists()
