"""Solver configuration: a frozen dataclass, loaded from TOML, overridden by CLI flags.

Every field has a documented default (see ``docs/configuration.md``). A TOML config file
holds the same keys at top level (``filter = "ukf"``, ``robust = "igg3"``, ...); unknown
keys and wrong types are rejected with the file and key named.
"""

from __future__ import annotations

import tomllib
from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path
from typing import Any

from robustrtk.core import InputError
from robustrtk.estimation.robust import POLICY_NAMES
from robustrtk.measurement.weighting import WEIGHTINGS

_CHOICES: dict[str, tuple[str, ...]] = {
    "mode": ("dpl", "rtk"),
    "filter": ("ukf", "ekf"),
    "robust": POLICY_NAMES,
    "dynamics": ("static", "kinematic"),
    "kinematic_model": ("auto", "random-walk", "constant-velocity"),
    "weighting": WEIGHTINGS,
    "ar": ("off", "lambda", "par", "par-sr"),
    "tropo": ("off", "saastamoinen"),
}

#: Cycle-slip detectors that ``slip`` may combine with ``+`` (or ``"none"``).
SLIP_DETECTORS: tuple[str, ...] = ("lli", "poly", "gf", "doppler")


@dataclass(frozen=True)
class Config:
    """All solver settings.

    Attributes
    ----------
    mode : {"dpl", "rtk"}
        DD code positioning or DD carrier-phase RTK.
    filter : {"ukf", "ekf"}
    robust : str
        Robust policy (``none``, ``igg3`` = Li et al. Δv̄ rule, ``igg3-std``, ``huber``,
        ``prefit``, ``postfit``, ``prefit+postfit``).
    k0, k1 : float or None
        IGG-III thresholds (None = the policy's default: 2 and 8 for ``igg3``).
    dynamics : {"static", "kinematic"}
    kinematic_model : {"auto", "random-walk", "constant-velocity"}
        ``auto``: random walk for DPL (code noise dominates any dynamic prior) and
        constant velocity for RTK (a tight dynamic prior gives the phase DDs the
        redundancy the robust filter needs to single out a faulty DD).
    q_static_m2_s : float
        Position process noise of the static model (m²/s).
    sigma_vel_m_s : float
        Random-walk velocity noise (m/s): position diffuses by ~σ·√dt per epoch.
    sigma_acc_m_s2 : float
        Constant-velocity model acceleration noise (m/s²).
    init_sigma_m : float
        Standard deviation of the initial position about the known point (m).
    init_sigma_vel_m_s : float
        Initial velocity standard deviation (constant-velocity model).
    code_sigma_m, phase_sigma_m : float
        Undifferenced code and phase noise (m).
    weighting : {"equal", "elevation", "distance", "snr"}
    reference : str or None
        Reference transmitter (overrides the site file; None = site file, else automatic).
    ukf_alpha, ukf_beta, ukf_kappa : float
        Sigma-point parameters.
    base, rover : str
        Receiver names in the observation table.
    ar : {"off", "lambda", "par", "par-sr"}
        Ambiguity resolution: none, full-set LAMBDA, PAR ranked by Δv̄ (Li et al.), PAR by
        bootstrapped success rate.
    hold : bool
        Fix-and-hold: constrain the filter to validated integers.
    instantaneous : bool
        Single-epoch AR: ambiguities re-initialised from the current epoch every epoch.
    ratio : float
        Ratio-test threshold.
    par_min : int
        Smallest subset PAR may fix.
    min_success_rate : float
        A validated subset is used only if its bootstrapped success rate reaches this
        value (the ratio test alone accepts wrong sets from weak float solutions).
    rtk_use_code : bool
        Add DD code rows to RTK updates.
    amb_init_sigma_cyc : float
        Initial ambiguity standard deviation when not initialised from a known point.
    known_point : bool
        Known-point initialization (KPI): the rover starts on its known initial position
        (σ = ``init_sigma_m``), which pins the float ambiguities at once. False: the
        initial position is approximate (σ ≥ 1 m) and RTK adds DD code rows, so the float
        ambiguities converge from code.
    slip : str
        Cycle-slip detection: ``"none"`` or detectors joined by ``+`` among ``lli``
        (loss-of-lock flags), ``poly`` (polynomial fit of each DD phase series), ``gf``
        (geometry-free combination, two frequencies), ``doppler`` (Doppler-minus-phase).
    hold_sigma_cyc : float
        Standard deviation of the fix-and-hold pseudo-observation (cycles).
    hold_min_fix : int
        Consecutive validated fixes needed before fix-and-hold constrains the filter.
    tropo : {"off", "saastamoinen"}
        Tropospheric model applied to each receiver's ranges (satellites; the DD removes
        most of it, the height difference between receivers does not cancel).
    snr_mask_dbhz : float
        Observations with a C/N0 below this (dB-Hz) at either receiver are left out
        (0 = off).
    ar_elev_mask_deg : float
        Ambiguities of transmitters below this elevation stay float (0 = off).
    ar_lock_epochs : int
        An ambiguity joins integer resolution only after this many epochs of continuous
        tracking (0 = at once).
    fix_max_sigma_m : float
        A validated fix is reported as ``fixed``/``partial`` only when the fixed
        position's standard deviation (square root of the covariance trace) is at most
        this (m); weaker fixes (e.g. very poor geometry) are reported ``float`` while the
        filter still uses and holds them (0 = no gate).
    gf_threshold_m : float
        Geometry-free slip threshold (m per epoch).
    doppler_threshold_cyc : float
        Doppler-minus-phase slip threshold (cycles).
    """

    mode: str = "dpl"
    filter: str = "ukf"
    robust: str = "igg3"
    k0: float | None = None
    k1: float | None = None
    dynamics: str = "static"
    kinematic_model: str = "auto"
    q_static_m2_s: float = 1e-8
    sigma_vel_m_s: float = 0.1
    sigma_acc_m_s2: float = 0.01
    init_sigma_m: float = 0.1
    init_sigma_vel_m_s: float = 0.1
    code_sigma_m: float = 0.25
    phase_sigma_m: float = 0.003
    weighting: str = "equal"
    reference: str | None = None
    ukf_alpha: float = 1.0
    ukf_beta: float = 2.0
    ukf_kappa: float = 0.0
    base: str = "base"
    rover: str = "rover"
    ar: str = "par"
    hold: bool = True
    instantaneous: bool = False
    ratio: float = 3.0
    par_min: int = 3
    min_success_rate: float = 0.0
    rtk_use_code: bool = False
    amb_init_sigma_cyc: float = 30.0
    known_point: bool = True
    slip: str = "lli+poly"
    hold_sigma_cyc: float = 0.01
    hold_min_fix: int = 0
    tropo: str = "off"
    snr_mask_dbhz: float = 0.0
    ar_elev_mask_deg: float = 0.0
    ar_lock_epochs: int = 0
    fix_max_sigma_m: float = 0.0
    gf_threshold_m: float = 0.05
    doppler_threshold_cyc: float = 0.5

    def validate(self, source: str = "config") -> Config:
        """Check choices and ranges; raise :class:`InputError` naming the field."""
        for name, allowed in _CHOICES.items():
            val = getattr(self, name)
            if val not in allowed:
                raise InputError(f"{name}: expected one of {', '.join(allowed)}, got {val!r}", source)
        positive = (
            "init_sigma_m",
            "code_sigma_m",
            "phase_sigma_m",
            "ratio",
            "sigma_vel_m_s",
            "sigma_acc_m_s2",
            "amb_init_sigma_cyc",
            "hold_sigma_cyc",
            "ukf_alpha",
        )
        for name in positive:
            if not getattr(self, name) > 0:
                raise InputError(f"{name}: expected a positive number, got {getattr(self, name)!r}", source)
        if self.k0 is not None and self.k1 is not None and not 0 < self.k0 < self.k1:
            raise InputError(f"k0, k1: expected 0 < k0 < k1, got {self.k0}, {self.k1}", source)
        tokens = self.slip.split("+")
        if self.slip != "none" and (not tokens or any(t not in SLIP_DETECTORS for t in tokens)):
            raise InputError(
                f"slip: expected 'none' or detectors joined by '+' among {', '.join(SLIP_DETECTORS)}, "
                f"got {self.slip!r}",
                source,
            )
        for name in ("hold_min_fix", "ar_lock_epochs"):
            if getattr(self, name) < 0:
                raise InputError(f"{name}: expected an integer >= 0, got {getattr(self, name)}", source)
        if self.par_min < 1:
            raise InputError(f"par_min: expected an integer >= 1, got {self.par_min}", source)
        return self

    def slip_detectors(self) -> frozenset[str]:
        """The enabled cycle-slip detectors (empty for ``"none"``)."""
        return frozenset() if self.slip == "none" else frozenset(self.slip.split("+"))

    def updated(self, **overrides: Any) -> Config:
        """A copy with the non-None ``overrides`` applied (CLI flags win over the file)."""
        kw = {k: v for k, v in overrides.items() if v is not None}
        return replace(self, **kw)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


