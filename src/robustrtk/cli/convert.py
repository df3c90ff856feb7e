"""``robustrtk convert LOG --out FILE.obs``: observations of any readable input to RINEX 3.04.

The input kind is detected from its content (:func:`robustrtk.io.readers.read_observations`):
an Android GnssLogger log, a GSDC ``device_gnss.csv`` or a RINEX observation file. Bad input
is reported as one line ``error: <file>:<line>: <what>`` with exit status 2.
"""

from __future__ import annotations

from typing import Any

import click

from robustrtk.cli.errors import one_line_errors
from robustrtk.errors import InputError


@click.command("convert", context_settings={"help_option_names": ["-h", "--help"]})
@click.argument("log", metavar="LOG")
@click.option("--out", "out", required=True, metavar="FILE.obs", help="Output RINEX 3.04 observation file.")
@click.option("--systems", default=None, metavar="LETTERS", help="Systems to keep, e.g. GE [all].")
@click.option(
    "--clock",
    type=click.Choice(["epoch", "first"]),
    default=None,
    help="Android logs: FullBiasNanos of each epoch (steered clock) or of the first epoch "
    "(hardware clock, as GSDC) for the pseudoranges [epoch].",
)
@one_line_errors
def convert(log: str, out: str, systems: str | None, clock: str | None) -> None:
    """Convert observations in LOG (GnssLogger, device_gnss.csv, RINEX) to RINEX 3.04."""
    from robustrtk.cli.paths import check_output_paths
    from robustrtk.io.readers import detect_format, read_observations
    from robustrtk.io.rinex_write import write_rinex_obs

    check_output_paths([("LOG", log)], [("--out", out)])

    kw: dict[str, Any] = {}
    if systems:
        kw["systems"] = systems.upper()
    if clock is not None:
        if detect_format(log) != "gnsslogger":
            raise InputError("--clock applies to GnssLogger logs only", path=log)
        kw["clock"] = clock
    batch = read_observations(log, **kw)
    if len(batch) == 0:
        raise InputError("no epochs with observations", path=log)
    stats = write_rinex_obs(batch, out)
    click.echo(
        f"wrote {out}: {stats['epochs']} epochs, {stats['records']} satellite records, "
        f"{len(batch.tx_ids)} transmitters, signals {' '.join(batch.signals)}"
    )
