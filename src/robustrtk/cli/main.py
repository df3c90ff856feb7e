"""Command-line interface: parses arguments and calls the library, nothing else.

Bad input (files, options) is reported as one line ``error: <file>:<line>: <what>`` with
exit status 2 — never a traceback.
"""

from __future__ import annotations

import importlib
import os
import time
from typing import TYPE_CHECKING, Any

import click

from robustrtk.cli.errors import one_line_errors as _friendly
from robustrtk.errors import InputError
from robustrtk.version import __version__

if TYPE_CHECKING:  # the configuration module loads only when a command needs it
    from robustrtk.pipeline.config import Config

#: Commands defined in their own modules: name -> (module, attribute). A module is imported
#: when the command line names its command (or lists the commands, as ``--help`` does), so
#: a solve does not import the code of the other commands.
LAZY_COMMANDS: dict[str, tuple[str, str]] = {
    "batch": ("robustrtk.cli.batch", "batch"),
    "compare": ("robustrtk.cli.compare", "compare"),
    "convert": ("robustrtk.cli.convert", "convert"),
    "coop": ("robustrtk.cli.coop", "coop"),
    "experiment": ("robustrtk.cli.experiment", "experiment"),
    "info": ("robustrtk.cli.gnss", "info"),
    "inject": ("robustrtk.cli.inject", "inject"),
    "report": ("robustrtk.cli.report", "report"),
    "run": ("robustrtk.cli.run", "run"),
}


class LazyGroup(click.Group):
    """A command group whose commands of :data:`LAZY_COMMANDS` are imported on first use.

    Listing, help and error messages (the close matches of a mistyped command) are those of
    a group with every command added.
    """

    def _load(self, name: str) -> None:
        if name not in self.commands and name in LAZY_COMMANDS:
            module, attr = LAZY_COMMANDS[name]
            self.add_command(getattr(importlib.import_module(module), attr), name)

    def list_commands(self, ctx: click.Context) -> list[str]:
        """Every command name, sorted."""
        return sorted({*self.commands, *LAZY_COMMANDS})

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        """The command ``cmd_name``, imported if needed; None when there is no such command
        (then every command is loaded, so the error can suggest the close matches)."""
        self._load(cmd_name)
        if cmd_name not in self.commands:
            for name in LAZY_COMMANDS:
                self._load(name)
        return super().get_command(ctx, cmd_name)


class ConfigCommand(click.Command):
    """A command whose own options are followed by one option per configuration leaf
    (:func:`robustrtk.cli.options.config_options`), made when the command first needs its
    parameters — to parse its arguments, show its help or complete a word — so listing the
    commands (``robustrtk --help``) or running another one does not import the configuration
    tree."""

    def __init__(self, *args: Any, mode_help: str | None = None, **kwargs: Any) -> None:
        self._leaves_added = False
        self.mode_help = mode_help  # the --mode line of the help, when not solve's
        super().__init__(*args, **kwargs)

    @property
    def params(self) -> list[click.Parameter]:
        """The command's own parameters, then the configuration leaves' options."""
        if not self._leaves_added:
            from robustrtk.cli.options import config_params

            self._params.extend(config_params())
            self._leaves_added = True
        return self._params

    @params.setter
    def params(self, value: list[click.Parameter]) -> None:
        self._params = value

    def get_help(self, ctx: click.Context) -> str:
        """The short grouped page, or every flag after ``--help-all``
        (:func:`robustrtk.cli.help.format_solve_help`)."""
        from robustrtk.cli.help import format_solve_help

        return format_solve_help(self, ctx, full=bool(ctx.meta.get("help_all"))).rstrip("\n")


def _help_all(ctx: click.Context, _param: click.Parameter, value: bool) -> None:
    if not value or ctx.resilient_parsing:
        return
    ctx.meta["help_all"] = True
    click.echo(ctx.get_help(), color=ctx.color)
    ctx.exit()


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="robustrtk")
def main() -> None:
    """robustrtk — robust DD code and carrier-phase positioning (pseudolites and GNSS)."""