_TYPES: dict[str, tuple[type, ...]] = {}
for _f in fields(Config):
    t = str(_f.type)
    if "bool" in t:
        _TYPES[_f.name] = (bool,)
    elif "float" in t:
        _TYPES[_f.name] = (float, int)
    elif "int" in t:
        _TYPES[_f.name] = (int,)
    else:
        _TYPES[_f.name] = (str,)


def read_config_dict(path: str | Path) -> dict[str, Any]:
    """The validated keys of a TOML config file as a mapping (for layering over
    mode-specific defaults, e.g. GNSS RTK's)."""
    p = Path(path)
    try:
        data = tomllib.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError("file not found", str(p)) from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"invalid TOML: {exc}", str(p)) from None
    config_from_dict(data, str(p))  # names bad keys and values
    return {k: (float(v) if _TYPES[k][0] is float else v) for k, v in data.items()}


def load_config(path: str | Path) -> Config:
    """Read a TOML config file (top-level keys = :class:`Config` fields)."""
    return config_from_dict(read_config_dict(path), str(path))


def config_from_dict(data: dict[str, Any], source: str = "config") -> Config:
    """Build a validated :class:`Config` from a mapping, naming bad keys."""
    kw: dict[str, Any] = {}
    for key, val in data.items():
        if key not in _TYPES:
            raise InputError(f"unknown key {key!r}; expected one of {', '.join(sorted(_TYPES))}", source)
        allowed = _TYPES[key]
        if isinstance(val, bool) and bool not in allowed:
            raise InputError(f"{key}: expected {allowed[0].__name__}, got {val!r}", source)
        if not isinstance(val, allowed):
            raise InputError(f"{key}: expected {allowed[0].__name__}, got {val!r}", source)
        kw[key] = float(val) if allowed[0] is float else val  # type: ignore[arg-type]
    return Config(**kw).validate(source)
