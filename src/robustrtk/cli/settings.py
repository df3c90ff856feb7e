"""From a mode, a TOML file and flags to the one :class:`~robustrtk.pipeline.config.Config`
that ``robustrtk solve`` runs with, and where each setting acts.

Layering: :func:`~robustrtk.pipeline.config.preset` of the mode and input kind, then an
RTKLIB ``.conf`` (``--rtklib-conf``, :mod:`robustrtk.pipeline.rtklib_conf`), then the TOML
file (``--config``, flat or sectioned), then the flags, which win. A *target* is an
input kind and a mode — the keys of :data:`~robustrtk.pipeline.config.PRESETS`, labelled
``dpl``, ``rtk`` (pseudolite tables), ``spp``, ``dgnss`` and ``rtk (RINEX)``.

A flag that does not act in the chosen target is refused (:class:`InputError`, one line,
exit status 2): either its leaf's ``modes`` do not include the mode, or it belongs to the
other input kind (:data:`KIND_ONLY`), or it acts only together with another setting that
the resolved configuration does not have (:data:`CONDITIONS`, e.g. ``--smoother`` needs a
Kalman SPP). Keys of a TOML file that do not act are allowed (one file may serve several
modes) and listed in one warning on stderr.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from robustrtk.errors import InputError
from robustrtk.pipeline.config import (
    DD_MODES,
    LEAVES,
    MODES,
    PRESETS,
    SECTIONS,
    Config,
    preset,
    profiled,
    read_config_dict,
)

if TYPE_CHECKING:  # read only with --rtklib-conf
    from robustrtk.pipeline.rtklib_conf import RtklibConf

#: Observation-table extensions (pseudolite input); anything else is read as RINEX.
PSEUDOLITE_EXT = (".csv", ".parquet", ".pq")
#: Input kinds and the mode each starts in when neither ``--mode`` nor the file names one.
DEFAULT_MODE = {"pseudolite": "dpl", "gnss": "spp"}
#: Every (input kind, mode) a solve can run, in preset order.
TARGETS: tuple[tuple[str, str], ...] = tuple(PRESETS)


def target_label(kind: str, mode: str) -> str:
    """``dpl``, ``rtk``, ``spp``, ``dgnss`` or ``rtk (RINEX)``."""
    return f"{mode} (RINEX)" if kind == "gnss" and mode == "rtk" else mode


def input_kind(path: str | Path) -> str:
    """``"pseudolite"`` for an observation table, else ``"gnss"`` (RINEX, phone logs), by content.

    The content decides (:func:`robustrtk.io.readers.detect_format`); a file that does not
    exist is judged by its extension so that the reader names it in its own error.
    """
    from robustrtk.io.readers import detect_format

    if not Path(path).is_file():
        return "pseudolite" if Path(path).suffix.lower() in PSEUDOLITE_EXT else "gnss"
    return "pseudolite" if detect_format(path).startswith("obs_table") else "gnss"


# ----------------------------------------------------------------------------- where keys act
#: Leaves that act for one input kind only: a leaf's ``modes`` cannot tell pseudolite RTK
#: from RINEX RTK. Receiver names and the reference transmitter come from pseudolite
#: tables and site files; satellite selection, the troposphere (ECEF frame only) and the
#: base-position source concern RINEX input.
KIND_ONLY: dict[str, str] = {
    "base": "pseudolite",
    "rover": "pseudolite",
    "reference": "pseudolite",
    "tropo": "gnss",
    "base_position": "gnss",
    **{k: "gnss" for k, leaf in LEAVES.items() if leaf.section == "gnss"},
}


def applies(key: str, kind: str, mode: str) -> bool:
    """Whether leaf ``key`` acts for ``kind`` input in ``mode`` (before :data:`CONDITIONS`)."""
    return mode in LEAVES[key].modes and KIND_ONLY.get(key, kind) == kind


def acts_in(key: str) -> tuple[tuple[str, str], ...]:
    """The targets leaf ``key`` acts in (before :data:`CONDITIONS`)."""
    return tuple(t for t in TARGETS if applies(key, *t))


def _process(cfg: Config) -> str:
    """The DD process model the engine builds from ``cfg``."""
    est = cfg.estimator
    if est.dynamics == "static":
        return "static"
    if est.dynamics == "auto":  # stationary or constant velocity, chosen per epoch
        return "constant-velocity"
    if est.kinematic_model == "constant-velocity" or (est.kinematic_model == "auto" and cfg.mode == "rtk"):
        return "constant-velocity"
    return "random-walk"


@dataclass(frozen=True)
class Condition:
    """Keys that act in ``modes`` only when ``holds(cfg)``; ``needs`` says what they need."""

    keys: tuple[str, ...]
    modes: tuple[str, ...]
    needs: str
    holds: Callable[[Config], bool]


#: Settings of the Kalman SPP that least squares does not use.
KALMAN_SPP_KEYS: tuple[str, ...] = (
    "k0", "k1", "smoother", "sigma_acc_m_s2", "phase_sigma_m", "reinit_epochs", "ukf_alpha", "ukf_beta",
    "ukf_kappa", "kalman_use_cn0", "sigma_acc_up_m_s2", "q_clk_m2_s", "q_drift_m2_s3", "q_phase_clk_m2_s",
    "use_doppler", "doppler_sigma_m_s", "use_phase", "q_amb_m2_s", "amb_var0_m2", "lli_reset", "slip_var_m2",
    "dual_frequency", "q_ifb_m2_s", "clock_reset_m", "reinit_m", "doppler_weighting", "doppler_cn0_sigma_m_s",
    "zupt", "zupt_speed_m_s", "zupt_sigma_m_s", "adaptive", "adaptive_c0", "adaptive_c1",
    "adaptive_max_iter", "prefit_k0", "prefit_k1", "code_bias", "code_bias_sigma_m", "code_bias_tau_s",
    "code_elevation_delay", "code_elevation_delay_tau_s",
)  # fmt: skip
_AR_KEYS = ("ratio", "min_success_rate", "ar_elev_mask_deg", "fix_max_sigma_m", "fix_residual_k")

_RW = "the random-walk model (--dynamics kinematic, --kinematic-model random-walk or auto outside rtk)"
_CV = "the constant-velocity model (--dynamics kinematic, --kinematic-model constant-velocity or auto in rtk)"
_CONT = "continuous ambiguity resolution (--ar other than off, --no-instantaneous, --ar-scheme filter)"

#: Settings that act only together with another setting (checked on the resolved config).
CONDITIONS: tuple[Condition, ...] = (
    Condition(
        KALMAN_SPP_KEYS, ("spp",), "a Kalman SPP (--filter ekf or ukf)", lambda c: c.estimator.filter != "lsq"
    ),
    Condition(("fgo_iono",), ("spp",), "the batch smoother (--fgo)", lambda c: c.spp.fgo),
    Condition(
        ("ukf_alpha", "ukf_beta", "ukf_kappa"),
        MODES,
        "the UKF (--filter ukf)",
        lambda c: c.estimator.filter == "ukf",
    ),
    Condition(
        ("q_static_m2_s",),
        DD_MODES,
        "static or auto dynamics (--dynamics static or auto)",
        lambda c: c.estimator.dynamics in ("static", "auto"),
    ),
    Condition(
        ("adaptive_c0", "adaptive_c1"),
        MODES,
        "an adaptive factor (--adaptive, --adaptive innovation)",
        lambda c: c.estimator.adaptive != "off",
    ),
    Condition(
        ("adaptive_max_iter",),
        MODES,
        "the state-discrepancy adaptive factor (--adaptive, --adaptive state)",
        lambda c: c.estimator.adaptive == "state",
    ),
    Condition(
        ("prefit_k0", "prefit_k1"),
        MODES,
        "the pre-fit + post-fit policy (--robust prefit+postfit)",
        lambda c: c.robust.policy == "prefit+postfit",
    ),
    Condition(
        ("kinematic_model",),
        DD_MODES,
        "kinematic dynamics (--dynamics kinematic)",
        lambda c: c.estimator.dynamics == "kinematic",
    ),
    Condition(("sigma_vel_m_s",), DD_MODES, _RW, lambda c: _process(c) == "random-walk"),
    Condition(
        ("sigma_acc_m_s2", "init_sigma_vel_m_s"), DD_MODES, _CV, lambda c: _process(c) == "constant-velocity"
    ),
    Condition(
        _AR_KEYS, ("rtk",), "ambiguity resolution (--ar other than off)", lambda c: c.ar.method != "off"
    ),
    Condition(
        ("par_min",),
        ("rtk",),
        "partial ambiguity resolution (--ar par, par-sr or par-sr+par)",
        lambda c: c.ar.method in ("par", "par-sr", "par-sr+par"),
    ),
    Condition(
        ("hold",),
        ("rtk",),
        _CONT,
        lambda c: c.ar.method != "off" and not c.ar.instantaneous and c.ar.scheme == "filter",
    ),
    Condition(
        ("ar_lock_epochs",),
        ("rtk",),
        "ambiguities kept from epoch to epoch (--ar not off, --no-instantaneous, and with "
        "--ar-scheme prior --prior-ambiguities carry)",
        lambda c: (
            c.ar.method != "off"
            and not c.ar.instantaneous
            and (c.ar.scheme == "filter" or c.ar.prior_ambiguities == "carry")
        ),
    ),
    Condition(
        ("hold_sigma_cyc", "hold_min_fix"),
        ("rtk",),
        "fix-and-hold (--hold, --no-instantaneous, --ar not off, --ar-scheme filter)",
        lambda c: c.ar.method != "off" and c.ar.hold and not c.ar.instantaneous and c.ar.scheme == "filter",
    ),
    Condition(
        ("instantaneous",),
        ("rtk",),
        "the filter AR scheme (--ar-scheme filter)",
        lambda c: c.ar.scheme == "filter",
    ),
    Condition(
        ("prior_sigma_m", "prior_ambiguities", "prior_covariance"),
        ("rtk",),
        "the prior AR scheme (--ar-scheme prior)",
        lambda c: c.ar.scheme == "prior",
    ),
)


def inactive_reason(key: str, cfg: Config, kind: str) -> str | None:
    """Why leaf ``key`` has no effect in ``cfg`` for ``kind`` input, or None if it acts."""
    mode = cfg.mode
    if not applies(key, kind, mode):
        where = ", ".join(target_label(*t) for t in acts_in(key)) or "no mode"
        return f"does not apply to mode {target_label(kind, mode)} (it acts in {where})"
    for cond in CONDITIONS:
        if key in cond.keys and mode in cond.modes and not cond.holds(cfg):
            return f"acts only with {cond.needs}"
    return None


# ----------------------------------------------------------------------------- non-config options
#: The ``solve`` options that are not config leaves, and the targets they act in.
OPTION_TARGETS: dict[str, tuple[tuple[str, str], ...]] = {
    "--site": (("pseudolite", "dpl"), ("pseudolite", "rtk")),
    "--nav": (("gnss", "spp"), ("gnss", "dgnss"), ("gnss", "rtk")),
    "--rtklib-conf": (("gnss", "spp"), ("gnss", "dgnss"), ("gnss", "rtk")),
    "--base": (("gnss", "dgnss"), ("gnss", "rtk")),
    "--base-pos": (("gnss", "dgnss"), ("gnss", "rtk")),
    "--diagnostics": (
        ("pseudolite", "dpl"),
        ("pseudolite", "rtk"),
        ("gnss", "spp"),
        ("gnss", "dgnss"),
        ("gnss", "rtk"),
    ),  # fmt: skip
    "--kalman": (("gnss", "spp"),),
    "--force": (("gnss", "dgnss"), ("gnss", "rtk")),
    "--profile": (("gnss", "dgnss"), ("gnss", "rtk")),
}


def check_options(given: Iterable[str], kind: str, mode: str) -> None:
    """Refuse a non-config option (see :data:`OPTION_TARGETS`) given for a target it does not act in."""
    for opt in given:
        targets = OPTION_TARGETS[opt]
        if (kind, mode) not in targets:
            where = ", ".join(target_label(*t) for t in targets)
            raise InputError(f"{opt}: does not apply to mode {target_label(kind, mode)} (it acts in {where})")


# ----------------------------------------------------------------------------- layering
def _mode_for(kind: str, mode: str | None) -> str:
    mode = mode or DEFAULT_MODE[kind]
    if (kind, mode) not in PRESETS:
        if kind == "gnss":
            raise InputError(
                f"--mode: mode {mode} is for pseudolite tables; RINEX input takes spp, dgnss or rtk"
            )
        raise InputError(f"--mode: mode {mode} is for RINEX input; pseudolite tables take dpl or rtk")
    return mode


def _echo_warning(msg: str) -> None:
    click.echo(f"warning: {msg}", err=True)


def _flag_error(exc: InputError, flags: Mapping[str, Any]) -> InputError:
    """A validation error of the command line, naming the flag instead of the key."""
    key = exc.message.split(":", 1)[0]
    if key in flags:
        return InputError(LEAVES[key].flag + exc.message[len(key) :])
    return InputError(exc.message, exc.path, exc.line)


#: Largest ``--config`` / ``--rtklib-conf`` file read (bytes): a configuration is a few kB.
MAX_CONFIG_BYTES = 1 << 20


def check_config_file(path: str | Path) -> None:
    """:class:`InputError` for a configuration that is not a regular file (a FIFO would
    block) or is larger than :data:`MAX_CONFIG_BYTES` (parsed, a huge array would take
    seconds and fill the error message)."""
    import os
    import stat

    try:
        st = os.stat(path)
    except OSError:
        return  # the reader names a missing file
    if not stat.S_ISREG(st.st_mode):
        raise InputError("--config: expected a regular file (not a FIFO, device or directory)", str(path))
    if st.st_size > MAX_CONFIG_BYTES:
        raise InputError(
            f"--config: {st.st_size} bytes; a configuration file is at most {MAX_CONFIG_BYTES >> 20} MiB",
            str(path),
        )


def resolve_config(
    mode: str | None,
    kind: str,
    config_path: str | Path | None,
    flags: Mapping[str, Any],
    *,
    warn: Callable[[str], None] | None = _echo_warning,
    rtklib_conf: str | Path | None = None,
    profile: str | None = None,
    default_mode: str | None = None,
) -> Config:
    """The configuration ``solve`` runs with.

    Parameters
    ----------
    mode : str, optional
        ``--mode``; None takes the file's ``mode``, else ``dpl`` for pseudolite tables and
        ``spp`` for RINEX.
    kind : {"pseudolite", "gnss"}
        Input kind (:func:`input_kind`).
    config_path : path, optional
        TOML file (flat or sectioned keys) layered over the preset.
    flags : mapping
        Flat settings given on the command line (keys of
        :data:`~robustrtk.pipeline.config.LEAVES`; None values are ignored); they win.
    warn : callable, optional
        Receives the one-line warning naming file keys that do not act (default: stderr),
        and the one naming the keys of the RTKLIB file that are ignored.
    rtklib_conf : path, optional
        RTKLIB ``.conf`` (RINEX input) layered over the preset, under the TOML file; its
        ``pos1-posmode`` gives the mode when neither ``--mode`` nor the TOML file does. Its
        base position is :func:`rtklib_base_pos`.
    profile : str, optional
        Receiver profile (:data:`~robustrtk.pipeline.config.PROFILES`, ``--profile``)
        applied over the preset, under the RTKLIB file, the TOML file and the flags.
    default_mode : str, optional
        The mode when neither ``mode``, the TOML file nor the RTKLIB file gives one
        (:func:`robustrtk.cli.infer.infer_gnss_mode`); None: the input kind's default.

    Raises
    ------
    InputError
        A bad file or value, or a flag that does not act in the resolved target.
    """
    given = {k: v for k, v in flags.items() if v is not None}
    for key in given:
        if key not in LEAVES:
            raise InputError(f"unknown setting {key!r}")
    if config_path is not None:
        check_config_file(config_path)
    file_flat = read_config_dict(config_path) if config_path is not None else {}
    conf = _rtklib(rtklib_conf, kind)
    conf_flat = dict(conf.settings) if conf is not None else {}
    mode = _mode_for(
        kind,
        mode or given.pop("mode", None) or file_flat.get("mode") or conf_flat.get("mode") or default_mode,
    )
    given.pop("mode", None)
    file_flat.pop("mode", None)
    conf_flat.pop("mode", None)
    source = str(config_path)
    cfg = profiled(preset(mode, kind), profile, kind)
    if conf is not None:
        cfg = cfg.updated(**conf_flat).validate(str(rtklib_conf))
    cfg = cfg.updated(**file_flat).validate(source) if file_flat else cfg
    for key in given:  # before the values: a refused flag is named even if its value is bad
        if not applies(key, kind, mode):
            raise InputError(f"{LEAVES[key].flag}: {inactive_reason(key, cfg, kind)}")
    try:
        cfg = cfg.updated(**given).validate("command line")
    except InputError as exc:
        raise _flag_error(exc, given) from None
    for key in given:
        why = inactive_reason(key, cfg, kind)
        if why is not None:
            raise InputError(f"{LEAVES[key].flag}: {why}")
    idle = [k for k in file_flat if k not in given and inactive_reason(k, cfg, kind) is not None]
    if idle and warn is not None:
        warn(
            f"{source}: {', '.join(idle)}: no effect in mode {target_label(kind, mode)} with these settings "
            "(see docs/configuration.md)"
        )
    if conf is not None and warn is not None:
        text = rtklib_ignored(conf, cfg, kind, overridden=set(given) | set(file_flat))
        if text:
            warn(f"{rtklib_conf}: RTKLIB keys ignored: {text}")
    return cfg


def _rtklib(path: str | Path | None, kind: str) -> RtklibConf | None:
    if path is None:
        return None
    if kind != "gnss":
        raise InputError("--rtklib-conf: RTKLIB settings apply to RINEX input, not pseudolite tables")
    from robustrtk.pipeline.rtklib_conf import read_rtklib_conf  # only with --rtklib-conf (start-up time)

    return read_rtklib_conf(path)


def rtklib_ignored(conf: RtklibConf, cfg: Config, kind: str = "gnss", overridden: Iterable[str] = ()) -> str:
    """The RTKLIB keys of ``conf`` that have no effect on ``cfg``, grouped by reason.

    These are the keys :func:`~robustrtk.pipeline.rtklib_conf.read_rtklib_conf` ignored and
    those whose setting does not act in ``cfg`` (e.g. ``pos2-arlockcnt`` with instantaneous
    AR); settings in ``overridden`` (given by the TOML file or flags) are not listed.
    """
    parts = [*conf.notes, conf.ignored_text()] if conf.ignored else list(conf.notes)
    skip = set(overridden)
    by_why: dict[str, list[str]] = {}
    for key, src in conf.sources.items():
        if key == "mode" or key in skip:
            continue
        why = inactive_reason(key, cfg, kind)
        if why is not None:
            by_why.setdefault(f"{key} {why}", []).append(src)
    parts += [f"{why}: {', '.join(srcs)}" for why, srcs in by_why.items()]
    return "; ".join(p for p in parts if p)


def rtklib_base_pos(path: str | Path | None, mode: str) -> str | None:
    """``--base-pos`` text (``"X,Y,Z"``) from the ``ant2-*`` keys of an RTKLIB file, or None
    (no file, SPP, or a base position the file leaves to the RINEX header)."""
    if path is None or mode == "spp":
        return None
    from robustrtk.pipeline.rtklib_conf import read_rtklib_conf

    return read_rtklib_conf(path).base_pos_text()


# ----------------------------------------------------------------------------- TOML text
def toml_value(v: Any) -> str:
    """One TOML value (bool, int, float, str)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        # a TOML basic string: quote, backslash and control characters (DEL too) escaped
        body = "".join(
            "\\" + ch if ch in '"\\' else f"\\u{ord(ch):04x}" if ord(ch) < 0x20 or ord(ch) == 0x7F else ch
            for ch in v
        )
        return f'"{body}"'
    raise TypeError(f"no TOML form for {v!r}")