# --------------------------------------------------------------------------- simulate
@main.command()
@click.argument("scenario")
@click.option("--seed", type=int, default=0, show_default=True, help="Random seed.")
@click.option(
    "--out", "out_dir", type=click.Path(file_okay=False), required=True, help="Output directory (created)."
)
@click.option("--epochs", type=int, default=None, help="Override the number of epochs.")
@_friendly
def simulate(scenario: str, seed: int, out_dir: str, epochs: int | None) -> None:
    """Simulate an indoor pseudolite SCENARIO (a TOML file or a preset name).

    Writes obs.csv, site.toml, truth.csv, ambiguities.csv and faults.csv to --out.
    Presets: see `robustrtk simulate --list`.
    """
    import numpy as np

    from robustrtk.sim.files import write_simulation
    from robustrtk.sim.pseudolite import simulate as sim
    from robustrtk.sim.scenario import load_scenario

    sc = load_scenario(scenario)
    result = sim(sc, np.random.default_rng(seed), n_epochs=epochs)
    paths = write_simulation(result, out_dir)
    click.echo(f"simulated {sc.name!r} (seed {seed}): " + ", ".join(str(p) for p in paths.values()))


@main.command("presets")
def presets() -> None:
    """List the simulation scenario presets."""
    from robustrtk.sim.scenario import list_presets, load_scenario

    for name in list_presets():
        sc = load_scenario(name)
        click.echo(f"{name:24s} {getattr(sc, 'description', '')}")


