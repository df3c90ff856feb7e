"""``robustrtk inject OBS --phase ... --code ... --slip ... --out OBS2``: fault injection.

Writes a copy of a RINEX observation file with silent gross errors (phase, code) and
cycle slips, plus a CSV log of every changed value (:mod:`robustrtk.sim.inject`).
Bad input is reported as one line ``error: <file>:<line>: <what>`` with exit status 2.
"""

from __future__ import annotations

import time

import click

from robustrtk.cli.errors import one_line_errors
from robustrtk.errors import InputError


@click.command("inject", context_settings={"help_option_names": ["-h", "--help"]})
@click.argument("obs", metavar="OBS")
@click.option(
    "--phase",
    "phase",
    multiple=True,
    metavar="SAT:SIGNAL:SIZE_M:EPOCHS",
    help="Add SIZE_M metres to a carrier phase (e.g. G05:L1C:0.15:random20). Repeatable.",
)
@click.option(
    "--code",
    "code",
    multiple=True,
    metavar="SAT:SIGNAL:SIZE_M:EPOCHS",
    help="Add SIZE_M metres to a pseudorange (e.g. E11:C1C:10:100-119). Repeatable.",
)
@click.option(
    "--slip",
    "slip",
    multiple=True,
    metavar="SAT:SIGNAL:CYCLES:EPOCH",
    help="Add CYCLES to a phase from EPOCH to the end of the file. Repeatable.",
)
@click.option(
    "--phone-profile",
    "phone",
    is_flag=True,
    help="Write a phone-like copy instead (L1/L5 only, C/N0-dependent noise, duty-cycled phase, "
    "half cycles, drifts, NLOS bursts; docs/phone_profile.md); log OBS2 + '.phone.csv'.",
)
@click.option(
    "--phone-param",
    "phone_params",
    multiple=True,
    metavar="NAME=VALUE",
    help="Change one phone-profile parameter (e.g. duty_on_s=10). Repeatable.",
)
@click.option("--slip-lli", is_flag=True, help="Set the loss-of-lock bit at the first epoch of each slip.")
@click.option(
    "--seed",
    type=int,
    default=0,
    show_default=True,
    help="Seed of randomN epoch selections and of the phone profile.",
)
@click.option(
    "--out",
    "out",
    required=True,
    metavar="OBS2",
    help="Output RINEX (.crx/.yyd: Hatanaka; .gz: gzip; otherwise plain).",
)
@click.option(
    "--log", "log_path", default=None, metavar="PATH", help="CSV log of the changes [OBS2 + '.inject.csv']."
)
@one_line_errors
def inject(
    obs: str,
    phase: tuple[str, ...],
    code: tuple[str, ...],
    slip: tuple[str, ...],
    phone: bool,
    phone_params: tuple[str, ...],
    slip_lli: bool,
    seed: int,
    out: str,
    log_path: str | None,
) -> None:
    """Copy the RINEX observation file OBS with silent gross errors and cycle slips.

    EPOCHS are 0-based indices of the file's epochs: 100, 100-119, 5,9,30, 30-220/10 or
    random20 (drawn with --seed among the epochs that have the observation). SIGNAL is the
    observation code as in the file (RINEX 3: L1C, C1C; RINEX 2: L1, C1, P2). Only the
    value columns of the changed fields differ; loss-of-lock and signal-strength digits
    are kept (except --slip-lli).
    """
    from robustrtk.cli.paths import check_output_paths
    from robustrtk.sim.inject import inject_file, parse_spec

    default_log = out + (".phone.csv" if phone else ".inject.csv")
    check_output_paths([("OBS", obs)], [("--out", out), ("--log", log_path or default_log)])

    if phone_params and not phone:
        raise InputError("--phone-param applies only with --phone-profile")
    if phone:
        if phase or code or slip or slip_lli:
            raise InputError(
                "--phone-profile writes its own faults: give no --phase, --code, --slip or --slip-lli"
            )
        from robustrtk.sim.phone import PhoneProfile, parse_params, phone_profile_file

        prof = PhoneProfile().updated(**parse_params(phone_params))
        t0 = time.perf_counter()
        pres, stats = phone_profile_file(obs, out, prof, seed=seed, log_path=log_path)
        kinds: dict[str, int] = {}
        for ev in pres.events:
            kinds[ev.kind] = kinds.get(ev.kind, 0) + 1
        click.echo(
            f"wrote {out}: phone profile (seed {seed}), {stats['epochs']} epochs, signals "
            f"{' '.join(pres.batch.signals)}; events "
            f"{', '.join(f'{n} {k}' for k, n in sorted(kinds.items())) or 'none'}; log "
            f"{log_path or out + '.phone.csv'}; {time.perf_counter() - t0:.2f} s"
        )
        return
    specs = (
        [parse_spec(s, "phase") for s in phase]
        + [parse_spec(s, "code") for s in code]
        + [parse_spec(s, "slip") for s in slip]
    )
    if not specs:
        raise InputError("nothing to inject: give at least one --phase, --code or --slip")
    t0 = time.perf_counter()
    res = inject_file(obs, out, specs, seed=seed, slip_lli=slip_lli, log_path=log_path)
    counts = {k: sum(1 for c in res.changes if c.kind == k) for k in ("phase", "code", "slip")}
    what = ", ".join(f"{n} {k}" for k, n in counts.items() if n)
    click.echo(
        f"wrote {res.out_path} ({res.output_compression}): {len(res.changes)} values changed "
        f"({what}); log {res.log_path}; {time.perf_counter() - t0:.2f} s"
    )


__all__ = ["inject"]
