"""GNSS commands: ``solve`` on RINEX input (SPP / DGNSS) and ``info``.

:func:`solve_gnss_cli` holds the logic of ``robustrtk solve ROVER --nav NAV --mode
{spp,dgnss} ...``; the ``solve`` command of :mod:`robustrtk.cli.main` calls it when the
input is not a pseudolite table. :data:`info` is the ``robustrtk info FILE`` command.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import click
import numpy as np

from robustrtk.core import InputError, Solution
from robustrtk.io.info import format_summary, summarize
from robustrtk.io.rinex_obs import read_rinex_obs
from robustrtk.io.solution import write_nmea, write_pos, write_solution_csv
from robustrtk.pipeline.gnss import dgnss_config, solve_dgnss, solve_spp_file
from robustrtk.pipeline.spp import SppConfig

OUTPUT_SUFFIXES = (".pos", ".csv", ".nmea")


def parse_xyz(text: str, what: str = "--base-pos") -> np.ndarray:
    """``"X,Y,Z"`` (ECEF m) -> ndarray (3,); :class:`InputError` naming ``what`` otherwise."""
    parts = [p for p in text.replace(" ", ",").split(",") if p]
    try:
        vals = np.array([float(p) for p in parts])
    except ValueError:
        raise InputError(f"{what}: expected X,Y,Z in metres (ECEF), got {text!r}") from None
    if vals.shape != (3,) or not np.all(np.isfinite(vals)):
        raise InputError(f"{what}: expected three finite numbers X,Y,Z, got {text!r}")
    return vals


def write_solutions(solutions: Sequence[Solution], out: str | Path) -> None:
    """Write by extension: ``.pos`` (RTKLIB llh), ``.csv``, ``.nmea`` (GGA)."""
    suffix = Path(out).suffix.lower()
    if suffix == ".pos":
        write_pos(solutions, out, header_lines=("program: robustrtk",))
    elif suffix == ".csv":
        write_solution_csv(solutions, out)
    elif suffix == ".nmea":
        write_nmea(solutions, out)
    else:
        raise InputError(f"--out: expected a file ending in {', '.join(OUTPUT_SUFFIXES)}, got {str(out)!r}")


def _bar(enabled: bool) -> tuple[Callable[[int, int], None] | None, Callable[[], None]]:
    if not enabled:
        return None, lambda: None
    state: dict[str, Any] = {}

    def update(done: int, total: int) -> None:
        if "bar" not in state:
            state["bar"] = click.progressbar(length=total, label="solving", file=sys.stderr)
            state["bar"].__enter__()
        state["bar"].update(done - state.get("done", 0))
        state["done"] = done

    def close() -> None:
        if "bar" in state:
            state["bar"].__exit__(None, None, None)

    return update, close


def solve_gnss_cli(
    rover: str,
    out: str,
    nav: Sequence[str] = (),
    base: str | None = None,
    base_pos: str | None = None,
    mode: str = "spp",
    filter: bool = False,
    robust: str | None = None,
    elev_mask: float = 15.0,
    systems: str | None = None,
    progress: bool = True,
    freqs: str | None = None,
    overrides: dict[str, Any] | None = None,
    diagnostics: str | None = None,
    smooth: bool = False,
    **_ignored: Any,
) -> list[Solution]:
    """Solve a RINEX rover file (SPP, DGNSS or RTK) and write the solutions.

    Parameters
    ----------
    rover : str
        Rover RINEX observation file.
    out : str
        Output path (``.pos``, ``.csv`` or ``.nmea``).
    nav : sequence of str
        Broadcast navigation files (at least one).
    base : str, optional
        Base RINEX observation file (DGNSS).
    base_pos : str, optional
        ``"X,Y,Z"`` base ECEF (m); default the base header position (with a warning).
    mode : {"spp", "dgnss", "rtk"}
    filter : bool
        SPP: the Kalman SPP instead of epoch-wise least squares.
    robust : str, optional
        Robust policy; default the mode's (Kalman SPP ``postfit``, DGNSS ``igg3``, RTK
        ``prefit+postfit``).
    elev_mask : float
        Elevation mask (deg).
    systems : str, optional
        System letters to use (``GRECJ``).
    progress : bool
        Progress bar on stderr.
    freqs : str, optional
        DGNSS and RTK frequency slots (``"L1+L2"``).
    overrides : dict, optional
        Engine settings (config file, then flags) over the mode's defaults (DGNSS, RTK).
    diagnostics : str, optional
        Per-DD diagnostics CSV (DGNSS, RTK).
    smooth : bool
        Kalman SPP: forward-backward (RTS) smoothing (post-processing).

    Returns
    -------
    list of Solution (as written).
    """
    if not nav:
        raise InputError("--nav: at least one RINEX navigation file is required for GNSS input")
    if mode not in ("spp", "dgnss", "rtk"):
        raise InputError(f"--mode: expected spp, dgnss or rtk for RINEX input, got {mode!r}")
    overrides = dict(overrides or {})
    if robust is not None:
        overrides["robust"] = robust
    if Path(out).suffix.lower() not in OUTPUT_SUFFIXES:
        raise InputError(f"--out: expected a file ending in {', '.join(OUTPUT_SUFFIXES)}, got {out!r}")
    if systems is not None:
        systems = systems.upper()
    update, close = _bar(progress and sys.stderr.isatty())
    try:
        if mode == "spp":
            spp_kw: dict[str, Any] = {"robust": robust} if robust else {}
            if smooth:
                spp_kw["smoother"] = True
            cfg = SppConfig(elev_mask_deg=elev_mask, **spp_kw)
            epochs = solve_spp_file(rover, list(nav), cfg, kalman=filter, systems=systems, progress=update)
            sols = [e.to_solution() for e in epochs]
        else:
            if base is None:
                raise InputError(f"--base: {mode.upper()} needs a base RINEX observation file")
            pos = parse_xyz(base_pos) if base_pos is not None else None
            if mode == "dgnss":
                res = solve_dgnss(
                    rover,
                    base,
                    list(nav),
                    pos,
                    dgnss_config(**overrides),
                    elev_mask_deg=elev_mask,
                    systems=systems,
                    progress=update,
                    freqs=freqs or "L1+L2",
                )
            else:
                from robustrtk.pipeline.rtk_gnss import rtk_gnss_config, solve_rtk

                res = solve_rtk(  # type: ignore[assignment]
                    rover,
                    base,
                    list(nav),
                    pos,
                    rtk_gnss_config(**overrides),
                    freqs=freqs or "L1+L2",
                    systems=systems,
                    elev_mask_deg=elev_mask,
                    progress=update,
                )
            sols = res.solutions
            if diagnostics:
                from robustrtk.io.solution import write_diagnostics_csv

                write_diagnostics_csv(
                    [
                        (d.t_s, d.dd, d.innovation, d.residual, d.std_residual, d.dv, d.factor, d.situation)
                        for d in res.run.diagnostics
                    ],
                    diagnostics,
                )
    finally:
        close()
    write_solutions(sols, out)
    return sols


@click.command("info")
@click.argument("path", type=click.Path(dir_okay=False))
@click.option("--systems", default=None, help="System letters to keep (e.g. GEJ).")
def info(path: str, systems: str | None) -> None:
    """Summarise a RINEX observation file (epochs, interval, systems, signals)."""
    try:
        batch = read_rinex_obs(path, systems=systems.upper() if systems else None)
    except InputError as exc:
        click.echo(f"error: {exc}", err=True)
        sys.exit(2)
    click.echo(format_summary(summarize(batch)))


__all__ = ["info", "parse_xyz", "solve_gnss_cli", "write_solutions"]
