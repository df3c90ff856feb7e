"""``robustrtk report``: one self-contained HTML report of a solution (and KML/GPX tracks)."""

from __future__ import annotations

import os

import click

from robustrtk.cli.compare import truth_options
from robustrtk.cli.errors import bad_input_exits
from robustrtk.errors import InputError


@click.command("report", context_settings={"help_option_names": ["-h", "--help"]})
@click.argument("solution")
@click.option("--out", required=True, help="HTML file to write (self-contained: images inlined).")
@truth_options
@click.option("--diagnostics", default=None, help="Diagnostics CSV of SOLUTION (solve --diagnostics).")
@click.option(
    "--vs", "vs", multiple=True, help="Another solution beside it, e.g. RTKLIB's .pos (repeatable)."
)
@click.option("--label", "labels", multiple=True, help="Label of SOLUTION, then of each --vs [file stem].")
@click.option("--obs", default=None, help="Rover observations (with --nav): satellites per epoch, sky plot.")
@click.option("--nav", multiple=True, help="Navigation file(s) for --obs.")
@click.option(
    "--elev-mask", type=float, default=15.0, show_default=True, help="Mask drawn on the sky plot (deg)."
)
@click.option("--title", default=None, help="Title of the report [file name].")
@click.option("--range", "range_m", type=float, default=None, help="Error axes limited to ± this (m).")
@click.option("--match-tol", type=float, default=0.05, show_default=True, help="Epoch match tolerance (s).")
@click.option("--kml", "kml_out", default=None, help="Also write SOLUTION as a KML track coloured by status.")
@click.option(
    "--gpx", "gpx_out", default=None, help="Also write SOLUTION as a GPX track, one track per status run."
)
def report(
    solution: str,
    out: str,
    truth: str | None,
    truth_llh: str | None,
    truth_window: str | None,
    truth_fixed: bool,
    diagnostics: str | None,
    vs: tuple[str, ...],
    labels: tuple[str, ...],
    obs: str | None,
    nav: tuple[str, ...],
    elev_mask: float,
    title: str | None,
    range_m: float | None,
    match_tol: float,
    kml_out: str | None,
    gpx_out: str | None,
) -> None:
    """Write an HTML report of SOLUTION (RTKLIB .pos or robustrtk .pos/.csv): ground track and
    ENU errors by fix status, fix rate and time to first fix, error statistics by status
    (with a truth), satellites and sky plot (with --obs and --nav), residuals and robust
    factors per satellite (with --diagnostics) and other solutions side by side (--vs)."""
    from robustrtk.cli.paths import check_output_paths

    with bad_input_exits():
        check_output_paths(
            [("SOLUTION", solution), ("--truth", truth), ("--diagnostics", diagnostics), ("--obs", obs)]
            + [("--vs", v) for v in vs] + [("--nav", n) for n in nav],
            [("--out", out), ("--kml", kml_out), ("--gpx", gpx_out)],
        )  # fmt: skip
        _run(solution, out, truth, truth_llh, truth_window, diagnostics, vs, labels, obs, nav, elev_mask,
             title, range_m, match_tol, kml_out, gpx_out, truth_fixed)  # fmt: skip


def _run(solution: str, out: str, truth_text: str | None, truth_llh: str | None, truth_window: str | None,
         diagnostics: str | None, vs: tuple[str, ...], labels: tuple[str, ...], obs: str | None,
         nav: tuple[str, ...], elev_mask: float, title: str | None, range_m: float | None, match_tol: float,
         kml_out: str | None, gpx_out: str | None, truth_fixed: bool = False) -> None:  # fmt: skip
    from robustrtk.eval.html_report import build_report, write_report
    from robustrtk.eval.truth import parse_time_window, parse_truth, truth_from_llh

    for opt, path, ext in (("--out", out, (".html", ".htm")), ("--kml", kml_out, (".kml",)),
                           ("--gpx", gpx_out, (".gpx",))):  # fmt: skip
        if path is None:
            continue
        if os.path.isdir(path):
            raise InputError(f"{opt}: is a directory, expected a file name", path)
        if os.path.splitext(path)[1].lower() not in ext:
            raise InputError(f"{opt}: expected a file ending in {' or '.join(ext)}, got {path!r}")
    if truth_text is not None and truth_llh is not None:
        raise InputError("give either --truth or --truth-llh, not both")
    if not match_tol > 0.0:
        raise InputError(f"--match-tol: expected a positive number of seconds, got {match_tol}")
    if range_m is not None and not range_m > 0.0:
        raise InputError(f"--range: expected a positive number of metres, got {range_m}")
    if truth_fixed and truth_text is None:
        raise InputError("--truth-fixed: needs a --truth trajectory file")
    truth = parse_truth(truth_text, truth_fixed) if truth_text is not None else None
    if truth_llh is not None:
        truth = truth_from_llh(truth_llh)
    window = None
    if truth_window is not None:
        if truth is None:
            raise InputError("--truth-window needs a truth (--truth or --truth-llh)")
        from robustrtk.eval.comparison import load_solution

        table, _ = load_solution(solution)
        window = parse_time_window(truth_window, float(table.t_s.min()) if len(table) else 0.0)
    text = build_report(
        solution, truth=truth, truth_window_s=window, diagnostics=diagnostics, vs=vs, labels=labels, obs=obs,
        nav=nav, elev_mask_deg=elev_mask, title=title, match_tol_s=match_tol, range_m=range_m,
    )  # fmt: skip
    if kml_out is not None or gpx_out is not None:
        from robustrtk.eval.comparison import load_solution
        from robustrtk.io.tracks import write_gpx, write_kml

        table, _ = load_solution(solution)
        name = title or os.path.basename(solution)
        if kml_out is not None:
            write_kml(table, kml_out, name=name)
            click.echo(f"wrote {kml_out}")
        if gpx_out is not None:
            write_gpx(table, gpx_out, name=name)
            click.echo(f"wrote {gpx_out}")
    write_report(text, out)
    click.echo(f"wrote {out} ({len(text.encode('utf-8')) / 1024:.0f} kB)")


__all__ = ["report"]
