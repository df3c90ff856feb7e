"""``robustrtk compare``: fix rate, time to first fix and H/V errors of solution files."""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any, TypeVar

import click

from robustrtk.cli.errors import bad_input_exits
from robustrtk.errors import InputError

F = TypeVar("F", bound=Callable[..., Any])


def truth_options(fn: F) -> F:
    """The ``--truth``, ``--truth-fixed``, ``--truth-llh`` and ``--truth-window`` options
    (compare, report)."""
    fn = click.option(
        "--truth-fixed",
        is_flag=True,
        help="Only the truth's fixed epochs (.pos Q=1, NMEA GGA quality 4, solution CSV fixed).",
    )(fn)
    fn = click.option(
        "--truth-window",
        default=None,
        help="START,END (GPST 'yyyy/mm/dd hh:mm:ss', 'hh:mm:ss' or seconds): error statistics "
        "only inside this window.",
    )(fn)
    fn = click.option("--truth-llh", default=None, help="Truth point LAT,LON,H (deg, deg, m ellipsoidal).")(
        fn
    )
    return click.option(
        "--truth",
        default=None,
        help="X,Y,Z (ECEF m) or a truth file: point (X Y Z / LAT LON H, e.g. truth_and_base.txt) "
        "or trajectory (.pos, GSDC ground_truth.csv, NMEA GGA, CSV time,x,y,z or time,lat,lon,h, "
        "rows 'week tow x y z').",
    )(fn)


@click.command("compare", context_settings={"help_option_names": ["-h", "--help"]})
@click.argument("solutions", nargs=-1, required=True)
@click.option(
    "--label", "labels", multiple=True, help="Label of the next solution (repeatable, in order) [file stem]."
)
@truth_options
@click.option(
    "--match-tol",
    type=float,
    default=0.05,
    show_default=True,
    help="Largest solution-truth time difference of a trajectory match (s).",
)
@click.option(
    "--rover-epochs",
    type=int,
    default=None,
    help="Number of rover epochs (fix rate over all rover epochs too).",
)
@click.option(
    "--rover-obs",
    default=None,
    help="Rover RINEX observation file whose epochs are counted (instead of --rover-epochs).",
)
@click.option(
    "--json",
    "json_out",
    default=None,
    help="Write the statistics as JSON (metres, full precision).",
)
@click.option(
    "--plot",
    "plot_out",
    default=None,
    help="Write a figure (.png, .pdf, .svg): ENU error series and horizontal scatter.",
)
@click.option(
    "--plot-range", type=float, default=None, help="Plot error axes limited to ± this value (m) [full range]."
)
@click.option("--details", is_flag=True, help="Also print fixed/float/all statistics per solution.")
def compare(
    solutions: tuple[str, ...],
    labels: tuple[str, ...],
    truth: str | None,
    truth_llh: str | None,
    truth_window: str | None,
    truth_fixed: bool,
    match_tol: float,
    rover_epochs: int | None,
    rover_obs: str | None,
    json_out: str | None,
    plot_out: str | None,
    plot_range: float | None,
    details: bool,
) -> None:
    """Compare SOLUTIONS (RTKLIB .pos in llh or xyz form, robustrtk .pos or .csv).

    Prints one row per solution: solved epochs, Q histogram, fix rate (of solved and of
    rover epochs), time to first fix, and fixed-epoch and all-epoch horizontal/vertical
    RMS and 95 % errors against the truth (ENU at the truth point).
    """
    with bad_input_exits():
        _run(solutions, labels, truth, truth_llh, truth_window, match_tol, rover_epochs, rover_obs,
             json_out, plot_out, plot_range, details, truth_fixed)  # fmt: skip


