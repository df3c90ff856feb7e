"""Solver configuration: one typed tree for every mode and input type.

:class:`Config` holds a mode and one frozen section per concern — ``estimator``, ``robust``,
``measurement``, ``ar``, ``slip``, ``gnss``, ``spp``, ``receivers`` and ``coop`` (the
cooperative run, which reads the shared leaves of the other sections too). Every leaf has a
unique *key* (its field name, e.g. ``ratio`` or ``code_sigma_m``); a few leaves whose field
name would be ambiguous have a public alias (``robust.policy`` is ``robust``, ``ar.method``
is ``ar``, ``slip.detectors`` is ``slip``, ``estimator.filter`` is ``filter``). That key is
the TOML key (top level, or inside the section's table), the name accepted by
:meth:`Config.updated`, and — with ``_`` as ``-`` and unit suffixes dropped — the command
line flag, so documentation, TOML, flags and the shown defaults come from one place.

Mode presets (:data:`PRESETS`) are instances of the tree; :func:`preset` returns the one a
mode and input kind start from. A TOML file is layered over the preset, then flags over
the file. Each leaf names the modes it acts in (``modes`` metadata); :func:`check_applies`
refuses a key given for a mode it does not act in.

The sections, their choices and their field helper
(:func:`~robustrtk.pipeline.config_sections.config_leaf`) are in
:mod:`robustrtk.pipeline.config_sections`; the sections are importable from here.
"""

from __future__ import annotations

import sys
import types
import typing
from dataclasses import MISSING, Field, asdict, dataclass, field, fields, is_dataclass, replace
from pathlib import Path
from typing import Any, Literal, get_args, get_origin

from robustrtk.errors import InputError
from robustrtk.pipeline.config_sections import (
    DD_MODES,
    MODES,
    SLIP_DETECTORS,
    ArConfig,
    CoopConfig,
    EstimatorConfig,
    GnssConfig,
    MeasurementConfig,
    Mode,
    ReceiversConfig,
    RobustConfig,
    SlipConfig,
    SppSection,
    config_leaf,
)


