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
"""

from __future__ import annotations

import types
import typing
from dataclasses import MISSING, Field, asdict, dataclass, field, fields, is_dataclass, replace
from pathlib import Path
from typing import Any, Literal, get_args, get_origin

from robustrtk.errors import InputError

Mode = Literal["dpl", "rtk", "spp", "dgnss"]
InputKind = Literal["pseudolite", "gnss"]
FilterName = Literal["ukf", "ekf", "lsq"]
PolicyName = Literal["none", "igg3", "igg3-std", "huber", "prefit", "postfit", "prefit+postfit"]
Weighting = Literal["equal", "elevation", "distance", "snr", "reported"]
ArMethod = Literal["off", "lambda", "par", "par-sr", "par-sr+par"]
ArScheme = Literal["filter", "prior"]
PriorAmbiguities = Literal["carry", "reestimate"]
PriorCovariance = Literal["reset", "add"]
Dynamics = Literal["static", "kinematic", "auto"]
GlonassAr = Literal["auto", "on", "off"]
Adaptive = Literal["off", "innovation", "state"]
KinematicModel = Literal["auto", "random-walk", "constant-velocity"]
Tropo = Literal["off", "saastamoinen"]
Iono = Literal["off", "klobuchar"]
BasePosition = Literal["fixed", "trajectory", "moving"]
DopplerWeighting = Literal["elevation", "cn0"]
CoopFilter = Literal["ekf", "ukf", "pf", "ls"]
Cooperation = Literal["improved", "traditional", "off"]

#: Every mode.
MODES: tuple[str, ...] = get_args(Mode)
#: Modes that run the double-difference engine.
DD_MODES: tuple[str, ...] = ("dpl", "rtk", "dgnss")
#: Cycle-slip detectors that ``slip`` may combine with ``+`` (or ``"none"``).
SLIP_DETECTORS: tuple[str, ...] = ("lli", "poly", "gf", "doppler")

_ALL = MODES
_DD = DD_MODES
_RTK = ("rtk",)
_SPP = ("spp",)
_GNSS = ("spp", "dgnss", "rtk")
#: The cooperative run (``robustrtk coop``, ``experiment zhou2018``): not a ``solve`` mode.
_COOP = ("coop",)


def _leaf(
    default: Any,
    help: str,
    modes: tuple[str, ...] = _ALL,
    key: str | None = None,
    flag: str | None = None,
    flag_value: str | None = None,
) -> Any:
    """A config leaf: default, one-line help, the modes it acts in, optional public key and
    command-line flag (when the derived one would clash with another option), and for a
    choice the value its flag takes when given without one (``--adaptive`` = ``state``)."""
    meta: dict[str, Any] = {"help": help, "modes": modes}
    if flag_value is not None:
        meta["flag_value"] = flag_value
    if key is not None:
        meta["key"] = key
    if flag is not None:
        meta["flag"] = flag
    return field(default=default, metadata=meta)


@dataclass(frozen=True)
class EstimatorConfig:
    """Filter, dynamics and initialisation."""

    filter: FilterName = _leaf(
        "ukf", "filter: ukf or ekf (DD modes, Kalman SPP); lsq = epoch-wise least squares (SPP)", key="filter"
    )
    ukf_alpha: float = _leaf(1.0, "UKF sigma-point spread α", _ALL)
    ukf_beta: float = _leaf(2.0, "UKF prior-knowledge parameter β", _ALL)
    ukf_kappa: float = _leaf(0.0, "UKF secondary scaling κ", _ALL)
    dynamics: Dynamics = _leaf(
        "static",
        "receiver dynamics: static, kinematic, or auto (stationary unless the innovations say it moves)",
        _DD,
    )
    kinematic_model: KinematicModel = _leaf(
        "auto",
        "kinematic process model; auto = random walk for code-only DD, constant velocity for RTK",
        _DD,
    )
    q_static_m2_s: float = _leaf(1e-8, "position process noise of the static model (m²/s)", _DD)
    sigma_vel_m_s: float = _leaf(0.1, "random-walk velocity noise (m/s)", _DD)
    sigma_acc_m_s2: float = _leaf(
        0.01, "constant-velocity acceleration noise, horizontal for the Kalman SPP (m/s²)", _ALL
    )
    init_sigma_m: float = _leaf(0.1, "initial position σ about the starting point (m)", _DD)
    init_sigma_vel_m_s: float = _leaf(0.1, "initial velocity σ (m/s)", _DD)
    known_point: bool = _leaf(
        True, "known-point initialisation: the rover starts on a known position (σ = init_sigma_m)", _DD
    )
    reinit_epochs: int = _leaf(
        5,
        "epochs in a row with every row rejected (DD) or far from least squares (SPP) before "
        "the filter restarts from a single-epoch solution (0 = never)",
        _ALL,
    )
    smoother: bool = _leaf(
        False,
        "forward-backward (RTS) smoothing (post-processing): Kalman SPP, DPL and DGNSS",
        ("spp", "dpl", "dgnss"),
    )
    adaptive: Adaptive = _leaf(
        "off",
        "adaptive factor of the filter update: off, state (Yang's factor from the predicted-state "
        "discrepancy, the smartphone paper's; --adaptive alone), or innovation (from the median "
        "standardized innovation)",
        ("spp", "dpl", "dgnss", "rtk"),
        flag_value="state",
    )
    adaptive_c0: float | None = _leaf(
        None,
        "adaptive factor: no inflation up to this discrepancy (None = the factor's own: state 1.0, "
        "innovation 2)",
        ("spp", "dpl", "dgnss", "rtk"),
    )
    adaptive_c1: float | None = _leaf(
        None,
        "adaptive factor: largest inflation beyond this discrepancy (None = state 2.5, innovation 6)",
        ("spp", "dpl", "dgnss", "rtk"),
    )
    adaptive_max_iter: int = _leaf(
        10,
        "passes of the state-discrepancy test, the prior widened until it agrees with the data "
        "(1 = the paper's single pass)",
        ("spp", "dpl", "dgnss", "rtk"),
    )


@dataclass(frozen=True)
class RobustConfig:
    """Robust policy and its IGG-III thresholds."""

    policy: PolicyName = _leaf(
        "igg3",
        "robust policy: none, igg3 (Li et al. Δv̄), igg3-std, huber, prefit, postfit, prefit+postfit",
        _ALL,
        key="robust",
    )
    k0: float | None = _leaf(None, "IGG-III k0 (None = the policy's own default)", _ALL)
    k1: float | None = _leaf(None, "IGG-III k1 (None = the policy's own default)", _ALL)
    prefit_k0: float | None = _leaf(
        None, "pre-fit IGG-III k0 of prefit+postfit, whose k0/k1 are the post-fit test's (None = 2.5)", _ALL
    )
    prefit_k1: float | None = _leaf(None, "pre-fit IGG-III k1 of prefit+postfit (None = 7)", _ALL)


@dataclass(frozen=True)
class MeasurementConfig:
    """Noise, weighting, masks and corrections."""

    code_sigma_m: float = _leaf(0.25, "undifferenced code σ at zenith (m)", _ALL)
    code_sigma_from_data: bool = _leaf(
        True,
        "RINEX RTK: raise code_sigma_m to what the receivers' own code minus carrier shows over 30 s "
        "(patch-antenna multipath), so the float covariance stays honest",
        _RTK,
    )
    phase_sigma_m: float = _leaf(0.003, "undifferenced carrier-phase σ at zenith (m)", ("rtk", "spp"))
    weighting: Weighting = _leaf(
        "equal",
        "DD weighting model: equal, elevation, distance, snr, or reported (the receiver's own σ "
        "per measurement where it gives one, else snr)",
        _DD,
    )
    reference: str | None = _leaf(None, "reference transmitter (None = site file, else automatic)", _DD)
    rtk_use_code: bool = _leaf(False, "add DD code rows to RTK updates", _RTK)
    tropo: Tropo = _leaf("off", "tropospheric model: off or saastamoinen", _ALL)
    iono: Iono = _leaf("klobuchar", "ionospheric model of undifferenced SPP: off or klobuchar", _SPP)
    snr_mask_dbhz: float = _leaf(0.0, "C/N0 mask at either receiver (dB-Hz, 0 = off)", _ALL)


@dataclass(frozen=True)
class ArConfig:
    """Integer ambiguity resolution and hold."""

    method: ArMethod = _leaf(
        "par",
        "ambiguity resolution: off, lambda, par (ranked by Δv̄), par-sr (success rate), par-sr+par "
        "(success rate, then by Δv̄ when that subset fails validation)",
        _RTK,
        key="ar",
    )
    hold: bool = _leaf(True, "fix-and-hold: constrain the filter to validated integers", _RTK)
    instantaneous: bool = _leaf(False, "single-epoch AR (ambiguities re-initialised every epoch)", _RTK)
    scheme: ArScheme = _leaf(
        "filter",
        "AR scheme: filter (the filter's own position covariance, with hold or single-epoch AR), or "
        "prior (known-point initialisation, then each epoch's float solution takes the previous "
        "epoch's coordinate as its prior with σ = prior_sigma_m and AR runs every epoch without hold)",
        _RTK,
        key="ar_scheme",
    )
    prior_sigma_m: float = _leaf(
        0.1, "σ of the previous epoch's coordinate as the prior of the next float solution (m)", _RTK
    )
    prior_ambiguities: PriorAmbiguities = _leaf(
        "carry",
        "ambiguities of the prior scheme: carry (float estimates kept from epoch to epoch) or "
        "reestimate (new ambiguities every epoch)",
        _RTK,
    )
    prior_covariance: PriorCovariance = _leaf(
        "reset",
        "position covariance of the prior scheme's next prior: reset (σ² I, uncorrelated with the "
        "ambiguities) or add (σ² I added to the posterior's, correlations kept)",
        _RTK,
    )
    ratio: float = _leaf(3.0, "ratio-test threshold", _RTK)
    par_min: int = _leaf(3, "smallest subset PAR may fix", _RTK)
    min_success_rate: float = _leaf(0.0, "bootstrapped success rate a validated subset must reach", _RTK)
    amb_init_sigma_cyc: float = _leaf(30.0, "initial ambiguity σ without known point (cycles)", _RTK)
    hold_sigma_cyc: float = _leaf(0.01, "σ of the fix-and-hold pseudo-observation (cycles)", _RTK)
    hold_min_fix: int = _leaf(0, "consecutive validated fixes before hold constrains the filter", _RTK)
    fix_residual_k: float = _leaf(
        0.0,
        "a validated subset is accepted only when each fixed DD phase residual is within this many "
        "nominal σ (0 = off; RTKLIB uses 4)",
        _RTK,
    )
    ar_elev_mask_deg: float = _leaf(0.0, "ambiguities below this elevation stay float (deg, 0 = off)", _RTK)
    ar_lock_epochs: int = _leaf(0, "epochs of continuous lock before an ambiguity joins AR", _RTK)
    fix_confirm_epochs: int = _leaf(
        0,
        "a fix is reported only after this many consecutive validated epochs with agreeing "
        "integers (0 = at once)",
        _RTK,
    )
    fix_max_sigma_m: float = _leaf(
        0.0, "a fix is reported fixed only when the fixed position σ is at most this (m, 0 = off)", _RTK
    )


@dataclass(frozen=True)
class SlipConfig:
    """Cycle-slip detection."""

    detectors: str = _leaf(
        "lli+poly", "slip detectors joined by + among lli, poly, gf, doppler; or none", _RTK, key="slip"
    )
    gf_threshold_m: float = _leaf(0.05, "geometry-free slip threshold (m per epoch)", _RTK)
    gf_window_s: float = _leaf(
        0.0,
        "window of the geometry-free drift test (phase-code inconsistency of one frequency; s, 0 = off)",
        _RTK,
    )
    gf_window_threshold_m: float = _leaf(
        0.1, "geometry-free change over the window that flags a drift (m)", _RTK
    )
    doppler_threshold_cyc: float = _leaf(0.5, "Doppler-minus-phase slip threshold (cycles)", _RTK)


@dataclass(frozen=True)
class GnssConfig:
    """Satellite selection for RINEX and phone input."""

    elev_mask_deg: float = _leaf(15.0, "elevation mask (deg)", _GNSS)
    systems: str | None = _leaf(None, "system letters to use, e.g. GEJ (None = the mode's default)", _GNSS)
    freqs: str = _leaf("L1+L2", "frequency slots of DGNSS and RTK, e.g. L1+L2+L5", ("dgnss", "rtk"))
    glonass_ar: GlonassAr = _leaf(
        "auto",
        "GLONASS (FDMA) ambiguity fixing when R is among the RTK systems: on (the receivers' inter-channel "
        "biases cancel: same make), off (float only) or auto (on when both receivers are the same make)",
        _RTK,
    )
    max_age_s: float = _leaf(
        30.0,
        "largest age of differential (s): a rover epoch without a base epoch at its time uses the latest "
        "base epoch at most this old, carried to its time (RINEX; 0 = same epochs only)",
        ("dgnss", "rtk"),
    )
    sigma_age_m_s: float = _leaf(
        5e-12 * 299_792_458.0,
        "growth of the base observations' σ per second of age (m/s; RTKLIB's clock-stability term, c·5e-12)",
        ("dgnss", "rtk"),
    )
    time_start: str | None = _leaf(
        None,
        "first rover epoch solved: GPST 'yyyy/mm/dd hh:mm:ss' or 'hh:mm:ss' on the first epoch's date "
        "(None = from the first)",
        _GNSS,
    )
    time_end: str | None = _leaf(
        None,
        "last rover epoch solved, as time_start; a time of day falls on time_start's date when that is a "
        "calendar time (None = to the last)",
        _GNSS,
    )
    interval_s: float = _leaf(
        0.0, "solve only the rover epochs on this grid of GPS time of week (s; 0 = every epoch)", _GNSS
    )


@dataclass(frozen=True)
class SppSection:
    """Settings specific to single point positioning (undifferenced)."""

    cn0_ref_dbhz: float = _leaf(45.0, "C/N0 above which no C/N0 down-weighting applies (dB-Hz)", _SPP)
    use_cn0: bool = _leaf(True, "C/N0 term in the least-squares variance model", _SPP)
    kalman_use_cn0: bool = _leaf(False, "C/N0 term in the Kalman SPP variance model", _SPP)
    raim: bool = _leaf(True, "fault detection and exclusion in least squares", _SPP)
    raim_alpha: float = _leaf(1e-3, "false-alarm probability of the FDE chi-square test", _SPP)
    max_exclusions: int = _leaf(6, "most observations FDE may exclude per epoch", _SPP)
    max_iter: int = _leaf(10, "Gauss-Newton iterations", _SPP)
    sigma_acc_up_m_s2: float = _leaf(0.5, "vertical acceleration noise of the Kalman SPP (m/s²)", _SPP)
    q_clk_m2_s: float = _leaf(1000.0, "receiver code-clock noise density (m²/s)", _SPP)
    q_drift_m2_s3: float = _leaf(10.0, "receiver clock-drift noise density (m²/s³)", _SPP)
    q_phase_clk_m2_s: float = _leaf(100.0, "carrier-phase clock noise density (m²/s)", _SPP)
    use_doppler: bool = _leaf(True, "Doppler range-rate rows in the Kalman SPP", _SPP)
    doppler_sigma_m_s: float = _leaf(0.5, "range-rate σ at zenith, elevation weighting (m/s)", _SPP)
    doppler_weighting: DopplerWeighting = _leaf(
        "cn0", "range-rate variance: elevation (σ²/sin²el) or cn0 (frequency-lock-loop noise law)", _SPP
    )
    doppler_cn0_sigma_m_s: float = _leaf(
        0.05, "range-rate σ at cn0_ref_dbhz under the cn0 weighting (m/s)", _SPP
    )
    zupt: bool = _leaf(False, "zero-velocity update when the Doppler velocity says the receiver stands", _SPP)
    zupt_speed_m_s: float = _leaf(0.1, "Doppler speed below which the receiver stands (m/s)", _SPP)
    zupt_sigma_m_s: float = _leaf(0.01, "σ of each zero-velocity pseudo-observation (m/s)", _SPP)
    use_phase: bool = _leaf(True, "carrier-phase rows with one float bias per arc (Kalman SPP)", _SPP)
    q_amb_m2_s: float = _leaf(1e-4, "random walk of the carrier-phase biases (m²/s)", _SPP)
    amb_var0_m2: float = _leaf(1e4, "variance of a new carrier-phase bias (m²)", _SPP)
    lli_reset: bool = _leaf(False, "a loss-of-lock bit starts a new phase arc", _SPP)
    slip_var_m2: float = _leaf(
        0.01, "variance added to a bias whose phase has a loss-of-lock flag (m²)", _SPP
    )
    dual_frequency: bool = _leaf(True, "Kalman SPP also uses the second band", _SPP)
    q_ifb_m2_s: float = _leaf(1e-4, "random walk of the inter-frequency code biases (m²/s)", _SPP)
    clock_reset_m: float = _leaf(
        1000.0, "a per-system median innovation beyond this resets the clock (m)", _SPP
    )
    reinit_m: float = _leaf(
        100.0, "filter vs least-squares disagreement that counts toward re-init (m)", _SPP
    )


@dataclass(frozen=True)
class ReceiversConfig:
    """Receivers: names in pseudolite tables and how the base position is known."""

    base: str = _leaf(
        "base", "base receiver name in the observation table", ("dpl", "rtk"), flag="--base-name"
    )
    rover: str = _leaf(
        "rover", "rover receiver name in the observation table", ("dpl", "rtk"), flag="--rover-name"
    )
    base_position: BasePosition = _leaf(
        "fixed",
        "base position: fixed (surveyed), trajectory (per-epoch file) or moving (its own SPP solution)",
        ("dgnss", "rtk"),
    )


@dataclass(frozen=True)
class CoopConfig:
    """Cooperative positioning (`robustrtk coop`, docs/coop.md), with the shared leaves it reads.

    Shared: ``code_sigma_m``, ``tropo``, ``iono``, ``elev_mask_deg``, ``systems``,
    ``ukf_alpha``, ``ukf_beta``, ``cn0_ref_dbhz``, ``use_cn0`` (their sections' leaves).
    """

    filter: CoopFilter = _leaf(
        "ekf", "each node's filter: ekf, ukf, pf (particle filter) or ls (epoch-wise least squares)", _COOP,
        key="coop_filter",
    )  # fmt: skip
    cooperation: Cooperation = _leaf(
        "improved",
        "improved (range variance inflated by the reset peer covariance, eqs. 24, 29, 30), traditional "
        "(as measured) or off (no ranges)",
        _COOP,
    )
    sigma_pos_m_s: float = _leaf(0.01, "eq. 8 position rate noise σ_ẋ per axis (m/s)", _COOP)
    sigma_clk_m_s: float = _leaf(100.0, "eq. 8 clock rate noise σ_ḃ (m/s)", _COOP)
    n_particles: int = _leaf(10_000, "particle-filter size", _COOP)
    ess_threshold: float = _leaf(0.5, "particle filter: resample below this effective sample fraction", _COOP)
    roughening: float = _leaf(
        0.2, "particle filter: roughening after resampling (fraction of the spread)", _COOP
    )
    seed: int = _leaf(0, "particle-filter seed (node i uses seed + i)", _COOP)
    sigma_set_m: float | None = _leaf(
        None, "σ_set of the covariance reset, eq. 29 (m; None = the short-window estimate)", _COOP
    )
    sigma_wset_m_s: float | None = _leaf(
        None, "σ_wset of the UKF's reset noise block, eq. 30 (m/s; None = the short-window estimate)", _COOP
    )
    window: int = _leaf(10, "peer broadcasts in the short window of the reset estimates (>= 2)", _COOP)
    sigma_set_floor_m: float = _leaf(0.5, "floor of the short-window σ_set (m)", _COOP)
    sigma_wset_floor_m_s: float = _leaf(0.01, "floor of the short-window σ_wset (m/s)", _COOP)
    max_broadcast_age_s: float = _leaf(60.0, "older peer broadcasts are not used (s)", _COOP)
    init_floor_m: float = _leaf(
        1.0, "floor of the initial position σ from the least-squares start (m)", _COOP
    )


@dataclass(frozen=True)
class Config:
    """All solver settings: a mode and one section per concern (see the module docstring)."""

    mode: Mode = _leaf("dpl", "dpl, rtk (pseudolite tables or RINEX), spp, dgnss (RINEX)")
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
                  "max_age_s", "sigma_age_m_s")  # fmt: skip
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


def _collect() -> dict[str, Leaf]:
    hints = typing.get_type_hints(Config)
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
            sub = typing.get_type_hints(t)
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

#: Receiver profiles: flat settings applied over a mode's preset (``solve --profile``),
#: by ``(input kind, mode)``. ``phone``: smartphone observations (docs/phone_profile.md) —
#: the signals phones track (L1/E1/B1I + L5/E5a/B2a), each measurement weighted by the σ
#: the phone reports or, where it reports none, by its C/N0 (algorithms.md § 24), with a
#: phone's code σ at 45 dB-Hz.
PROFILES: dict[str, dict[tuple[str, str], dict[str, Any]]] = {
    "phone": {
        ("gnss", "rtk"): {
            "freqs": "L1+L5",
            "weighting": "reported",
            "code_sigma_m": 1.0,
            "fix_confirm_epochs": 3,
            "ar": "par-sr+par",
            "gf_window_s": 10.0,
        },
        ("gnss", "dgnss"): {"freqs": "L1+L5", "weighting": "reported", "code_sigma_m": 1.0},
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
