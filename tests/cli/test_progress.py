"""The progress bar of long commands and the end-of-run summary.

The bar is drawn on a real pseudo-terminal and absent when stderr is not a terminal or
with ``--quiet``; the summary's numbers equal a recount from the written solution file.
"""

from __future__ import annotations

import io
import os
import pty
import re
import select
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from robustrtk.cli.entry import run
from robustrtk.cli.progress import ProgressBar, bar_wanted, format_summary
from robustrtk.io.diagnostics import read_diagnostics_csv
from robustrtk.io.solution import read_pos, read_solution_csv
from robustrtk.pipeline.series import RunSummary

SRC = Path(__file__).resolve().parents[2] / "src"


_ANSI = re.compile(r"\x1b\[[0-9;?]*[A-Za-z]")


def _plain(text: str) -> str:
    """The text without terminal control sequences (colours, cursor, line erase)."""
    return _ANSI.sub("", text)


def _frames(text: str) -> list[str]:
    """The frames drawn on one terminal line, oldest first (trailing blanks removed)."""
    return [f.rstrip() for f in _plain(text).replace("\r\n", "\n").split("\r") if f.strip()]


class _Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


class _Clock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def test_bar_line_counts_rate_and_fix_rate() -> None:
    out, clock = _Tty(), _Clock()
    bar = ProgressBar("solving rtk", stream=out, show_fix=True, min_interval_s=0.0, clock=clock)
    statuses = ["float", "fixed", "fixed", "none", "partial", "fixed", "float", "fixed"]
    for i, st in enumerate(statuses[:6]):
        clock.t += 0.5
        bar.epoch(i + 1, 8, st)
    line = bar.line()
    assert "6/8 epochs" in line
    # 6 epochs over the 2.5 s since the first callback
    assert f"{6 / 2.5:.1f} epochs/s" in line
    assert f"fix {100 * 4 / 6:.0f} %" in line  # fixed, fixed, partial, fixed of six
    assert "ETA 1 s" in line  # two more epochs at 2.4/s
    frames = _frames(out.getvalue())
    assert frames[-1].startswith("solving rtk ") and frames[-1].endswith(line)
    for i, st in enumerate(statuses[6:], start=6):
        clock.t += 0.5
        bar.epoch(i + 1, 8, st)
    bar.close()
    text = _plain(out.getvalue())
    assert text.endswith("\n")  # the line is ended once, after the last frame
    last = f"8/8 epochs   {8 / 3.5:.1f} epochs/s   fix {100 * 5 / 8:.0f} %"  # 8 in 3.5 s, 5 of 8 fixed
    assert _frames(out.getvalue())[-1].endswith(last)


def test_plain_callbacks_count_without_a_fix_rate() -> None:
    out = _Tty()
    with ProgressBar("li2019", "tasks", stream=out, min_interval_s=0.0) as bar:
        for k in range(1, 4):
            bar(k, 3)
    assert "3/3 tasks" in out.getvalue() and "fix" not in out.getvalue()


def test_disabled_bar_writes_nothing_and_the_rule() -> None:
    out = _Tty()
    with ProgressBar("solving", stream=out, enabled=False) as bar:
        bar.epoch(1, 2, "fixed")
        bar.epoch(2, 2, "fixed")
    assert out.getvalue() == ""
    assert bar_wanted(False, _Tty()) and not bar_wanted(True, _Tty())
    assert not bar_wanted(False, io.StringIO())


def test_summary_text() -> None:
    s = RunSummary(
        epochs=120,
        solved=118,
        by_status={"fixed": 100, "float": 18, "none": 2},
        fixed=100,
        fix_rate=100 / 120,
        time_to_first_fix_s=60.0,
        rows_downweighted=7,
        rows_rejected=2,
        epochs_flagged=5,
    )
    text = format_summary(s, title="robustrtk solve: mode rtk", wall_s=2.0, outputs=["a.pos"])
    assert text.splitlines()[0] == "robustrtk solve: mode rtk"
    assert "83.3 % of 120 epochs (Q=1): fixed 100 (83.3 %), partial 0 (0.0 %)" in text
    assert "60 s after" in text
    assert "7 DD rows down-weighted, 2 rejected, in 5 epochs" in text and "60 epochs/s" in text


def test_summary_keeps_full_and_partial_fixes_apart() -> None:
    """The fix rate is the Q=1 share (fixed + partial, as the API's fix_rate), and the two
    are shown apart: 54 full fixes are never reported as 358."""
    s = RunSummary(
        epochs=360,
        solved=360,
        by_status={"fixed": 54, "partial": 304, "float": 2},
        fixed=358,
        fix_rate=358 / 360,
        time_to_first_fix_s=2.0,
        rows_downweighted=0,
        rows_rejected=0,
        epochs_flagged=0,
    )
    text = format_summary(s, title="t", wall_s=1.0)
    assert "99.4 % of 360 epochs (Q=1): fixed 54 (15.0 %), partial 304 (84.4 %)" in text


