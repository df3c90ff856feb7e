"""GNSS commands: ``solve`` on RINEX input (SPP, DGNSS, RTK) and ``info``.

:func:`run_gnss` runs ``robustrtk solve ROVER --nav NAV ...`` with the configuration
resolved by :func:`robustrtk.cli.settings.resolve_config`; the ``solve`` command of
:mod:`robustrtk.cli.main` calls it when the input is not a pseudolite table. :data:`info`
is the ``robustrtk info FILE`` command.
"""

from __future__ import annotations

import inspect
import os
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from robustrtk.cli.errors import one_line
from robustrtk.cli.gnss_messages import (
    kalman_hint_counts,
    note_masked,
    nothing_solved,
    say_hint,
    warn,
    warn_read,
    warn_refused,
)
from robustrtk.errors import InputError

if TYPE_CHECKING:  # the solver modules are imported by the commands that run them (start-up time)
    import numpy as np

    from robustrtk.core import Solution
    from robustrtk.pipeline.api import SolutionSeries
    from robustrtk.pipeline.config import Config
    from robustrtk.pipeline.spp_stream import SppRunCounts

OUTPUT_SUFFIXES = (".pos", ".csv", ".nmea", ".kml", ".gpx")


def parse_xyz(text: str, what: str = "--base-pos") -> np.ndarray:
    """``"X,Y,Z"`` (ECEF m) -> ndarray (3,); :class:`InputError` naming ``what`` otherwise."""
    import numpy as np

    parts = [p for p in text.replace(" ", ",").split(",") if p]
    try:
        vals = np.array([float(p) for p in parts])
    except ValueError:
        raise InputError(f"{what}: expected X,Y,Z in metres (ECEF), got {text!r}") from None
    if vals.shape != (3,) or not np.all(np.isfinite(vals)):
        raise InputError(f"{what}: expected three finite numbers X,Y,Z, got {text!r}")
    return vals


def output_kind(out: str | Path, fmt: str | None = None) -> str:
    """``pos``, ``csv``, ``nmea``, ``kml`` or ``gpx`` from ``fmt`` or the extension of ``out``."""
    if fmt is not None:
        return fmt.lower()
    suffix = Path(out).suffix.lower()
    if suffix not in OUTPUT_SUFFIXES:
        raise InputError(f"--out: expected a file ending in {', '.join(OUTPUT_SUFFIXES)}, got {str(out)!r}")
    return suffix.lstrip(".")


def check_output_kind(out: str | Path, fmt: str | None, pos_frame: str) -> str:
    """The output kind (:func:`output_kind`), refused before any work when it cannot hold
    positions of ``pos_frame`` (a local pseudolite frame goes to CSV only)."""
    kind = output_kind(out, fmt)
    if kind not in ("pos", "csv", "nmea", "gga", "kml", "gpx"):
        raise InputError(f"--format: expected csv, pos, nmea, kml or gpx, got {kind!r}")
    if pos_frame != "ecef" and kind != "csv":
        raise InputError(
            f"--out: {kind} needs ECEF (GNSS) positions; {pos_frame}-frame (pseudolite) solutions go to .csv",
            str(out),
        )
    return kind


def write_solutions(
    solutions: Sequence[Solution],
    out: str | Path,
    fmt: str | None = None,
    pos_frame: str = "ecef",
    *,
    inputs: Sequence[str] = (),
    ref_pos_ecef_m: Any = None,
) -> None:
    """Write as ``fmt`` or by extension: ``.pos`` (RTKLIB llh), ``.csv``, ``.nmea`` (GGA), or a
    map track coloured by status, ``.kml`` or ``.gpx`` (:mod:`robustrtk.io.tracks`).
    ``pos_frame`` is the frame of the positions (``ecef`` or ``local``), as the solver
    reports it; only CSV takes a local frame. ``inputs`` (file names) and ``ref_pos_ecef_m``
    (the fixed base position, ECEF m) go into the ``.pos`` header as RTKLIB's ``% inp file``
    and ``% ref pos`` lines."""
    kind = check_output_kind(out, fmt, pos_frame)
    if kind == "pos":
        from robustrtk.io.solution_pos import write_pos

        write_pos(solutions, out, inputs=inputs, ref_pos_ecef_m=ref_pos_ecef_m, pos_frame=pos_frame)
    elif kind == "csv":
        from robustrtk.io.solution_csv import write_solution_csv

        write_solution_csv(solutions, out)
    elif kind in ("nmea", "gga"):
        from robustrtk.io.solution_nmea import write_nmea

        write_nmea(solutions, out, pos_frame=pos_frame)
    else:
        from robustrtk.io.tracks import write_gpx, write_kml

        (write_kml if kind == "kml" else write_gpx)(solutions, out, pos_frame=pos_frame)


