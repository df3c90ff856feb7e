"""``run --help`` lists the command's own options (sources, streams, outputs), not solve's,
and ``run``'s ``--rover`` source is not the pseudolite ``--rover-name`` setting."""

from __future__ import annotations

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
    assert "dgnss or rtk; default rtk" in out
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