@dataclass(frozen=True)
class Config:
    """All solver settings: a mode and one section per concern (see the module docstring)."""

    mode: Mode = config_leaf("dpl", "dpl, rtk (pseudolite tables or RINEX), spp, dgnss (RINEX)")
    estimator: EstimatorConfig = field(default_factory=EstimatorConfig)
    robust: RobustConfig = field(default_factory=RobustConfig)
    measurement: MeasurementConfig = field(default_factory=MeasurementConfig)
    ar: ArConfig = field(default_factory=ArConfig)
    slip: SlipConfig = field(default_factory=SlipConfig)
    gnss: GnssConfig = field(default_factory=GnssConfig)
    spp: SppSection = field(default_factory=SppSection)
    receivers: ReceiversConfig = field(default_factory=ReceiversConfig)
    coop: CoopConfig = field(default_factory=CoopConfig)

    # ---------------------------------------------------------------- construction
    @classmethod
    def of(cls, **flat: Any) -> Config:
        """The default tree with flat ``key=value`` settings applied (see :meth:`updated`)."""
        return cls().updated(**flat)

    def updated(self, **flat: Any) -> Config:
        """A copy with the non-None flat settings applied (keys as in :data:`LEAVES`).

        ``cfg.updated(ratio=2.0, robust="none")`` sets ``cfg.ar.ratio`` and
        ``cfg.robust.policy``; an unknown key raises :class:`InputError`.
        """
        by_section: dict[str | None, dict[str, Any]] = {}
        for key, val in flat.items():
            if val is None:
                continue
            leaf = LEAVES.get(key)
            if leaf is None:
                raise InputError(f"unknown setting {key!r}; expected one of {', '.join(sorted(LEAVES))}")
            by_section.setdefault(leaf.section, {})[leaf.attr] = val
        out = self
        for section, kw in by_section.items():
            if section is None:
                out = replace(out, **kw)
            else:
                out = replace(out, **{section: replace(getattr(out, section), **kw)})
        return out

    # ---------------------------------------------------------------- access
    def get(self, key: str) -> Any:
        """The value of the leaf with flat key ``key``."""
        leaf = LEAVES[key]
        return getattr(self if leaf.section is None else getattr(self, leaf.section), leaf.attr)

    def slip_detectors(self) -> frozenset[str]:
        """The enabled cycle-slip detectors (empty for ``"none"``)."""
        d = self.slip.detectors
        return frozenset() if d == "none" else frozenset(d.split("+"))

    def to_dict(self) -> dict[str, Any]:
        """Nested mapping (sections as tables), as written to TOML."""
        return asdict(self)

    def flat(self) -> dict[str, Any]:
        """Flat mapping ``key -> value`` of every leaf."""
        return {k: self.get(k) for k in LEAVES}

    # ---------------------------------------------------------------- checks
    def validate(self, source: str = "config") -> Config:
        """Check choices, types and ranges; raise :class:`InputError` naming the key."""
        for key, leaf in LEAVES.items():
            val = self.get(key)
            if leaf.choices and val not in leaf.choices:
                raise InputError(f"{key}: expected one of {', '.join(leaf.choices)}, got {val!r}", source)
            _check_type(key, leaf, val, source)
        positive = (
            "init_sigma_m", "code_sigma_m", "phase_sigma_m", "ratio", "sigma_vel_m_s", "sigma_acc_m_s2",
            "amb_init_sigma_cyc", "hold_sigma_cyc", "ukf_alpha", "init_sigma_vel_m_s", "q_static_m2_s",
            "gf_threshold_m", "doppler_threshold_cyc", "sigma_acc_up_m_s2", "doppler_sigma_m_s",
            "code_elevation_delay_tau_s", "dgnss_doppler_sigma_m_s",
            "amb_var0_m2", "raim_alpha", "doppler_cn0_sigma_m_s", "zupt_speed_m_s", "zupt_sigma_m_s",
            "prior_sigma_m", "gf_window_threshold_m",
        )  # fmt: skip
        for key in positive:
            v = self.get(key)
            if not (v > 0 and v < float("inf")):
                raise InputError(f"{key}: expected a finite positive number, got {v!r}", source)
        nonneg = ("snr_mask_dbhz", "ar_elev_mask_deg", "fix_residual_k", "fix_max_sigma_m",
                  "min_success_rate", "q_clk_m2_s", "q_drift_m2_s3", "q_phase_clk_m2_s", "q_amb_m2_s",
                  "q_ifb_m2_s", "slip_var_m2", "gf_window_s", "fix_confirm_epochs", "interval_s",
                  "max_age_s", "sigma_age_m_s", "dgnss_doppler_jerk_m_s3")  # fmt: skip
        for key in nonneg:
            v = self.get(key)
            if not (v >= 0 and v < float("inf")):
                raise InputError(f"{key}: expected a finite number >= 0, got {v!r}", source)
        for key in ("init_sigma_m", "code_sigma_m", "phase_sigma_m", "sigma_vel_m_s", "sigma_acc_m_s2",
                    "amb_init_sigma_cyc", "hold_sigma_cyc", "init_sigma_vel_m_s", "sigma_acc_up_m_s2",
                    "doppler_sigma_m_s", "prior_sigma_m"):  # fmt: skip
            v = self.get(key)
            if not SIGMA_RANGE[0] <= v <= SIGMA_RANGE[1]:
                lo, hi = SIGMA_RANGE
                raise InputError(
                    f"{key}: expected a standard deviation in [{lo:g}, {hi:g}], got {v!r}", source
                )
        for key in ("q_static_m2_s", "amb_var0_m2", "q_clk_m2_s", "q_drift_m2_s3", "q_phase_clk_m2_s",
                    "q_amb_m2_s", "q_ifb_m2_s", "slip_var_m2"):  # fmt: skip
            v = self.get(key)
            if not v <= SIGMA_RANGE[1] ** 2:
                raise InputError(f"{key}: expected a variance <= {SIGMA_RANGE[1] ** 2:g}, got {v!r}", source)
        for key in ("time_start", "time_end"):
            text = self.get(key)
            if text is not None:
                from robustrtk.timeutil import parse_gpst_instant  # numpy: only when a window is set

                try:
                    parse_gpst_instant(text, 0.0, key)
                except InputError as exc:
                    raise InputError(exc.message, source) from None
        for key in ("elev_mask_deg", "ar_elev_mask_deg"):
            v = self.get(key)
            if not 0.0 <= v < 90.0:
                raise InputError(f"{key}: expected degrees in [0, 90), got {v!r}", source)
        try:
            from robustrtk.measurement.signals import parse_slots  # numpy: not at start-up

            parse_slots(self.gnss.freqs)
        except InputError as exc:
            raise InputError(exc.message, source) from None
        for n0, n1 in (("k0", "k1"), ("prefit_k0", "prefit_k1")):
            k0, k1 = self.get(n0), self.get(n1)
            for name, k in ((n0, k0), (n1, k1)):
                if k is not None and not (0 < k < float("inf")):
                    raise InputError(f"{name}: expected a finite positive number, got {k!r}", source)
            if k0 is not None and k1 is not None and not k0 < k1:
                raise InputError(f"{n0}, {n1}: expected 0 < {n0} < {n1}, got {k0}, {k1}", source)
        tokens = self.slip.detectors.split("+")
        if self.slip.detectors != "none" and (not tokens or any(t not in SLIP_DETECTORS for t in tokens)):
            raise InputError(
                f"slip: expected 'none' or detectors joined by '+' among {', '.join(SLIP_DETECTORS)}, "
                f"got {self.slip.detectors!r}",
                source,
            )
        for key in ("hold_min_fix", "ar_lock_epochs", "reinit_epochs", "max_exclusions"):
            if self.get(key) < 0:
                raise InputError(f"{key}: expected an integer >= 0, got {self.get(key)}", source)
        for key in ("par_min", "max_iter", "adaptive_max_iter"):
            if self.get(key) < 1:
                raise InputError(f"{key}: expected an integer >= 1, got {self.get(key)}", source)
        c0, c1 = self.estimator.adaptive_c0, self.estimator.adaptive_c1
        for name, c in (
            ("code_bias_sigma_m", self.spp.code_bias_sigma_m),
            ("code_bias_tau_s", self.spp.code_bias_tau_s),
        ):
            if c is not None and not (0 < c < float("inf")):
                raise InputError(f"{name}: expected a finite positive number, got {c!r}", source)
        for name, c in (("adaptive_c0", c0), ("adaptive_c1", c1)):
            if c is not None and not (0 < c < float("inf")):
                raise InputError(f"{name}: expected a finite positive number, got {c!r}", source)
        lo = c0 if c0 is not None else (1.0 if self.estimator.adaptive == "state" else 2.0)
        hi = c1 if c1 is not None else (2.5 if self.estimator.adaptive == "state" else 6.0)
        if not lo < hi:
            key = "adaptive_c1" if c0 is None else "adaptive_c0"
            raise InputError(f"{key}: expected adaptive_c0 < adaptive_c1, got {lo:g} and {hi:g}", source)
        if self.ar.scheme == "prior" and self.ar.instantaneous:
            msg = "ar_scheme: prior runs its own per-epoch AR; turn instantaneous off (see prior_ambiguities)"
            raise InputError(msg, source)
        if self.mode != "spp" and self.estimator.filter == "lsq":
            msg = f"filter: lsq (least squares) is for mode spp; mode {self.mode} takes ukf or ekf"
            raise InputError(msg, source)
        _validate_coop(self.coop, source)
        return self