def _solve_spp(
    rover: Any,
    eph: Any,
    cfg: Config,
    progress: Callable[[int, int], None] | None,
    diagnostics: list[Any] | None = None,
) -> SolutionSeries:
    from robustrtk.pipeline import gnss as _gnss
    from robustrtk.pipeline.api import spp_series

    systems = cfg.gnss.systems.upper() if cfg.gnss.systems else None
    epochs = _gnss.solve_spp_file(
        rover, eph, cfg, systems=systems, progress=progress, diagnostics=diagnostics
    )
    refused: dict[str, int] = {}
    for e in epochs:
        if e.status == "none" and getattr(e, "reason", "").startswith(
            ("residuals", "height", "position sigma", "jump")
        ):
            key = e.reason.split(" ", 1)[0]
            refused[key] = refused.get(key, 0) + 1
    warn_refused(refused)
    return spp_series(epochs)


def _fgo_row(row: dict[str, object]) -> tuple[Any, ...]:
    """One row of :meth:`robustrtk.pipeline.spp_fgo.FgoDiagnostics.table` in the diagnostics
    CSV column order (no innovation or Δv̄ in a batch solve: NaN)."""
    nan = float("nan")
    return (row["time"], row["dd"], nan, row.get("residual", nan), row.get("std_residual", nan), nan,
            row.get("factor", nan), row.get("situation", 0))  # fmt: skip


def kalman_hint(path: str, batch: Any) -> str | None:
    """One line suggesting ``--kalman`` for a least-squares SPP run, or None.

    Given for a phone log (by its reader kind: a GnssLogger log or a GSDC
    ``device_gnss.csv``) and for any file whose code observations mostly come with Doppler:
    epoch-wise least squares uses the code alone, while the Kalman SPP adds Doppler (and
    carrier phase where present) and the dynamics between epochs — on the GSDC Pixel 5
    drive 28 m against 2.4 m horizontal 95 %.
    """
    import numpy as np

    code = np.isfinite(batch.code_m)
    return kalman_hint_counts(path, int(code.sum()), int((code & np.isfinite(batch.doppler_hz)).sum()))


def check_common_epochs(rover: Any, base: Any, tol_s: float = 0.5) -> None:
    """:class:`InputError` when no rover epoch has a base epoch within ``tol_s`` (the larger of
    0.5 s and ``max_age_s`` in solve; a base
    file of another day or hour): said before the base position is judged, since a base
    solved with the rover's navigation data of another time lands far from any position."""
    import numpy as np

    from robustrtk.timeutil import gpst_text

    tr, tb = np.asarray(rover.t_s, float), np.sort(np.asarray(base.t_s, float))
    if tr.size and tb.size:
        j = np.clip(np.searchsorted(tb, tr), 1, tb.size - 1) if tb.size > 1 else np.zeros(tr.size, int)
        near = np.minimum(np.abs(tr - tb[j]), np.abs(tr - tb[np.maximum(j - 1, 0)]))
        if np.any(near <= tol_s):
            return
    span = lambda t: f"{gpst_text(float(t.min()))} to {gpst_text(float(t.max()))}" if t.size else "no epochs"  # noqa: E731
    raise InputError(
        f"--base: no common epochs between rover ({span(tr)}) and base ({span(tb)}) observations; "
        "expected a base file of the same hours"
    )


