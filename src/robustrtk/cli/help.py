"""The help of ``robustrtk solve``: a short grouped page, and every flag with ``--help-all``.

``solve --help`` shows the command's own options in three groups (input, mode, output) and
the settings a first run is most likely to change, one line each, then one line per
configuration section naming how many more settings it holds. ``solve --help-all`` lists
every flag, grouped by section, with where it acts and its defaults in words
(``default 0.1 for pseudolite dpl and rtk; 10 for RINEX dgnss and rtk``).
"""

from __future__ import annotations

import inspect
import textwrap
from collections.abc import Iterable, Sequence

import click

__all__ = ["BASIC_SETTINGS", "OWN_GROUPS", "defaults_words", "format_solve_help"]

#: The command's own options by group (``mode`` and ``kalman`` are shown under Mode); a
#: command's own options in none of them are listed under "Other options", never hidden.
OWN_GROUPS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("Input", ("rover_src", "base_src", "nav", "base_obs", "base_pos", "site", "config", "rtklib_conf",
               "profile", "time_ref", "beidou_time")),
    ("Mode", ("mode", "kalman")),
    ("Output", ("out", "fmt", "diagnostics", "nmea", "quiet", "force", "show_config", "help_all")),
    ("Streams", ("speed", "base_wait", "retries", "gga_interval_s", "stall_timeout_s")),
)  # fmt: skip

#: Settings shown by ``--help`` (the rest: ``--help-all``).
BASIC_SETTINGS: tuple[str, ...] = (
    "filter", "robust", "dynamics", "smoother", "ar", "ratio", "hold", "elev_mask_deg", "systems",
    "freqs", "code_sigma_m", "time_start", "time_end",
)  # fmt: skip

#: One-line help of the settings ``--help`` shows (``--help-all``: the full text).
SHORT_HELP = {
    "mode": "spp, dgnss, rtk (GNSS); dpl, rtk (pseudolite tables)",
    "filter": "ukf or ekf (Kalman), lsq (epoch-wise least squares, SPP)",
    "robust": "robust policy: none, igg3, igg3-std, huber, postfit, prefit+postfit",
    "dynamics": "receiver dynamics: static, kinematic or auto",
    "ar": "ambiguity resolution: off, lambda, par, par-sr, par-sr+par",
    "systems": "system letters to use, e.g. GEJ",
    "time_start": "first rover epoch solved, GPST 'yyyy/mm/dd hh:mm:ss' or 'hh:mm:ss'",
    "time_end": "last rover epoch solved, as --time-start",
}

#: Section titles of ``--help-all``.
SECTION_TITLES = {
    "estimator": "Filter and dynamics [estimator]",
    "robust": "Robust estimation [robust]",
    "measurement": "Measurement model [measurement]",
    "ar": "Ambiguity resolution [ar]",
    "slip": "Cycle slips [slip]",
    "gnss": "Satellites, signals and time window [gnss]",
    "spp": "Single-point positioning [spp]",
    "receivers": "Receivers [receivers]",
}

_WIDTH = 90
_FLAG_COL = 26


def _words(kind: str, mode: str) -> str:
    if kind == "pseudolite":
        return f"pseudolite {mode}"
    return f"RINEX {mode}" if mode == "rtk" else mode


def _join(items: Sequence[str]) -> str:
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " and " + items[-1]


def _value(v: str) -> str:
    return "not set" if v == "None" else v


def defaults_words(key: str) -> str:
    """The presets' defaults of a setting in words: ``default 3`` when they agree, else
    ``default 0.1 for pseudolite dpl and rtk; 10 for dgnss and RINEX rtk``."""
    from robustrtk.cli.options import defaults_text, preset_defaults
    from robustrtk.cli.settings import acts_in

    if key == "mode":
        return "default spp (rtk or dgnss with --base), dpl for pseudolite tables"
    targets = acts_in(key)
    pairs = preset_defaults(key)
    if not pairs:
        return f"default {_value(defaults_text(key))}"
    values = [_value(v) for _, v in pairs]
    if len(set(values)) == 1:
        return f"default {values[0]}"
    by_value: dict[str, list[tuple[str, str]]] = {}
    for (kind, mode), v in zip(targets, values, strict=True):
        by_value.setdefault(v, []).append((kind, mode))
    parts = []
    for v, ts in by_value.items():
        kinds = {k for k, _ in ts}
        if len(kinds) == 1 and len(ts) > 1:
            prefix = "pseudolite " if "pseudolite" in kinds else "RINEX "
            parts.append(f"{v} for {prefix}{_join([m for _, m in ts])}")
        else:
            parts.append(f"{v} for {_join([_words(k, m) for k, m in ts])}")
    return "default " + "; ".join(parts)