# --------------------------------------------------------------------------- the command
@pytest.fixture(scope="module")
def room(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("room")
    assert run(["simulate", "demo", "--seed", "4", "--epochs", "150", "--out", str(d)]) == 0
    return d


def _solve_on_pty(args: list[str]) -> tuple[str, str, int]:
    """Run ``robustrtk ARGS`` with stderr on a pseudo-terminal; (stderr, stdout, status)."""
    master, slave = pty.openpty()
    env = {**os.environ, "PYTHONPATH": str(SRC), "COLUMNS": "200"}
    proc = subprocess.Popen(
        [sys.executable, "-m", "robustrtk", *args],
        stdout=subprocess.PIPE,
        stderr=slave,
        stdin=subprocess.DEVNULL,
        env=env,
    )
    os.close(slave)
    chunks: list[bytes] = []
    while True:
        ready, _, _ = select.select([master], [], [], 60)
        if not ready:
            break
        try:
            data = os.read(master, 65536)
        except OSError:  # the child closed the terminal
            break
        if not data:
            break
        chunks.append(data)
    os.close(master)
    assert proc.stdout is not None
    stdout = proc.stdout.read().decode()
    status = proc.wait(timeout=60)
    return b"".join(chunks).decode(errors="replace"), stdout, status


def _args(room: Path, out: Path) -> list[str]:
    return [
        "solve",
        str(room / "obs.csv"),
        "--site",
        str(room / "site.toml"),
        "--mode",
        "rtk",
        "--out",
        str(out),
    ]


def test_bar_on_a_terminal_and_summary_equal_to_the_file(room: Path, tmp_path: Path) -> None:
    out = tmp_path / "rtk.csv"
    err, stdout, status = _solve_on_pty(_args(room, out))
    assert status == 0, err
    frames = _frames(err)
    assert len(frames) >= 1 and "solving rtk" in frames[-1] and "150/150 epochs" in frames[-1]
    assert re.search(r"\d+\.\d epochs/s", frames[-1]) and re.search(r"fix \d+ %", frames[-1])
    _check_summary(stdout, read_solution_csv(out))


def test_no_bar_with_quiet(room: Path, tmp_path: Path) -> None:
    err, stdout, status = _solve_on_pty([*_args(room, tmp_path / "q.csv"), "--quiet"])
    assert status == 0 and err.strip() == "" and stdout == ""
    assert (tmp_path / "q.csv").is_file()


def test_no_bar_when_stderr_is_not_a_terminal(room: Path, tmp_path: Path) -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "robustrtk", *_args(room, tmp_path / "p.csv")],
        capture_output=True,
        text=True,
        env={**os.environ, "PYTHONPATH": str(SRC)},
    )
    assert proc.returncode == 0
    assert "epochs/s" not in proc.stderr and "\r" not in proc.stderr and "\x1b" not in proc.stderr
    assert "fix rate" in proc.stdout  # the summary still goes to stdout


def _summary_value(stdout: str, name: str) -> str:
    m = re.search(rf"^  {name}\s{{2,}}(.*)$", stdout, re.M)
    assert m, f"no {name!r} line in:\n{stdout}"
    return m.group(1)


def _check_summary(stdout: str, table: object) -> None:
    t = np.asarray(table.t_s)  # type: ignore[attr-defined]
    st = np.asarray(table.status)  # type: ignore[attr-defined]
    solved = st != "none"
    fixed = np.isin(st, ["fixed", "partial"])
    epochs = _summary_value(stdout, "epochs")
    assert epochs.startswith(f"{len(st)} ({int(solved.sum())} solved")
    rate = _summary_value(stdout, "fix rate")
    full = int((st == "fixed").sum())
    assert rate.startswith(f"{100 * fixed.sum() / len(st):.1f} % of {len(st)} epochs (Q=1): fixed {full} (")
    first = _summary_value(stdout, "first fix")
    assert first == f"{t[np.flatnonzero(fixed)[0]] - t[0]:.0f} s after the first epoch"


def test_summary_equals_a_recount_of_the_pos(
    shared_data: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    d = shared_data / "geonet_0759_3040_static_3km"
    out = tmp_path / "rtk.pos"
    argv = [
        "solve",
        str(d / "07590920.05o"),
        "--base",
        str(d / "30400920.05o"),
        "--nav",
        str(d / "07590920.05n"),
        "--base-pos=-3978241.958,3382840.234,3649900.853",
        "--mode",
        "rtk",
        "--out",
        str(out),
    ]
    assert run(argv) == 0
    stdout = capsys.readouterr().out
    pos = read_pos(out)
    # every epoch of this pair is solved, so the .pos holds them all (no 'none' line is written)
    _check_summary(stdout, pos)
    flagged = _summary_value(stdout, "faults flagged")
    assert "DD rows down-weighted" in flagged
    # without --diagnostics the run keeps no row, only their counts: the same summary as a
    # run that keeps them and writes them
    diag = tmp_path / "diag.csv"
    assert run([*argv, "--diagnostics", str(diag)]) == 0
    assert _summary_value(capsys.readouterr().out, "faults flagged") == flagged
    rows = read_diagnostics_csv(diag)
    n_down = int(np.sum((rows.factor > 1.0) & np.isfinite(rows.factor)))
    n_rej = int(np.sum(rows.factor == np.inf))
    n_epochs = np.unique(rows.t_s[rows.factor > 1.0]).size
    assert flagged == f"{n_down} DD rows down-weighted, {n_rej} rejected, in {n_epochs} epochs"
