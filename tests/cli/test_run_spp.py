"""``robustrtk run --mode spp``: the Kalman SPP of one receiver in real time.

* The galway s1 rover's UBX log replayed as fast as possible, with the RINEX navigation
  file: every line of the ``.pos`` is the one ``solve --mode spp --kalman`` writes for the
  same log (time, Q = 5, ns as written; the numbers to one unit of their last digit: the
  stream computes each epoch's satellites alone, the file 256 epochs at a time).
* Its NMEA says what it is: GGA quality 1, RMC mode ``A`` (autonomous), not differential.
* What does not apply to one receiver is refused in one line naming the flag (exit 2):
  ``--base``, ``--base-pos``, ``--base-wait``; so is what needs the whole record
  (``--smoother``) and the least-squares filter (``run`` is the Kalman SPP).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from robustrtk.cli.entry import run as cli_run
from robustrtk.cli.main import main
from robustrtk.io.streams import rmc_sentence

ROVER, NAV, BASE = "rover-20181004-1237.ubx.gz", "rover-20181004-1237.nav", "base-20181004-1236.rtcm3"


def solution_lines(path: Path) -> list[list[str]]:
    return [ln.split() for ln in path.read_text().splitlines() if not ln.startswith("%")]


@pytest.mark.slow
def test_replayed_rover_log_is_the_file_kalman_spp(galway_s1: Path, tmp_path: Path) -> None:
    out_run, out_solve = tmp_path / "run.pos", tmp_path / "solve.pos"
    rover, nav = str(galway_s1 / ROVER), str(galway_s1 / NAV)
    run = ["run", "--mode", "spp", "--rover", rover, "--nav", nav, "--speed", "0"]
    nmea = tmp_path / "run.nmea"
    assert cli_run([*run, "--out", str(out_run), "--nmea", str(nmea), "--quiet"]) == 0
    solve = ["solve", rover, "--mode", "spp", "--kalman", "--nav", nav]
    assert cli_run([*solve, "--out", str(out_solve), "--quiet"]) == 0
    got, want = solution_lines(out_run), solution_lines(out_solve)
    assert len(want) == 1205
    assert [[r[c] for c in (0, 1, 5, 6)] for r in got] == [[r[c] for c in (0, 1, 5, 6)] for r in want]
    assert {r[5] for r in got} == {"5"}
    cols = (2, 3, 4, 7, 8, 9, 10, 11, 12)
    g = np.array([[float(r[c]) for c in cols] for r in got])
    w = np.array([[float(r[c]) for c in cols] for r in want])
    unit = np.array([1e-9, 1e-9, 1e-4] + [1e-4] * 6)
    assert np.all(np.abs(g - w) <= 1.5 * unit)
    # NMEA: GGA quality 1 (autonomous GNSS fix), RMC mode A, a pair per solution
    sentences = nmea.read_bytes().decode("ascii").split("\r\n")[:-1]
    assert len(sentences) == 2 * len(got)
    assert {s.split(",")[6] for s in sentences[0::2]} == {"1"}
    assert {s.split("*")[0][-1] for s in sentences[1::2]} == {"A"}


def test_rmc_mode_says_autonomous_or_differential() -> None:
    pos = [3774088.68, -601663.04, 5089318.23]
    statuses = ("single", "dgnss", "fixed")
    mode = {st: rmc_sentence(1.2e9, pos, None, True, st).split("*")[0][-1] for st in statuses}
    assert mode == {"single": "A", "dgnss": "D", "fixed": "D"}
    assert rmc_sentence(1.2e9, pos, None, False, "single").split("*")[0][-1] == "N"


@pytest.mark.parametrize(
    ("extra", "flag"),
    [
        (["--base", BASE], "--base"),
        (["--base-pos", "1,2,3"], "--base-pos"),
        (["--base-wait", "5"], "--base-wait"),
        (["--filter", "lsq"], "--filter"),
        (["--smoother"], "smoother"),
    ],
)
def test_what_does_not_apply_to_one_receiver_is_refused(extra: list[str], flag: str, tmp_path: Path) -> None:
    rover = tmp_path / "rover.ubx"
    rover.write_bytes(b"\xb5b")
    out = tmp_path / "x.pos"
    args = ["run", "--mode", "spp", "--rover", str(rover), *extra, "--out", str(out), "--quiet"]
    r = CliRunner().invoke(main, args)
    assert r.exit_code == 2
    lines = r.output.strip().splitlines()
    assert len(lines) == 1 and flag in lines[0], r.output
    assert not out.exists()