def _line(flag: str, text: str, width: int = _WIDTH) -> list[str]:
    """``  flag   text`` wrapped under the text column."""
    head = f"  {flag}"
    body = textwrap.wrap(text, width - _FLAG_COL) or [""]
    if len(head) > _FLAG_COL - 2:
        return [head] + [" " * _FLAG_COL + b for b in body]
    return [head.ljust(_FLAG_COL) + body[0]] + [" " * _FLAG_COL + b for b in body[1:]]


def _decl(param: click.Parameter) -> str:
    opts = [o for o in param.opts if o.startswith("--")]
    secondary = [o for o in getattr(param, "secondary_opts", []) if o.startswith("--")]
    name = "/".join(opts[:1] + secondary[:1])
    if isinstance(param, click.Option) and not param.is_flag and not param.count:
        t = param.type
        if isinstance(t, click.Choice) and len(t.choices) <= 5:
            return f"{name} [{'|'.join(map(str, t.choices))}]"
        meta = "PATH" if isinstance(t, click.Path) else t.name.upper()
        if param.metavar:
            meta = param.metavar
        return f"{name} {meta}"
    return name


def _own_lines(params: dict[str, click.Parameter], names: Iterable[str]) -> list[str]:
    out: list[str] = []
    for n in names:
        p = params.get(n)
        if p is not None and isinstance(p, click.Option) and p.help:
            out += _line(_decl(p), p.help)
    return out


def _leaf_lines(params: dict[str, click.Parameter], keys: Iterable[str], full: bool) -> list[str]:
    from robustrtk.cli.options import SOLVE_LEAVES, modes_text

    out: list[str] = []
    for k in keys:
        leaf = SOLVE_LEAVES[k]
        p = params.get(k)
        if p is None:
            continue
        modes = modes_text(k)
        where = "" if modes == "all" else f" ({modes})"
        what = leaf.help if full else SHORT_HELP.get(k, leaf.help)
        out += _line(_decl(p), f"{what}{where}; {defaults_words(k)}.")
    return out


def format_solve_help(cmd: click.Command, ctx: click.Context, *, full: bool) -> str:
    """The help page of ``solve`` or ``run`` (short, or every flag with ``full``): the
    command's own options by :data:`OWN_GROUPS`, then the configuration's settings."""
    from robustrtk.cli.options import SOLVE_LEAVES

    params = {p.name: p for p in cmd.get_params(ctx) if p.name}
    args = " ".join(p.human_readable_name for p in cmd.get_params(ctx) if isinstance(p, click.Argument))
    lines = [f"Usage: {ctx.command_path} [OPTIONS]{' ' + args if args else ''}", ""]
    doc = inspect.cleandoc(cmd.help or "")
    lines += ["  " + ln if ln else "" for ln in doc.splitlines()]
    grouped = {n for _, names in OWN_GROUPS for n in names}
    other = [n for n, p in params.items()
             if isinstance(p, click.Option) and n not in SOLVE_LEAVES and n not in grouped
             and "--help" not in p.opts]  # fmt: skip
    for title, names in (*OWN_GROUPS, ("Other options", tuple(other))):
        own = _own_lines(params, [n for n in names if n != "mode"])
        if title == "Mode":
            mode_help = getattr(cmd, "mode_help", None)
            p = params.get("mode")
            own = (
                _line(_decl(p), mode_help)
                if mode_help and p is not None
                else _leaf_lines(params, ["mode"], full=False)
            ) + own
        if own:
            lines += ["", f"{title}:", *own]
    if full:
        sections: dict[str, list[str]] = {}
        for k, leaf in SOLVE_LEAVES.items():
            if k != "mode":
                sections.setdefault(leaf.section or "", []).append(k)
        for sec, keys in sections.items():
            lines += ["", f"{SECTION_TITLES.get(sec, sec)}:"] + _leaf_lines(params, keys, full=True)
        lines += ["", "  -h, --help               Show the short help and exit."]
        return "\n".join(lines) + "\n"
    lines += ["", "Settings most often changed (defaults per mode):"]
    lines += _leaf_lines(params, [k for k in BASIC_SETTINGS if k in SOLVE_LEAVES], full=False)
    counts: dict[str, int] = {}
    for k, leaf in SOLVE_LEAVES.items():
        if k not in BASIC_SETTINGS and k != "mode":
            counts[leaf.section or ""] = counts.get(leaf.section or "", 0) + 1
    more = ", ".join(f"{sec} {n}" for sec, n in counts.items())
    lines += [
        "",
        *textwrap.wrap(f"Advanced: {sum(counts.values())} more settings by section ({more}):", _WIDTH),
    ]
    lines += [
        "  robustrtk solve --help-all or docs/configuration.md; each is also a --config key.",
        "  -h, --help               Show this message and exit.",
    ]
    return "\n".join(lines) + "\n"