def raw_logs(rover: str, base: str | None) -> list[str]:
    """The rover and base files that are UBX or RTCM 3 logs, which carry their own broadcast
    ephemerides (RXM-SFRBX subframes, RTCM 3 messages 1019/1020/1042/1044/1045/1046): the
    navigation source of a solve given no ``--nav``, as a receiver's own log needs none."""
    from robustrtk.io.readers import detect_format

    out = []
    for path in (rover, base):
        if path is not None and os.path.isfile(path) and detect_format(path) in ("ubx", "rtcm3"):
            out.append(path)
    return out


def check_systems(systems: str | None) -> None:
    """:class:`InputError` for a ``--systems`` letter that names no GNSS (every mode)."""
    from robustrtk.io.rinex_layout import SYSTEM_ORDER

    unknown = sorted(set(systems.upper()) - set(SYSTEM_ORDER)) if systems else []
    if unknown:
        raise InputError(
            f"--systems: unknown system letter(s) {''.join(unknown)!r}; expected letters from {SYSTEM_ORDER}"
        )


def _warn(text: str) -> None:
    warn(text)


def _read_notes(meta: Any) -> list[str]:
    """The reader's notes on the oddities it tolerated (``meta["read_notes"]``)."""
    notes = meta.get("read_notes") if isinstance(meta, dict) else None
    return [str(n) for n in notes] if isinstance(notes, list) else []


def _warn_masked(path: str, batch: Any) -> None:
    """Say how many impossible values the reader masked (:mod:`robustrtk.io.obs_checks`)."""
    from robustrtk.io.obs_checks import masked_text

    meta = getattr(batch, "meta", {})
    warn_read(path, masked_text(batch), meta.get("duplicate_epochs_dropped", 0), notes=_read_notes(meta))


def _note_masked(notes: list[tuple[str, str]] | None, what: str, batch: Any) -> None:
    """The summary line of the values the reader masked (left out of every solution)."""
    from robustrtk.io.obs_checks import masked_text

    note_masked(notes, what, masked_text(batch))


def _load_checked(
    path: str,
    what: str,
    systems: str | None,
    eph: Any,
    cfg: Config | None = None,
    bounds_s: tuple[float | None, float | None] | None = None,
) -> Any:
    """:func:`robustrtk.pipeline.gnss.load_checked` (``cfg``'s time window, ``bounds_s``),
    with a partial navigation coverage warned about on stderr."""
    from robustrtk.io.obs_checks import masked_text
    from robustrtk.pipeline import gnss as _gnss

    batch, frac = _gnss.load_checked(path, what, systems, eph, None if cfg is None else cfg.gnss, bounds_s)
    dup = batch.meta.get("duplicate_epochs_dropped", 0)
    n_dup = dup if isinstance(dup, int) else 0
    warn_read(path, masked_text(batch), n_dup, frac, what, _read_notes(batch.meta))
    return batch


# ----------------------------------------------------------------------------- DD on RINEX
def _gnss_kwargs(fn: Callable[..., Any], cfg: Config) -> dict[str, Any]:
    """Satellite selection for solvers that still take it as keywords (else it is in ``cfg``)."""
    sel = {
        "elev_mask_deg": cfg.gnss.elev_mask_deg,
        "systems": cfg.gnss.systems.upper() if cfg.gnss.systems else None,
        "freqs": cfg.gnss.freqs,
    }
    params = inspect.signature(fn).parameters
    return {k: v for k, v in sel.items() if k in params}