def _validate_coop(c: CoopConfig, source: str) -> None:
    """Ranges of the ``[coop]`` leaves (choices and types are checked with the others)."""
    for key in ("sigma_pos_m_s", "sigma_clk_m_s", "sigma_set_floor_m", "sigma_wset_floor_m_s",
                "max_broadcast_age_s", "sigma_set_m", "sigma_wset_m_s"):  # fmt: skip
        v = getattr(c, key)
        if v is not None and not (0 < v < float("inf")):
            raise InputError(f"{key}: expected a finite positive number, got {v!r}", source)
    if not 0.0 <= c.init_floor_m < float("inf"):
        raise InputError(f"init_floor_m: expected a finite number >= 0, got {c.init_floor_m!r}", source)
    if not 0.0 <= c.ess_threshold <= 1.0:
        raise InputError(f"ess_threshold: expected a fraction in [0, 1], got {c.ess_threshold!r}", source)
    if not 0.0 <= c.roughening < float("inf"):
        raise InputError(f"roughening: expected a finite number >= 0, got {c.roughening!r}", source)
    if c.n_particles < 2:
        raise InputError(f"n_particles: expected an integer >= 2, got {c.n_particles}", source)
    if c.window < 2:
        raise InputError(f"window: expected an integer >= 2, got {c.window}", source)


