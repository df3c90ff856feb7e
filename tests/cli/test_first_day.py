"""What ``solve`` assumes without being told, and what it counts: mode, base position, ns."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from click.testing import CliRunner, Result

from robustrtk.cli.infer import has_phase, infer_gnss_mode
from robustrtk.cli.main import main
from robustrtk.io.solution import read_pos
from robustrtk.pipeline.results import DiagRow
from robustrtk.pipeline.satcount import satellites_used

GEONET = "geonet_0759_3040_static_3km"
KAMAKURA = "kamakura_kinematic_5km"


def _run(*args: object) -> Result:
    return CliRunner().invoke(main, [str(a) for a in args])


def _row(dd: str, kind: str = "phase", factor: float = 1.0) -> DiagRow:
    nan = float("nan")
    return DiagRow(0.0, dd, kind, nan, nan, nan, nan, factor, 1)


def test_satellites_used_counts_satellites_not_rows() -> None:
    ids = ["G05:L1", "G13:L1", "G15:L1", "G05:L2", "G13:L2", "G15:L2", "E07:L1", "E26:L1", "PL-1", "PL-2"]
    rows = [
        _row("G05:L1-G15:L1"), _row("G13:L1-G15:L1"), _row("G05:L2-G15:L2"),
        _row("G13:L2-G15:L2", "code"), _row("E26:L1-E07:L1", factor=float("inf")),
        _row("integrity:widened", "integrity"),
    ]  # fmt: skip
    # 4 rows of G05, G13, G15 on two bands: 3 satellites; E26-E07 rejected; events ignored
    assert satellites_used(rows, ids) == 3
    assert satellites_used(rows[:5] + [_row("E26:L1-E07:L1")], ids) == 5
    # an id holding "-" is split where both parts are ids
    assert satellites_used([_row("PL-1-PL-2", "code")], ids) == 2
    assert satellites_used([], ids) == 0


def _rinex_header(path: Path, types: str) -> Path:
    n = len(types.split())
    path.write_text(
        "     2.11           OBSERVATION DATA    G (GPS)             RINEX VERSION / TYPE\n"
        f"{n:6d}    " + "".join(f"{t:>6s}" for t in types.split()).ljust(50) + "# / TYPES OF OBSERV\n"
        "                                                            END OF HEADER\n"
    )
    return path


def test_mode_inferred_from_the_phase_the_headers_list(tmp_path: Path) -> None:
    with_phase = _rinex_header(tmp_path / "a.obs", "C1 L1 P2 L2")
    code_only = _rinex_header(tmp_path / "b.obs", "C1 P2 D1")
    assert has_phase(with_phase) and not has_phase(code_only)
    assert infer_gnss_mode(with_phase, with_phase)[0] == "rtk"
    mode, why = infer_gnss_mode(with_phase, code_only)
    assert mode == "dgnss" and "b.obs records no carrier phase" in why


def test_kamakura_without_mode_or_base_pos(shared_data: Path, tmp_path: Path) -> None:
    """kamakura with --base only: rtk inferred and said; the header base position is used
    with one notice naming its offset from the base's own SPP (4.4 m, within that SPP's σ)
    and --base-pos, and the offset in the summary; no Python warning; ns = satellites (16
    on the first epoch, as RTKLIB's .pos)."""
    d = shared_data / KAMAKURA
    out = tmp_path / "k.pos"
    res = _run(
        "solve", d / "SEPT265G.21O", "--base", d / "3034265G.21O", "--nav", d / "SEPT2650.21P", "--out", out
    )
    assert res.exit_code == 0, res.output
    err = res.stderr
    assert "note: mode rtk: --base given and both receivers record carrier phase" in err
    assert "base position from the RINEX header" in err and "--base-pos X,Y,Z" in err
    assert "4.39 m from the base's own mean single-point position" in err
    assert "Warning" not in err
    assert "RINEX header, 4.39 m from the base's own SPP" in res.stdout
    assert "fixed 54 (15.0 %), partial 304 (84.4 %)" in res.stdout
    tb = read_pos(out)
    rtklib = read_pos(d / "rtklib" / "fh.pos")
    assert tb.n_used.max() <= 20 and tb.n_used[0] == 16 == rtklib.n_used[0]


def test_header_contradicted_by_the_base_is_refused(shared_data: Path, tmp_path: Path) -> None:
    """A header 300 m off the base's observations: refused naming both positions and
    --base-pos (exit 2); with --force one warning line and the run goes on."""
    d = shared_data / GEONET
    text = (d / "30400920.05o").read_text()
    base = tmp_path / "base.obs"
    base.write_text(text.replace(" -3978242.4348  3382841.1715", " -3978042.4348  3383041.1715", 1))
    args = [
        "solve",
        d / "07590920.05o",
        "--base",
        base,
        "--nav",
        d / "07590920.05n",
        "--out",
        tmp_path / "g.pos",
    ]
    res = _run(*args)
    assert res.exit_code == 2
    msg = res.stderr
    assert "--base-pos" in msg and "(-3978042.43,3383041.17," in msg and "mean single-point position" in msg
    assert not (tmp_path / "g.pos").exists()
    res = _run(*args, "--force")
    assert res.exit_code == 0, res.output
    assert res.stderr.count("warning: base position from the RINEX header") == 1
    assert "used because of --force" in res.stderr
    assert np.isfinite(read_pos(tmp_path / "g.pos").pos_m).all()


GALWAY_S1 = "galway_m8p_l1_lowcost/s1_static"


def test_raw_logs_bring_their_own_ephemerides(shared_data: Path, tmp_path: Path) -> None:
    """A u-blox rover log and an RTCM 3 base stream solve without ``--nav``: the rover's
    RXM-SFRBX subframes are the navigation source, the same solutions as naming the log as
    ``--nav`` (and the summary says where the ephemerides came from)."""
    d = shared_data / GALWAY_S1
    rover, base = d / "rover-20181004-1237.ubx.gz", d / "base-20181004-1236.rtcm3"
    common = ("--base", base, "--freqs", "L1", "--time-end", "12:39:30")
    own = _run("solve", rover, *common, "--out", tmp_path / "own.pos")
    assert own.exit_code == 0, own.output
    assert "ephemerides from rover-20181004-1237.ubx.gz" in own.output
    named = _run("solve", rover, *common, "--nav", rover, "--out", tmp_path / "named.pos", "--quiet")
    assert named.exit_code == 0, named.output
    lines = [
        [ln for ln in (tmp_path / f).read_text().splitlines() if not ln.startswith("%")]
        for f in ("own.pos", "named.pos")
    ]
    assert len(lines[0]) > 60
    assert lines[0] == lines[1]


def test_rinex_without_nav_names_what_serves(shared_data: Path, tmp_path: Path) -> None:
    d = shared_data / GEONET
    res = _run("solve", d / "07590920.05o", "--out", tmp_path / "x.pos")
    assert res.exit_code == 2
    assert "--nav" in res.output and "UBX / RTCM 3" in res.output
    assert not (tmp_path / "x.pos").exists()