def run_gnss(
    rover: str,
    cfg: Config,
    out: str,
    nav: Sequence[str] = (),
    base: str | None = None,
    base_pos: str | None = None,
    fmt: str | None = None,
    diagnostics: str | None = None,
    progress: Callable[[int, int], None] | None = None,
    force: bool = False,
    notes: list[tuple[str, str]] | None = None,
    quiet: bool = False,
) -> SolutionSeries | SppRunCounts:
    """Solve a RINEX rover file in ``cfg.mode`` (spp, dgnss or rtk) and write the solutions.

    A least-squares SPP of a plain RINEX 3/4 file written to ``.pos``, without diagnostics
    or a time window, is streamed (:func:`robustrtk.cli.gnss_stream.solve_spp_streamed`:
    memory of a block of epochs, not of the file; the same output, summary and messages).

    Parameters
    ----------
    rover : str
        Rover RINEX observation file.
    cfg : Config
        Resolved settings (:func:`robustrtk.cli.settings.resolve_config`).
    out : str
        Output path (``.pos``, ``.csv`` or ``.nmea``, or any name with ``fmt``).
    nav : sequence of str
        Broadcast navigation files (at least one).
    base : str, optional
        Base RINEX observation file (dgnss, rtk).
    base_pos : str, optional
        ``"X,Y,Z"`` base ECEF (m); default the base header position (with a warning).
    fmt : {"csv", "pos", "nmea"}, optional
        Output format (default: by extension).
    diagnostics : str, optional
        Per-DD diagnostics CSV (dgnss, rtk).
    progress : callable (done, total), optional
        Per-epoch callback (the command's :class:`robustrtk.cli.progress.ProgressBar`).
    force : bool
        Accept a ``base_pos`` farther than 100 m from the base's own single-point solution,
        or a header position its χ² test refuses (:func:`check_header_base`).
    notes : list of (name, value), optional
        Receives the summary lines of what the run assumed (the base position's source).
    quiet : bool
        No notice on stderr.

    Returns
    -------
    SolutionSeries or SppRunCounts
        The solutions as written, with the run's diagnostics (the counts of a streamed run).
    """
    import numpy as np

    from robustrtk.pipeline import gnss as _gnss
    from robustrtk.pipeline.api import SolutionSeries

    mode = cfg.mode
    check_systems(cfg.gnss.systems)
    from_logs = not nav
    if from_logs:
        nav = raw_logs(rover, base)
        if not nav:
            raise InputError(
                "--nav: at least one RINEX navigation file is required for GNSS input "
                "(or a UBX / RTCM 3 rover or base log, whose ephemerides serve)"
            )
        said = "ephemerides from " + " and ".join(os.path.basename(n) for n in nav)
        if notes is not None:
            notes.append(("navigation", said + " (no --nav)"))
        if not quiet:
            _warn(f"note: {said} (no --nav given)")
    if mode not in ("spp", "dgnss", "rtk"):
        raise InputError(f"--mode: expected spp, dgnss or rtk for RINEX input, got {mode!r}")
    check_output_kind(out, fmt, "ecef")
    if mode != "spp" and base is None:
        raise InputError(f"--base: {mode.upper()} needs a base RINEX observation file")
    kind = cfg.receivers.base_position
    if kind == "moving" and base_pos is not None:
        raise InputError("--base-pos: a moving base takes its position from its own solution; leave it out")
    if kind == "trajectory" and base_pos is None:
        raise InputError("--base-pos: --base-position trajectory needs a trajectory file (.pos or .csv)")
    pos: Any = None
    if base_pos is not None:
        pos = base_pos if kind == "trajectory" else parse_xyz(base_pos)
    systems = cfg.gnss.systems.upper() if cfg.gnss.systems else None
    eph = _gnss.nav_source(list(nav))
    n_nav = sum(len(v.toe_s) for v in eph.nav.kepler.values()) + len(eph.nav.glonass)
    if n_nav == 0:
        if from_logs:
            raise InputError(
                "--nav: no navigation file given and the UBX / RTCM 3 logs carry no broadcast "
                "ephemeris; give a RINEX navigation file"
            )
        raise InputError("--nav: no broadcast ephemeris in the navigation file(s) (header only?)")
    # read as each solver would (RTK reads every system and selects later)
    load_systems = None if mode == "rtk" else systems
    if mode == "spp":
        from robustrtk.cli.gnss_stream import solve_spp_streamed, streamable

        if streamable(rover, cfg, output_kind(out, fmt), diagnostics):
            streamed = solve_spp_streamed(rover, eph, cfg, out, nav, progress, notes, quiet)
            if streamed is not None:
                return streamed
    rover_b = _load_checked(rover, "rover", load_systems, eph, cfg)
    _note_masked(notes, "rover", rover_b)
    base_b = None
    if mode != "spp":
        assert base is not None
        # the epochs are matched first: a base of another day is named as such, not as
        # navigation data that does not cover it or a base position far off
        base_b = _gnss.load_obs(base, load_systems, None, _gnss.base_read_bounds(rover_b, cfg.gnss), "base")
        _warn_masked(base, base_b)
        _note_masked(notes, "base", base_b)
        _gnss.check_has_epochs(base_b, "base")
        check_common_epochs(rover_b, base_b, tol_s=max(0.5, cfg.gnss.max_age_s))
        frac = _gnss.check_nav_coverage(base_b, eph)
        if frac < 1.0:
            _warn(f"{base}: the navigation data covers only {100 * frac:.1f} % of the base epochs")
        if kind == "fixed" and isinstance(pos, np.ndarray):
            _gnss.check_base_position(base_b, eph, pos, cfg.gnss.elev_mask_deg, force=force)
        elif kind == "fixed" and pos is None:
            pos = check_header_base(base, base_b, eph, cfg.gnss.elev_mask_deg, force, notes, quiet)
    diag_rows: list[tuple[Any, ...]] | None = None
    if mode == "spp":
        if cfg.estimator.filter == "lsq" and not cfg.spp.fgo:  # the smoother has Doppler, phase
            say_hint(kalman_hint(rover, rover_b), notes, quiet)
        if diagnostics and not cfg.spp.fgo:
            raise InputError("--diagnostics: in spp mode only with the batch smoother (--fgo)")
        fgo_diag: list[Any] = []
        series = _solve_spp(rover_b, eph, cfg, progress, fgo_diag)
        if diagnostics:
            diag_rows = [_fgo_row(r) for d in fgo_diag for r in d.table()]
        if fgo_diag and fgo_diag[0].ionosphere and notes is not None:
            notes.append(("ionosphere", fgo_diag[0].ionosphere))
    else:
        if mode == "dgnss":
            fn: Callable[..., Any] = _gnss.solve_dgnss
        else:
            from robustrtk.pipeline.rtk_gnss import solve_rtk

            fn = solve_rtk
        # the rows are kept only for the diagnostics file: the summary needs their counts alone
        res = fn(
            rover_b, base_b, eph, pos, cfg, progress=progress, keep_diagnostics=bool(diagnostics),
            **_gnss_kwargs(fn, cfg),
        )  # fmt: skip
        series = SolutionSeries.from_solutions(
            res.solutions, mode, res.run.diagnostics, res.info, frame="ecef"
        )
        if diagnostics:
            diag_rows = [
                (d.t_s, d.dd, d.innovation, d.residual, d.std_residual, d.dv, d.factor, d.situation)
                for d in res.run.diagnostics
            ]
    sols = list(series.solutions)
    check_solved(sols, min_sats=4)
    # the .pos header names the inputs and, for a fixed base, the position used (RTKLIB's)
    ref: Any = None
    if base_b is not None and kind == "fixed":
        ref = pos if isinstance(pos, np.ndarray) else base_b.approx_pos_m
    inputs = [str(rover)] + ([str(base)] if base_b is not None else []) + [str(n) for n in nav]
    write_outputs(sols, out, fmt, diagnostics, diag_rows, series.frame, inputs=inputs, ref_pos_ecef_m=ref)
    return series