#: Accepted range of every standard deviation setting (in its own unit).
SIGMA_RANGE = (1e-6, 1e6)


@dataclass(frozen=True)
class Leaf:
    """One configuration leaf: where it lives and what it accepts."""

    key: str
    section: str | None
    attr: str
    type: Any
    default: Any
    help: str
    modes: tuple[str, ...]
    choices: tuple[str, ...]
    flag_name: str | None = None
    flag_value: str | None = None

    @property
    def flag(self) -> str:
        """The command-line flag (``--code-sigma`` for ``code_sigma_m``)."""
        if self.flag_name is not None:
            return self.flag_name
        name = self.key
        for unit in ("_m2_s3", "_m2_s", "_m_s2", "_m_s", "_m2", "_dbhz", "_deg", "_cyc", "_m"):
            if name.endswith(unit):
                name = name[: -len(unit)]
                break
        return "--" + name.replace("_", "-")

    @property
    def base_type(self) -> type:
        """``bool``, ``int``, ``float`` or ``str`` (optional and Literal types unwrapped)."""
        return _base_type(self.type)

    @property
    def optional(self) -> bool:
        t = self.type
        return (get_origin(t) in (typing.Union, types.UnionType)) and type(None) in get_args(t)


def _base_type(t: Any) -> type:
    origin = get_origin(t)
    if origin is Literal:
        return type(get_args(t)[0])
    if origin in (typing.Union, types.UnionType):
        args = [a for a in get_args(t) if a is not type(None)]
        return _base_type(args[0])
    return t


def _choices(t: Any) -> tuple[str, ...]:
    origin = get_origin(t)
    if origin is Literal:
        return tuple(get_args(t))
    if origin in (typing.Union, types.UnionType):
        for a in get_args(t):
            if get_origin(a) is Literal:
                return tuple(get_args(a))
    return ()


def _check_type(key: str, leaf: Leaf, val: Any, source: str) -> None:
    if val is None:
        if leaf.optional:
            return
        raise InputError(f"{key}: a value is required", source)
    want = leaf.base_type
    ok = isinstance(val, want) and not (want is not bool and isinstance(val, bool))
    if want is float and isinstance(val, int) and not isinstance(val, bool):
        ok = True
    if not ok:
        raise InputError(f"{key}: expected {want.__name__}, got {val!r}", source)


def field_types(cls: type) -> dict[str, Any]:
    """The annotations of a class of the tree, evaluated: :func:`typing.get_type_hints`'s
    dictionary (each string evaluated in the namespace of the class's module), with each
    distinct string evaluated once, where ``get_type_hints`` compiles every one of them
    (125 compilations, about 2 % of a short solve's instructions). A class with bases
    other than ``object`` goes to ``get_type_hints``."""
    if cls.__mro__[1:] != (object,):
        return typing.get_type_hints(cls)
    # get_type_hints's name lookup: the module's names, then the class's, then builtins
    module, own = vars(sys.modules[cls.__module__]), dict(vars(cls))
    seen: dict[str, Any] = {}
    out: dict[str, Any] = {}
    for name, ann in cls.__dict__.get("__annotations__", {}).items():
        if isinstance(ann, str):
            if ann not in seen:
                seen[ann] = eval(ann, own, module)  # noqa: S307  # the class's own annotation
            ann = seen[ann]
        out[name] = type(None) if ann is None else ann
    return out