# --------------------------------------------------------------------------- solve
@main.command(cls=ConfigCommand)
@click.argument("obs", type=click.Path())
@click.option("--site", type=click.Path(), help="Pseudolite site TOML (pseudolite tables).")
@click.option(
    "--config",
    type=click.Path(),
    help="TOML settings over the mode's preset (flat keys or [section] tables).",
)
@click.option(
    "--rtklib-conf",
    type=click.Path(),
    default=None,
    help="RTKLIB .conf under --config and flags (ignored keys named on stderr).",
)
@click.option(
    "--profile",
    "profile",
    type=click.Choice(["lowcost", "phone"]),
    default=None,
    help="Receiver profile (rtk, dgnss): phone (L1+L5, C/N0 weighting) or lowcost (code sigma from the "
    "receivers' own code minus carrier).",
)
@click.option(
    "--base",
    "base_obs",
    type=click.Path(),
    default=None,
    help="Base observations (RINEX, UBX, RTCM 3): a relative run, rtk or dgnss.",
)
@click.option(
    "--nav",
    multiple=True,
    type=click.Path(),
    help="Navigation file(s) (repeatable; default: UBX/RTCM 3 inputs').",
)
@click.option(
    "--base-pos",
    default=None,
    metavar="X,Y,Z",
    help="Base ECEF position (m) or trajectory file; default the base header's, checked "
    "against the base's own SPP.",
)
@click.option(
    "--kalman",
    is_flag=True,
    default=False,
    help="Kalman SPP (--filter ekf) on code, Doppler, phase; best for phones.",
)
@click.option(
    "--out",
    "out",
    type=click.Path(dir_okay=False),
    default=None,
    help="Solution file; the extension picks the format: .pos (RTKLIB), .csv, .nmea (GGA), "
    ".kml, .gpx (map track); pseudolite runs: .csv.",
)
@click.option(
    "--format",
    "fmt",
    type=click.Choice(["pos", "csv", "nmea", "kml", "gpx"]),
    default=None,
    help="Format when the --out extension does not say.",
)
@click.option(
    "--diagnostics",
    type=click.Path(dir_okay=False),
    default=None,
    help="Diagnostics CSV (residuals, Δv̄, factors; spp with --fgo).",
)
@click.option("--quiet", is_flag=True, help="No progress bar, notices or summary.")
@click.option(
    "--force",
    is_flag=True,
    default=False,
    help="Use a base position that fails its check (one warning line).",
)
@click.option("--show-config", is_flag=True, help="Print the resolved settings as TOML and exit.")
@click.option(
    "--help-all",
    is_flag=True,
    expose_value=False,
    is_eager=True,
    callback=_help_all,
    help="Show every setting, grouped by section, and exit.",
)
@_friendly
def solve(
    obs: str,
    site: str | None,
    config: str | None,
    rtklib_conf: str | None,
    profile: str | None,
    base_obs: str | None,
    nav: tuple[str, ...],
    base_pos: str | None,
    kalman: bool,
    out: str | None,
    fmt: str | None,
    diagnostics: str | None,
    quiet: bool,
    force: bool,
    show_config: bool,
    **settings: Any,
) -> None:
    """Solve OBS: GNSS observations (RINEX, UBX, RTCM 3, phone logs; with --nav) or a
    pseudolite observation table (.csv/.parquet, with --site).

    GNSS mode: spp alone; with --base, rtk when both receivers record carrier phase, else
    dgnss (said in one line; --mode to choose). Settings: the mode's preset, then --config,
    then flags; a flag that does not act in the mode is refused (exit status 2).
    """
    from robustrtk.cli.settings import check_options, config_toml, input_kind, resolve_config, target_label

    kind = input_kind(obs)
    flags = {k: v for k, v in settings.items() if v is not None}
    if kalman:
        if flags.get("filter", "ekf") not in ("ekf", "ukf"):
            raise InputError(f"--kalman: conflicts with --filter {flags['filter']}")
        flags.setdefault("filter", "ekf")
    mode_flag = flags.pop("mode", None)
    inferred: tuple[str, str] | None = None
    if mode_flag is None and kind == "gnss" and base_obs is not None:
        from robustrtk.cli.infer import infer_gnss_mode

        inferred = infer_gnss_mode(obs, base_obs)
    cfg = resolve_config(
        mode_flag, kind, config, flags, rtklib_conf=rtklib_conf, profile=profile,
        default_mode=inferred[0] if inferred else None,
    )  # fmt: skip
    notes: list[tuple[str, str]] = []
    if inferred is not None and cfg.mode == inferred[0]:
        notes.append(("mode", f"{cfg.mode} ({inferred[1]})"))
        if not quiet and not show_config:
            click.echo(f"note: mode {cfg.mode}: {inferred[1]}", err=True)
    given = {
        "--site": site is not None,
        "--nav": bool(nav),
        "--base": base_obs is not None,
        "--base-pos": base_pos is not None,
        "--diagnostics": diagnostics is not None,
        "--kalman": kalman,
        "--force": force,
        "--profile": profile is not None,
    }
    check_options([k for k, v in given.items() if v], kind, cfg.mode)
    if base_pos is None and rtklib_conf is not None:
        from robustrtk.cli.settings import rtklib_base_pos

        base_pos = rtklib_base_pos(rtklib_conf, cfg.mode)
    label = target_label(kind, cfg.mode)
    if show_config:
        click.echo(config_toml(cfg, f"robustrtk solve: {kind} input, mode {label}", kind), nl=False)
        return
    if out is None:
        raise InputError("--out: a solution file is required")
    from robustrtk.cli.paths import check_output_paths

    check_output_paths(
        [("OBS", obs), ("--site", site), ("--config", config), ("--rtklib-conf", rtklib_conf),
         ("--base", base_obs), ("--base-pos", base_pos if base_pos and os.path.exists(base_pos) else None)]
        + [("--nav", n) for n in nav],
        [("--out", out), ("--diagnostics", diagnostics)],
    )  # fmt: skip
    from robustrtk.cli.progress import ProgressBar, bar_wanted, format_summary

    smoothing = bool(cfg.estimator.smoother) and cfg.mode != "rtk"
    bar = ProgressBar(
        f"solving {label}",
        enabled=bar_wanted(quiet),
        show_fix=cfg.mode == "rtk",
        after="forward pass done; RTS smoothing the track (backward pass)" if smoothing else None,
    )
    est = "FGO (batch smoother)" if cfg.mode == "spp" and cfg.spp.fgo else cfg.estimator.filter.upper()
    title = f"robustrtk solve: mode {label}, {est} robust={cfg.robust.policy}"
    outputs = [out] + ([diagnostics] if diagnostics else [])
    if kind == "gnss":
        from robustrtk.cli.gnss import run_gnss

        t0 = time.perf_counter()
        with bar:
            series = run_gnss(
                obs,
                cfg,
                out,
                nav=nav,
                base=base_obs,
                base_pos=base_pos,
                fmt=fmt,
                diagnostics=diagnostics,
                progress=bar,
                force=force,
                notes=notes,
                quiet=quiet,
            )
        if not quiet:
            click.echo(
                format_summary(
                    series.summary(),
                    title=title,
                    wall_s=time.perf_counter() - t0,
                    outputs=outputs,
                    fix_mode=cfg.mode == "rtk",
                    flagged_what=_flagged_what(cfg),
                    extra=notes + _integrity_line(series.info.get("integrity")),
                )
            )
        return
    from robustrtk.cli.gnss import check_output_kind, check_solved, write_outputs
    from robustrtk.pipeline.api import SolutionSeries
    from robustrtk.pipeline.solve import solve_pseudolite

    if site is None:
        raise InputError("--site SITE.toml is required for pseudolite observation tables", obs)
    check_output_kind(out, fmt, "local")
    t0 = time.perf_counter()
    with bar:
        res = solve_pseudolite(obs, site, cfg, progress=bar)
    dt = time.perf_counter() - t0
    check_solved(res.solutions, min_sats=4)
    diag_rows = [
        (d.t_s, d.dd, d.innovation, d.residual, d.std_residual, d.dv, d.factor, d.situation)
        for d in res.diagnostics
    ]
    write_outputs(res.solutions, out, fmt, diagnostics, diag_rows if diagnostics else None, pos_frame="local")
    if not quiet:
        refs = ", ".join(map(str, res.info.get("references", [])))  # type: ignore[call-overload]
        series = SolutionSeries.from_solutions(res.solutions, cfg.mode, res.diagnostics, frame="local")
        click.echo(
            format_summary(
                series.summary(),
                title=title,
                wall_s=dt,
                outputs=outputs,
                fix_mode=cfg.mode == "rtk",
                extra=[("reference", f"{refs} ({res.info.get('reference_source')})")],
            )
        )