def check_header_base(
    path: str,
    base_b: Any,
    eph: Any,
    elev_mask_deg: float,
    force: bool,
    notes: list[tuple[str, str]] | None,
    quiet: bool,
) -> Any:
    """The base file's header position, tested against the base's own single-point solution.

    Without ``--base-pos`` the header's ``APPROX POSITION XYZ`` is used: one notice line
    says so with its offset from the base's mean SPP and the χ² test of
    :func:`robustrtk.pipeline.base_check.check_header_position`; a header the test refuses
    stops the run (exit 2) naming both positions and ``--base-pos``, or with ``force`` is
    used with one warning line. The offset goes to the summary (``notes``).

    Returns
    -------
    ndarray, shape (3,)
        The header position (ECEF m).
    """
    import numpy as np

    from robustrtk.pipeline.base_check import check_header_position

    hdr = base_b.approx_pos_m
    if hdr is None or not np.all(np.isfinite(hdr)) or not 6.2e6 < float(np.linalg.norm(hdr)) < 6.5e6:
        raise InputError(
            "--base-pos: not given, and the base header has no usable APPROX POSITION XYZ; "
            "pass the base's surveyed ECEF position as X,Y,Z (m)",
            path,
        )
    hdr = np.asarray(hdr, float)
    chk = check_header_position(base_b, eph, hdr, elev_mask_deg)
    if chk is None:
        line = "base position from the RINEX header (no base epoch solved to check it); pass --base-pos X,Y,Z"
        summary = "RINEX header, unchecked"
    else:
        summary = (
            f"RINEX header, {chk.distance_m:.2f} m from the base's own SPP "
            f"(χ² {chk.chi2:.1f}, bound {chk.bound:.1f})"
        )
        if not chk.consistent and not force:
            raise InputError(
                f"--base-pos: not given, and the {chk.describe()}: the header contradicts the base's "
                "observations; pass the surveyed position with --base-pos X,Y,Z "
                "(or --force to use the header)",
                path,
            )
        line = (
            f"base position from the RINEX header: {chk.describe()}"
            + ("; used because of --force" if not chk.consistent else "")
            + "; fixes are only as accurate as the base position: pass --base-pos X,Y,Z"
        )
    if not quiet:
        click.echo(f"{'warning' if chk is not None and not chk.consistent else 'note'}: {line}", err=True)
    if notes is not None:
        notes.append(("base position", summary))
    return hdr