def _collect() -> dict[str, Leaf]:
    hints = field_types(Config)
    out: dict[str, Leaf] = {}

    def add(f: Field[Any], section: str | None, t: Any) -> None:
        key = f.metadata.get("key", f.name)
        if key in out:
            raise RuntimeError(f"config key {key!r} defined twice")
        out[key] = Leaf(key, section, f.name, t, f.default, f.metadata["help"], tuple(f.metadata["modes"]),
                        _choices(t), f.metadata.get("flag"), f.metadata.get("flag_value"))  # fmt: skip

    for f in fields(Config):
        t = hints[f.name]
        if isinstance(t, type) and is_dataclass(t):
            sub = field_types(t)
            for g in fields(t):
                assert g.default is not MISSING
                add(g, f.name, sub[g.name])
        else:
            add(f, None, t)
    return out


#: Every leaf of the tree by flat key, in tree order.
LEAVES: dict[str, Leaf] = _collect()
#: Section names of the tree.
SECTIONS: tuple[str, ...] = tuple(f.name for f in fields(Config) if f.name != "mode")

_PSEUDOLITE_DPL = Config()
_PSEUDOLITE_RTK = Config.of(mode="rtk")
_GNSS_SPP = Config.of(
    mode="spp", filter="lsq", robust="postfit", code_sigma_m=3.0, phase_sigma_m=0.05, sigma_acc_m_s2=3.0,
    tropo="saastamoinen", weighting="elevation",
    # phone code carries NLOS biases shared by several satellites, so the measurement-only
    # fit is at times tens of metres off: only the paper's single pass (algorithms.md §23)
    adaptive_max_iter=1,
)  # fmt: skip
_GNSS_DGNSS = Config.of(
    mode="dgnss", filter="ekf", weighting="elevation", code_sigma_m=0.3, init_sigma_m=10.0, known_point=False,
    # the receivers' own code σ where the configured one would have the robust test reject
    # rows at one σ of the data (patch antennas); geodetic receivers' code minus carrier
    # (0.4-0.5 m) stays under that and keeps the configured σ (algorithms.md §39)
    code_sigma_from_data=True,
    # a receiver may move: averaged while it stands still, constant velocity with a car's
    # accelerations while the innovations say it moves
    dynamics="auto", kinematic_model="constant-velocity", sigma_acc_m_s2=3.0, init_sigma_vel_m_s=10.0,
    # post-fit test (one row at a time): rejects gross code errors that a kinematic prior
    # leaves only moderately visible; a faulty reference is handled by the engine's check
    robust="postfit",
)  # fmt: skip
_GNSS_RTK = Config.of(
    mode="rtk", filter="ekf", robust="prefit+postfit", weighting="elevation", code_sigma_m=0.3,
    phase_sigma_m=0.003, dynamics="kinematic", kinematic_model="constant-velocity", sigma_acc_m_s2=3.0,
    init_sigma_m=10.0, init_sigma_vel_m_s=10.0, known_point=False, rtk_use_code=True, ar="par-sr", hold=True,
    hold_min_fix=5,
    # a soft hold: a tight one, repeated every epoch, shrinks the ambiguity variances to
    # nothing and pushes every unmodelled error into the position (vertical noise)
    hold_sigma_cyc=0.3, ratio=3.0, par_min=4, slip="lli+gf+doppler", tropo="saastamoinen",
    ar_lock_epochs=3, ar_elev_mask_deg=15.0, amb_init_sigma_cyc=30.0, fix_max_sigma_m=0.05,
)  # fmt: skip

