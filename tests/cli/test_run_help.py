"""``run`` as a new user meets it: its help lists its own options (sources, streams,
outputs), its ``--rover`` source is not the pseudolite ``--rover-name`` setting, and a file
that is not a receiver's byte stream is named, not read as nothing."""

from __future__ import annotations

from pathlib import Path

import click
import pytest
from click.testing import CliRunner

from robustrtk.cli.main import main


@pytest.mark.parametrize("command", ["run", "solve"])
def test_help_lists_every_own_option(command: str) -> None:
    from robustrtk.cli.options import SOLVE_LEAVES

    cmd = main.get_command(click.Context(main), command)
    assert cmd is not None
    out = CliRunner().invoke(main, [command, "--help"]).output
    own = [p for p in cmd.get_params(click.Context(cmd)) if isinstance(p, click.Option)]
    leaves = set(SOLVE_LEAVES)
    for p in own:
        flag = next(o for o in p.opts if o.startswith("--"))
        if p.name in leaves and flag != "--mode":
            continue  # a configuration setting: the short page shows a few, --help-all every one
        assert flag in out, f"{command} --help: {flag} missing"
    usage = out.splitlines()[0]
    assert usage.endswith("OBS") == (command == "solve")


def test_run_help_says_its_own_modes_and_sources() -> None:
    out = CliRunner().invoke(main, ["run", "--help"]).output
    assert "spp, dgnss or rtk; default rtk" in out
    for flag in ("--rover", "--speed", "--nmea", "--time-ref", "--beidou-time", "--stall-timeout-s"):
        assert flag in out
    assert "default spp" not in out.split("Settings most often changed")[0]


def test_rover_name_is_not_the_rover_source() -> None:
    r = CliRunner().invoke(main, ["run", "--rover-name", "foo", "--base", "b.rtcm3", "--out", "x.pos"])
    assert r.exit_code == 2 and "Missing option '--rover'" in r.output
    r = CliRunner().invoke(
        main, ["run", "--rover", "no-such.ubx", "--rover-name", "foo", "--base", "b.rtcm3", "--out", "x.pos"]
    )
    assert r.exit_code == 2 and "--rover-name: does not apply" in r.output


def test_no_two_parameters_of_a_command_share_a_name() -> None:
    """Two options with one name write one value: the later silently wins (how
    ``--rover-name`` once became ``run``'s rover source)."""
    from collections import Counter

    ctx = click.Context(main)
    for name in main.list_commands(ctx):
        cmd = main.get_command(ctx, name)
        assert cmd is not None
        counts = Counter(p.name for p in cmd.get_params(click.Context(cmd)))
        assert [n for n, k in counts.items() if k > 1] == [], name


def test_run_refuses_a_rinex_file_as_a_stream_in_one_line(tmp_path: Path) -> None:
    """A RINEX file given as a source was read as bytes holding no frame: ``run: 0 epochs
    solved``, exit 0. It is named now, exit 2; a navigation file as the base too."""
    obs = tmp_path / "rover.obs"
    obs.write_text(
        "     3.04           OBSERVATION DATA    M                   RINEX VERSION / TYPE\n"
        "G    2 C1C L1C                                              SYS / # / OBS TYPES\n"
        "                                                            END OF HEADER\n"
    )
    nav = tmp_path / "base.nav"
    nav.write_text(
        "     3.04           N: GNSS NAV DATA    M                   RINEX VERSION / TYPE\n"
        "                                                            END OF HEADER\n"
    )
    out = tmp_path / "x.pos"
    r = CliRunner().invoke(
        main, ["run", "--rover", str(obs), "--base", str(nav), "--out", str(out), "--quiet"]
    )
    assert r.exit_code == 2
    lines = [ln for ln in r.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and str(obs) in lines[0] and "RINEX observation file" in lines[0]
    assert "Traceback" not in r.output and not out.exists()
    r = CliRunner().invoke(
        main, ["run", "--rover", str(nav), "--base", str(obs), "--out", str(out), "--quiet"]
    )
    assert r.exit_code == 2 and "--rover: a RINEX navigation file (give it as --nav)" in r.output


def test_run_says_when_the_rover_sent_no_frame(tmp_path: Path) -> None:
    """Bytes in which no UBX or RTCM 3 frame is found: one line, exit 2 (was exit 0 and a
    .pos holding its header only, without a word)."""
    import numpy as np

    junk = tmp_path / "junk.bin"
    junk.write_bytes(
        np.random.default_rng(0)
        .integers(0, 256, 5000, dtype=np.uint8)
        .tobytes()
        .replace(b"\xd3", b"\x00")
        .replace(b"\xb5", b"\x00")
    )
    r = CliRunner().invoke(
        main,
        [
            "run",
            "--rover",
            str(junk),
            "--base",
            str(junk),
            "--out",
            str(tmp_path / "x.pos"),
            "--speed",
            "0",
            "--quiet",
        ],
    )
    assert r.exit_code == 2
    assert r.output.strip() == f"error: --rover: {junk}: no UBX or RTCM 3 frame in what it sent"