def _run(solutions: tuple[str, ...], labels: tuple[str, ...], truth_text: str | None,
         truth_llh: str | None, truth_window: str | None, match_tol: float, rover_epochs: int | None,
         rover_obs: str | None, json_out: str | None, plot_out: str | None, plot_range: float | None,
         details: bool, truth_fixed: bool = False) -> None:  # fmt: skip
    from robustrtk.eval import compare as cmp

    if truth_text is not None and truth_llh is not None:
        raise InputError("give either --truth or --truth-llh, not both")
    if rover_epochs is not None and rover_obs is not None:
        raise InputError("give either --rover-epochs or --rover-obs, not both")
    if rover_epochs is not None and rover_epochs < 1:
        raise InputError(f"--rover-epochs: expected a positive number, got {rover_epochs}")
    if not match_tol > 0.0:
        raise InputError(f"--match-tol: expected a positive number of seconds, got {match_tol}")
    if plot_range is not None and not plot_range > 0.0:
        raise InputError(f"--plot-range: expected a positive number of metres, got {plot_range}")
    for opt, out in (("--json", json_out), ("--plot", plot_out)):
        if out is not None and os.path.isdir(out):
            raise InputError(f"{opt}: is a directory, expected a file name", out)
    if plot_out is not None and os.path.splitext(plot_out)[1].lower() not in (".png", ".pdf", ".svg"):
        raise InputError(f"--plot: expected a file ending in .png, .pdf or .svg, got {plot_out!r}")
    truth = None
    if truth_fixed and truth_text is None:
        raise InputError("--truth-fixed: needs a --truth trajectory file")
    if truth_text is not None:
        truth = cmp.parse_truth(truth_text, truth_fixed)
    elif truth_llh is not None:
        truth = cmp.truth_from_llh(truth_llh)
    if truth is None and (truth_window is not None or plot_out is not None):
        raise InputError("--truth-window and --plot need a truth (--truth or --truth-llh)")
    if rover_obs is not None:
        rover_epochs = cmp.count_rover_epochs(rover_obs)
    loaded = [cmp.load_solution(p) for p in solutions]
    window = None
    if truth_window is not None:
        firsts = [float(tb.t_s.min()) for tb, _ in loaded if len(tb)]
        window = cmp.parse_time_window(truth_window, min(firsts) if firsts else 0.0)
    labs = cmp.default_labels(solutions)
    if len(labels) > len(solutions):
        raise InputError(f"--label given {len(labels)} times for {len(solutions)} solution files")
    labs[: len(labels)] = list(labels)
    results = [
        cmp.compare_solution(
            tb, q, truth, label=lab, path=p, rover_epochs=rover_epochs, window_s=window, tol_s=match_tol
        )  # fmt: skip
        for (tb, q), lab, p in zip(loaded, labs, solutions, strict=True)
    ]
    if truth is not None:
        line = f"truth: {truth.source}" + ("" if truth.is_point else f", {truth.pos_m.shape[0]} epochs")
        if window is not None:
            line += f"; window {cmp.gpst_text(window[0])} to {cmp.gpst_text(window[1])} GPST"
        click.echo(line)
        if truth.note and window is None:
            click.echo(f"warning: the truth file says: {truth.note!r}; consider --truth-window", err=True)
    for r in results:
        for w in r.warnings:
            click.echo(f"warning: {r.label}: {w}", err=True)
    click.echo(cmp.summary_table(results))
    if truth is not None and truth.kind == "gsdc":
        for r in results:
            pct = r.horizontal_percentiles_m()
            if pct is not None:
                click.echo(
                    f"GSDC score {r.label}: {0.5 * (pct[0] + pct[1]):.2f} m "
                    f"(horizontal p50 {pct[0]:.2f} m, p95 {pct[1]:.2f} m, {r.n_with_truth} epochs)"
                )
    if details and truth is not None:
        click.echo("")
        click.echo(cmp.detail_table(results))
    if json_out is not None:
        cmp.write_json(cmp.comparison_report(results, truth, window, match_tol), json_out)
        click.echo(f"wrote {json_out}")
    if plot_out is not None:
        from robustrtk.eval.plots import save_figure

        assert truth is not None
        title = f"Position error against {truth.source}"
        fig = cmp.plot_comparison(results, title=title, range_m=plot_range)
        save_figure(fig, plot_out)
        click.echo(f"wrote {plot_out}")


__all__ = ["compare"]