#: Mode presets by ``(input kind, mode)``: what a solve starts from before TOML and flags.
PRESETS: dict[tuple[str, str], Config] = {
    ("pseudolite", "dpl"): _PSEUDOLITE_DPL,
    ("pseudolite", "rtk"): _PSEUDOLITE_RTK,
    ("gnss", "spp"): _GNSS_SPP,
    ("gnss", "dgnss"): _GNSS_DGNSS,
    ("gnss", "rtk"): _GNSS_RTK,
}


#: What ``robustrtk coop`` starts from before TOML and flags: the ``[coop]`` section and
#: the shared leaves it reads, set for GNSS code (eq. 25 variance with a 3 m zenith σ).
COOP_PRESET: Config = Config.of(
    code_sigma_m=3.0, elev_mask_deg=10.0, tropo="saastamoinen", iono="klobuchar", systems="GECJ",
)  # fmt: skip
#: The Zhou et al. (2018) study (``experiment zhou2018``, algorithms.md §25): simulated
#: corrected pseudoranges of two static nodes, a steadier clock, fewer particles.
ZHOU2018_PRESET: Config = COOP_PRESET.updated(sigma_clk_m_s=10.0, n_particles=2000)

#: White-jerk σ (m/s^2.5) of the profiles that carry a moving DGNSS rover by its Doppler
#: (algorithms.md §44): ordinary driving changes its acceleration by about 1 m/s² per second.
DOPPLER_CARRY_JERK = 1.0

#: Receiver profiles: flat settings applied over a mode's preset (``solve --profile``),
#: by ``(input kind, mode)``. ``phone``: smartphone observations (docs/phone_profile.md) —
#: the signals phones track (L1/E1/B1I + L5/E5a/B2a), each measurement weighted by the σ
#: the phone reports or, where it reports none, by its C/N0 (algorithms.md § 24), with a
#: phone's code σ at 45 dB-Hz; in DGNSS a moving rover carried by its Doppler (metres of code
#: noise average over many epochs, algorithms.md §44). ``lowcost``: patch-antenna receivers
#: (u-blox and the like) — the code σ from the receivers' own code minus carrier (metres of
#: multipath a geodetic σ would hide: algorithms.md §29; DGNSS by the rule of §39, which its
#: preset now applies too), and in DGNSS the Doppler carry as for phones. Both keep the TDCP
#: carry of DGNSS off (§45: on galway s3 it measured worse than their Doppler carry).
PROFILES: dict[str, dict[tuple[str, str], dict[str, Any]]] = {
    "lowcost": {
        ("gnss", "dgnss"): {
            "code_sigma_from_data": True,
            "dgnss_doppler_jerk_m_s3": DOPPLER_CARRY_JERK,
            "dgnss_tdcp_carry": False,
        },
        ("gnss", "rtk"): {"code_sigma_from_data": True},
    },
    "phone": {
        ("gnss", "rtk"): {
            "freqs": "L1+L5",
            "weighting": "reported",
            "code_sigma_m": 1.0,
            "fix_confirm_epochs": 3,
            "ar": "par-sr+par",
            "gf_window_s": 10.0,
        },
        ("gnss", "dgnss"): {
            "freqs": "L1+L5",
            "weighting": "reported",
            "code_sigma_m": 1.0,
            "dgnss_doppler_jerk_m_s3": DOPPLER_CARRY_JERK,
            "dgnss_tdcp_carry": False,
        },
    },
}


def profiled(cfg: Config, name: str | None, kind: str = "gnss") -> Config:
    """``cfg`` with the settings of profile ``name`` (:data:`PROFILES`) for its mode.

    Raises
    ------
    InputError
        Unknown profile, or one that has no settings for this input kind and mode.
    """
    if name is None:
        return cfg
    if name not in PROFILES:
        raise InputError(f"--profile: unknown profile {name!r}; expected one of {', '.join(PROFILES)}")
    over = PROFILES[name].get((kind, cfg.mode))
    if over is None:
        where = ", ".join(f"{m} ({k})" for k, m in PROFILES[name])
        raise InputError(
            f"--profile: profile {name} does not apply to mode {cfg.mode} ({kind}); it acts in {where}"
        )
    return cfg.updated(**over).validate(f"profile {name}")