# --------------------------------------------------------------------------- evaluate
@main.command()
@click.argument("sol", type=click.Path())
@click.option(
    "--truth",
    type=click.Path(),
    required=True,
    help="Truth: truth.csv (time,x,y,z), a point file, .pos, GSDC ground_truth.csv, NMEA GGA "
    "or time,lat,lon,h CSV.",
)
@click.option("--diagnostics", type=click.Path(), default=None, help="Diagnostics CSV of SOL.")
@click.option("--faults", type=click.Path(), default=None, help="faults.csv of a simulation.")
@click.option("--plots", type=click.Path(file_okay=False), default=None, help="Directory for PNGs.")
@_friendly
def evaluate(sol: str, truth: str, diagnostics: str | None, faults: str | None, plots: str | None) -> None:
    """Accuracy of SOL against TRUTH; situations (Li et al. Table 1, Fig. 6) with DIAG."""
    from robustrtk.eval.cli_support import evaluate_files

    click.echo(evaluate_files(sol, truth, diagnostics, faults, plots))


def _flagged_what(cfg: Config) -> str:
    """What the summary's robust counts count: SPP's FDE excludes satellites; DGNSS rows
    are DD code rows and, with ``measurement.dgnss_doppler``, Doppler velocity rows."""
    if cfg.mode == "spp":
        return "satellites"
    if cfg.mode == "dgnss" and cfg.measurement.dgnss_doppler:
        return "rows (DD code, Doppler)"
    return "DD rows"


def _integrity_line(counts: object) -> list[tuple[str, str]]:
    """The summary line of the integrity monitor's events (none without counts)."""
    if not isinstance(counts, dict):
        return []
    return [
        (
            "integrity",
            f"{counts.get('inflate', 0)} predictions widened, {counts.get('reinit', 0)} re-initialised, "
            f"{counts.get('fix_rejected', 0)} fixes reported float",
        )
    ]


# --------------------------------------------------------------------------- demo
@main.command()
@click.option(
    "--out", "out_dir", type=click.Path(file_okay=False), default="robustrtk-demo", show_default=True
)
@click.option("--seed", type=int, default=1, show_default=True)
@click.option("--quiet", is_flag=True, help="No progress bar.")
@_friendly
def demo(out_dir: str, seed: int, quiet: bool) -> None:
    """RTK on a bundled real rover/base pair, and a simulated pseudolite room solved with
    SUKF and RUKF; one HTML report of both (report.html in --out)."""
    from robustrtk.cli.progress import ProgressBar, bar_wanted
    from robustrtk.eval.demo import run_full_demo

    click.echo(f"demo: writing every file under {os.path.abspath(out_dir)} (--out to choose)")
    t0 = time.perf_counter()
    with ProgressBar("real-data RTK", enabled=bar_wanted(quiet), show_fix=True) as bar:
        text, report_path = run_full_demo(out_dir, seed, progress=bar)
    click.echo(text)
    click.echo(f"demo finished in {time.perf_counter() - t0:.1f} s; files in {os.path.abspath(out_dir)}")
    click.echo(f"report: {report_path.resolve()}")


if __name__ == "__main__":  # pragma: no cover
    # run as a script: go through the entry point (clean exits on signals); it imports
    # this module under its own name, so this is no import cycle
    importlib.import_module("robustrtk.cli.entry").main()
