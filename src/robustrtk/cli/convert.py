"""``robustrtk convert LOG --out FILE.obs [--nav-out FILE.nav]``: observations (and broadcast
ephemerides) of any readable input to RINEX 3.04.

The input kind is detected from its content (:func:`robustrtk.io.readers.read_observations`):
an Android GnssLogger log, a GSDC ``device_gnss.csv``, a RINEX observation file, a u-blox UBX
log (RXM-RAWX, RXM-SFRBX) or an RTCM 3 stream, plain or compressed. UBX and RTCM 3 logs also
give a navigation file (``--nav-out``) with the ephemerides decoded from their navigation
messages. RTCM 3 carries no week number: ``--time-ref`` gives the approximate time when the
stream has no Galileo/BeiDou ephemeris and its file name no date; ``--beidou-time gpst`` reads
the BeiDou MSM epoch times as GPST for encoders that write them so (the decoder counts BeiDou
epochs 14 s off the others). Bad input is reported as one
line ``error: <file>:<line>: <what>`` with exit status 2.
"""

from __future__ import annotations

from typing import Any

import click

from robustrtk.cli.errors import one_line_errors
from robustrtk.errors import InputError


@click.command("convert", context_settings={"help_option_names": ["-h", "--help"]})
@click.argument("log", metavar="LOG")
@click.option("--out", "out", required=True, metavar="FILE.obs", help="Output RINEX 3.04 observation file.")
@click.option(
    "--nav-out",
    "nav_out",
    default=None,
    metavar="FILE.nav",
    help="UBX and RTCM 3 logs: also write the decoded ephemerides as RINEX 3.04 navigation.",
)
@click.option("--systems", default=None, metavar="LETTERS", help="Systems to keep, e.g. GE [all].")
@click.option(
    "--time-ref",
    "time_ref",
    default=None,
    metavar="'YYYY/MM/DD HH:MM:SS'",
    help="RTCM 3: approximate GPST of the stream (within half a week) [from the stream's "
    "Galileo/BeiDou ephemerides or a date in the file name].",
)
@click.option(
    "--beidou-time",
    "beidou_time",
    type=click.Choice(["bdt", "gpst"]),
    default=None,
    help="RTCM 3: time system of the BeiDou MSM epoch times; gpst for encoders that write "
    "GPST there (their BeiDou epochs come 14 s after the others) [bdt, as RTCM 10403.3].",
)
@click.option(
    "--clock",
    type=click.Choice(["epoch", "first"]),
    default=None,
    help="Android logs: FullBiasNanos of each epoch (steered clock) or of the first epoch "
    "(hardware clock, as GSDC) for the pseudoranges [epoch].",
)
@one_line_errors
def convert(
    log: str,
    out: str,
    nav_out: str | None,
    systems: str | None,
    time_ref: str | None,
    beidou_time: str | None,
    clock: str | None,
) -> None:
    """Convert observations in LOG (GnssLogger, device_gnss.csv, RINEX, UBX, RTCM 3) to RINEX 3.04."""
    from robustrtk.cli.paths import check_output_paths
    from robustrtk.io.readers import detect_format, read_observations
    from robustrtk.io.rinex_write import write_rinex_obs

    check_output_paths([("LOG", log)], [("--out", out)] + ([("--nav-out", nav_out)] if nav_out else []))

    kw: dict[str, Any] = {}
    if systems:
        kw["systems"] = systems.upper()
    fmt = detect_format(log)
    if clock is not None:
        if fmt != "gnsslogger":
            raise InputError("--clock applies to GnssLogger logs only", path=log)
        kw["clock"] = clock
    if time_ref is not None and fmt != "rtcm3":
        raise InputError("--time-ref applies to RTCM 3 streams only", path=log)
    if beidou_time is not None and fmt != "rtcm3":
        raise InputError("--beidou-time applies to RTCM 3 streams only", path=log)
    if nav_out is not None and fmt not in ("ubx", "rtcm3"):
        raise InputError(f"--nav-out applies to UBX and RTCM 3 logs only (this is {fmt})", path=log)
    nav = None
    if fmt in ("ubx", "rtcm3"):
        batch, nav, counts = _read_raw(log, fmt, time_ref, beidou_time == "gpst")
        if systems:
            batch = batch.select_systems(systems.upper())
        _echo_counts(log, counts)
    else:
        batch = read_observations(log, **kw)
    if len(batch) == 0:
        raise InputError("no epochs with observations", path=log)
    stats = write_rinex_obs(batch, out)
    click.echo(
        f"wrote {out}: {stats['epochs']} epochs, {stats['records']} satellite records, "
        f"{len(batch.tx_ids)} transmitters, signals {' '.join(batch.signals)}"
    )
    if nav_out is not None and nav is not None:
        from robustrtk.io.rinex_nav_write import write_rinex3_nav

        write_rinex3_nav(nav, nav_out)
        n = {s: len(nav.kepler[s]) for s in nav.kepler if len(nav.kepler[s])}
        n["R"] = len(nav.glonass)
        click.echo(f"wrote {nav_out}: ephemerides " + ", ".join(f"{s} {v}" for s, v in n.items() if v))


def _read_raw(
    log: str, fmt: str, time_ref: str | None, beidou_gpst: bool = False
) -> tuple[Any, Any, dict[str, int]]:
    if fmt == "ubx":
        from robustrtk.io.ubx import read_ubx

        return read_ubx(log)
    from robustrtk.io.rtcm3 import read_rtcm3
    from robustrtk.timeutil import parse_gpst_instant

    t_ref = None if time_ref is None else parse_gpst_instant(time_ref, 0.0, "--time-ref")
    return read_rtcm3(log, t_ref_s=t_ref, beidou_gpst=beidou_gpst)


def _echo_counts(log: str, counts: dict[str, int]) -> None:
    """One line of what the decoder skipped (corrupt frames, unknown messages), if anything."""
    bad = {
        k: v for k, v in counts.items() if k.startswith(("bad", "short", "truncated")) or k == "skipped_bytes"
    }
    bad = {k: v for k, v in bad.items() if v}
    if bad:
        click.echo(f"{log}: skipped " + ", ".join(f"{k} {v}" for k, v in sorted(bad.items())), err=True)
    n_off = counts.get("BeiDou epochs 14 s off", 0)
    if n_off:
        click.echo(
            f"{log}: {n_off} BeiDou MSM epochs 14 s off the other systems' (time system of the "
            "encoder: see --beidou-time)",
            err=True,
        )