def check_solved(sols: Sequence[Solution], min_sats: int) -> None:
    """:class:`NothingSolved` when every solution has status ``none`` (or none is finite),
    with the epochs counted by the number of transmitters used."""
    import numpy as np

    if any(s.status != "none" and np.all(np.isfinite(s.pos_m)) for s in sols):
        return
    n0 = sum(1 for s in sols if s.n_used == 0)
    few = sum(1 for s in sols if 0 < s.n_used < min_sats)
    raise nothing_solved(len(sols), n0, few, min_sats)


def write_outputs(
    sols: Sequence[Solution],
    out: str,
    fmt: str | None,
    diagnostics: str | None,
    diag_rows: Sequence[tuple[Any, ...]] | None,
    pos_frame: str = "ecef",
    *,
    inputs: Sequence[str] = (),
    ref_pos_ecef_m: Any = None,
) -> None:
    """Write the solution (and diagnostics) as one transaction
    (:func:`robustrtk.io.atomic.atomic_paths`): both files or neither are replaced
    (``inputs`` and ``ref_pos_ecef_m``: :func:`write_solutions`)."""
    from robustrtk.io.atomic import atomic_paths

    targets = ([diagnostics] if diagnostics else []) + [out]
    with atomic_paths(targets) as tmps:
        if diagnostics:
            from robustrtk.io.diagnostics import write_diagnostics_csv

            write_diagnostics_csv(list(diag_rows or []), tmps[0])
        write_solutions(
            sols, tmps[-1], fmt or output_kind(out), pos_frame, inputs=inputs, ref_pos_ecef_m=ref_pos_ecef_m
        )


@click.command("info")
@click.argument("path", type=click.Path(dir_okay=False))
@click.option("--systems", default=None, help="System letters to keep (e.g. GEJ).")
def info(path: str, systems: str | None) -> None:
    """Summarise an observation file (RINEX 2/3/4, Android GnssLogger, GSDC device_gnss.csv:
    epochs, interval, systems, signals) or a RINEX navigation file (records per kind,
    satellites, time span); the format is recognised by the content."""
    from robustrtk.io.info import format_nav_summary, format_summary, summarize, summarize_nav_file
    from robustrtk.io.readers import detect_format, read_observations
    from robustrtk.io.rinex_obs import read_rinex_obs

    try:
        fmt = detect_format(path)
        if fmt == "rinex_nav":
            click.echo(format_nav_summary(summarize_nav_file(path, systems)))
            return
        sel = systems.upper() if systems else None
        if fmt == "rinex_obs":
            batch = read_rinex_obs(path, systems=sel)
        else:
            batch = read_observations(path)
            if sel:
                batch = batch.select_systems(sel)
    except InputError as exc:
        click.echo(f"error: {one_line(str(exc))}", err=True)
        sys.exit(2)
    click.echo(format_summary(summarize(batch)))


__all__ = [
    "info",
    "output_kind",
    "parse_xyz",
    "check_output_kind",
    "run_gnss",
    "write_outputs",
    "write_solutions",
]