def config_toml(cfg: Config, header: str | None = None, kind: str | None = None) -> str:
    """``cfg`` as sectioned TOML (unset optional keys as comments); reads back equal.

    With ``kind`` (the input kind), keys without effect in ``cfg`` are marked in a comment.
    """
    data = cfg.to_dict()
    lines = [f"# {h}" for h in (header.splitlines() if header else ())]
    lines.append(f"mode = {toml_value(data['mode'])}")
    for section in SECTIONS:
        lines += ["", f"[{section}]"]
        for attr, v in data[section].items():
            key = next(k for k, lf in LEAVES.items() if lf.section == section and lf.attr == attr)
            line = f"# {key} = (unset)" if v is None else f"{key} = {toml_value(v)}"
            if kind is not None and inactive_reason(key, cfg, kind) is not None:
                line += "  # no effect here"
            lines.append(line)
    return "\n".join(lines) + "\n"


__all__ = [
    "CONDITIONS", "DEFAULT_MODE", "KALMAN_SPP_KEYS", "KIND_ONLY", "OPTION_TARGETS", "PSEUDOLITE_EXT",
    "TARGETS", "Condition", "acts_in", "applies", "check_options", "config_toml", "inactive_reason",
    "input_kind", "resolve_config", "rtklib_base_pos", "rtklib_ignored", "target_label", "toml_value",
]  # fmt: skip