def preset(mode: str, kind: str = "gnss") -> Config:
    """The preset of ``mode`` for ``kind`` input (``"pseudolite"`` or ``"gnss"``)."""
    try:
        return PRESETS[(kind, mode)]
    except KeyError:
        modes = sorted(m for k, m in PRESETS if k == kind)
        raise InputError(f"mode: {kind} input takes {', '.join(modes)}, got {mode!r}") from None


def check_applies(keys: typing.Iterable[str], mode: str, source: str = "command line") -> None:
    """Refuse any key among ``keys`` that does not act in ``mode``."""
    for key in keys:
        leaf = LEAVES[key]
        if mode not in leaf.modes:
            raise InputError(
                f"{leaf.flag if source == 'command line' else key}: does not apply to mode {mode} "
                f"(it acts in {', '.join(leaf.modes)})",
                source,
            )


def read_config_dict(path: str | Path) -> dict[str, Any]:
    """The settings of a TOML file as a flat mapping ``key -> value`` (checked).

    Keys may be at top level (``ratio = 2.0``) or in their section's table
    (``[ar] ratio = 2.0``); a table must be a section of the tree and hold only its own keys.
    """
    p = Path(path)
    try:
        text = p.read_bytes().decode("utf-8")
    except FileNotFoundError:
        raise InputError("file not found", str(p)) from None
    except IsADirectoryError:
        raise InputError("expected a TOML file, got a directory", str(p)) from None
    except UnicodeDecodeError as exc:
        raise InputError(f"not UTF-8 text (byte {exc.start})", str(p)) from None
    import tomllib  # here, not at start-up

    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"invalid TOML: {exc}", str(p)) from None
    return flatten_config_dict(data, str(p))


def flatten_config_dict(data: dict[str, Any], source: str = "config") -> dict[str, Any]:
    """A nested or flat mapping as flat ``key -> value``, naming unknown keys."""
    flat: dict[str, Any] = {}
    for key, val in data.items():
        if key in SECTIONS and isinstance(val, dict):
            for sub, v in val.items():
                leaf = LEAVES.get(sub)
                if leaf is None or leaf.section != key:
                    own = sorted(k for k, lf in LEAVES.items() if lf.section == key)
                    raise InputError(
                        f"[{key}] {sub!r}: unknown key; expected one of {', '.join(own)}", source
                    )
                flat[sub] = v
            continue
        if key not in LEAVES:
            raise InputError(f"unknown key {key!r}; expected one of {', '.join(sorted(LEAVES))}", source)
        flat[key] = val
    for key, val in flat.items():
        leaf = LEAVES[key]
        _check_type(key, leaf, val, source)
        if leaf.base_type is float and isinstance(val, int):
            flat[key] = float(val)
    return flat


def config_from_dict(data: dict[str, Any], source: str = "config", base: Config | None = None) -> Config:
    """A validated :class:`Config`: ``base`` (default tree) with the mapping applied."""
    return (base or Config()).updated(**flatten_config_dict(data, source)).validate(source)


def load_config(path: str | Path, base: Config | None = None) -> Config:
    """Read a TOML config file over ``base`` (default tree)."""
    return (base or Config()).updated(**read_config_dict(path)).validate(str(path))


__all__ = [
    "COOP_PRESET", "DD_MODES", "LEAVES", "MODES", "PRESETS", "PROFILES", "SECTIONS", "SLIP_DETECTORS",
    "ZHOU2018_PRESET", "ArConfig", "Config", "CoopConfig",
    "profiled",
    "EstimatorConfig", "GnssConfig", "Leaf", "MeasurementConfig", "ReceiversConfig", "RobustConfig",
    "SlipConfig", "SppSection", "check_applies", "config_from_dict", "flatten_config_dict", "load_config",
    "preset", "read_config_dict",
]  # fmt: skip
