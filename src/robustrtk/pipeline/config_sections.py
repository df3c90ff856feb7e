"""The sections of the solver configuration tree (:class:`robustrtk.pipeline.config.Config`).

The choices (``Literal`` types), the mode groups each leaf acts in, the :func:`config_leaf` field
helper and one frozen dataclass per concern: ``estimator``, ``robust``, ``measurement``,
``ar``, ``slip``, ``gnss``, ``spp``, ``receivers`` and ``coop``. The tree itself, its
leaves by flat key, validation, presets and TOML loading are in
:mod:`robustrtk.pipeline.config`, which re-exports every public name of this module.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal, get_args

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


def config_leaf(
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

    filter: FilterName = config_leaf(
        "ukf", "filter: ukf or ekf (DD modes, Kalman SPP); lsq = epoch-wise least squares (SPP)", key="filter"
    )
    ukf_alpha: float = config_leaf(1.0, "UKF sigma-point spread α", _ALL)
    ukf_beta: float = config_leaf(2.0, "UKF prior-knowledge parameter β", _ALL)
    ukf_kappa: float = config_leaf(0.0, "UKF secondary scaling κ", _ALL)
    dynamics: Dynamics = config_leaf(
        "static",
        "receiver dynamics: static, kinematic, or auto (code modes: IMM of stationary, cruising and "
        "manoeuvring models; RTK and smoothed runs: stationary unless the innovations say it moves)",
        _DD,
    )
    kinematic_model: KinematicModel = config_leaf(
        "auto",
        "kinematic process model; auto = random walk for code-only DD, constant velocity for RTK",
        _DD,
    )
    q_static_m2_s: float = config_leaf(1e-8, "position process noise of the static model (m²/s)", _DD)
    sigma_vel_m_s: float = config_leaf(0.1, "random-walk velocity noise (m/s)", _DD)
    sigma_acc_m_s2: float = config_leaf(
        0.01, "constant-velocity acceleration noise, horizontal for the Kalman SPP (m/s²)", _ALL
    )
    init_sigma_m: float = config_leaf(0.1, "initial position σ about the starting point (m)", _DD)
    init_sigma_vel_m_s: float = config_leaf(0.1, "initial velocity σ (m/s)", _DD)
    known_point: bool = config_leaf(
        True, "known-point initialisation: the rover starts on a known position (σ = init_sigma_m)", _DD
    )
    reinit_epochs: int = config_leaf(
        5,
        "epochs in a row with every row rejected (DD) or far from least squares (SPP) before "
        "the filter restarts from a single-epoch solution (0 = never)",
        _ALL,
    )
    smoother: bool = config_leaf(
        False,
        "forward-backward (RTS) smoothing (post-processing): Kalman SPP, DPL and DGNSS",
        ("spp", "dpl", "dgnss"),
    )
    adaptive: Adaptive = config_leaf(
        "off",
        "adaptive factor of the filter update: off, state (Yang's factor from the predicted-state "
        "discrepancy, the smartphone paper's; --adaptive alone), or innovation (from the median "
        "standardized innovation)",
        ("spp", "dpl", "dgnss", "rtk"),
        flag_value="state",
    )
    adaptive_c0: float | None = config_leaf(
        None,
        "adaptive factor: no inflation up to this discrepancy (None = the factor's own: state 1.0, "
        "innovation 2)",
        ("spp", "dpl", "dgnss", "rtk"),
    )
    adaptive_c1: float | None = config_leaf(
        None,
        "adaptive factor: largest inflation beyond this discrepancy (None = state 2.5, innovation 6)",
        ("spp", "dpl", "dgnss", "rtk"),
    )
    adaptive_max_iter: int = config_leaf(
        10,
        "passes of the state-discrepancy test, the prior widened until it agrees with the data "
        "(1 = the paper's single pass)",
        ("spp", "dpl", "dgnss", "rtk"),
    )


@dataclass(frozen=True)
class RobustConfig:
    """Robust policy and its IGG-III thresholds."""

    policy: PolicyName = config_leaf(
        "igg3",
        "robust policy: none, igg3 (Li et al. Δv̄), igg3-std, huber, prefit, postfit, prefit+postfit",
        _ALL,
        key="robust",
    )
    k0: float | None = config_leaf(None, "IGG-III k0 (None = the policy's own default)", _ALL)
    k1: float | None = config_leaf(None, "IGG-III k1 (None = the policy's own default)", _ALL)
    prefit_k0: float | None = config_leaf(
        None, "pre-fit IGG-III k0 of prefit+postfit, whose k0/k1 are the post-fit test's (None = 2.5)", _ALL
    )
    prefit_k1: float | None = config_leaf(None, "pre-fit IGG-III k1 of prefit+postfit (None = 7)", _ALL)


@dataclass(frozen=True)
class MeasurementConfig:
    """Noise, weighting, masks and corrections."""

    code_sigma_m: float = config_leaf(0.25, "undifferenced code σ at zenith (m)", _ALL)
    code_sigma_from_data: bool = config_leaf(
        True,
        "raise code_sigma_m to what the receivers' own code minus carrier shows over 30 s "
        "(patch-antenna multipath), so the covariance stays honest: RINEX RTK whenever it is larger; "
        "DGNSS when it exceeds the robust test's rejection threshold times code_sigma_m",
        ("dgnss", "rtk"),
    )
    phase_sigma_m: float = config_leaf(0.003, "undifferenced carrier-phase σ at zenith (m)", ("rtk", "spp"))
    weighting: Weighting = config_leaf(
        "equal",
        "DD weighting model: equal, elevation, distance, snr, or reported (the receiver's own σ "
        "per measurement where it gives one, else snr)",
        _DD,
    )
    reference: str | None = config_leaf(None, "reference transmitter (None = site file, else automatic)", _DD)
    rtk_use_code: bool = config_leaf(False, "add DD code rows to RTK updates", _RTK)
    tropo: Tropo = config_leaf("off", "tropospheric model: off or saastamoinen", _ALL)
    iono: Iono = config_leaf("klobuchar", "ionospheric model of undifferenced SPP: off or klobuchar", _SPP)
    snr_mask_dbhz: float = config_leaf(0.0, "C/N0 mask at either receiver (dB-Hz, 0 = off)", _ALL)
    dgnss_doppler: bool = config_leaf(
        True,
        "the rover's Doppler velocity (robust single-epoch fit, algorithms.md §44) as a measurement "
        "of the DGNSS filter's velocity, each epoch with enough Doppler rows",
        ("dgnss",),
    )
    dgnss_doppler_jerk_m_s3: float = config_leaf(
        0.0,
        "carry the DGNSS position from epoch to epoch by the Doppler velocities (trapezoid) "
        "instead of the dynamics model, with this white-jerk σ (m/s^2.5, 0 = off: the Doppler "
        "velocity is a measurement of the velocity state)",
        ("dgnss",),
    )
    dgnss_tdcp_carry: bool = config_leaf(
        True,
        "carry a moving DGNSS rover from epoch to epoch by its time-differenced carrier phase "
        "(robust displacement, algorithms.md §45; before the Doppler carry) instead of the "
        "dynamics model",
        ("dgnss",),
    )
    dgnss_doppler_sigma_m_s: float = config_leaf(
        0.05, "range-rate σ of a DGNSS Doppler row at 45 dB-Hz (m/s; C/N0 noise law)", ("dgnss",)
    )


@dataclass(frozen=True)
class ArConfig:
    """Integer ambiguity resolution and hold."""

    method: ArMethod = config_leaf(
        "par",
        "ambiguity resolution: off, lambda, par (ranked by Δv̄), par-sr (success rate), par-sr+par "
        "(success rate, then by Δv̄ when that subset fails validation)",
        _RTK,
        key="ar",
    )
    hold: bool = config_leaf(True, "fix-and-hold: constrain the filter to validated integers", _RTK)
    instantaneous: bool = config_leaf(False, "single-epoch AR (ambiguities re-initialised every epoch)", _RTK)
    scheme: ArScheme = config_leaf(
        "filter",
        "AR scheme: filter (the filter's own position covariance, with hold or single-epoch AR), or "
        "prior (known-point initialisation, then each epoch's float solution takes the previous "
        "epoch's coordinate as its prior with σ = prior_sigma_m and AR runs every epoch without hold)",
        _RTK,
        key="ar_scheme",
    )
    prior_sigma_m: float = config_leaf(
        0.1, "σ of the previous epoch's coordinate as the prior of the next float solution (m)", _RTK
    )
    prior_ambiguities: PriorAmbiguities = config_leaf(
        "carry",
        "ambiguities of the prior scheme: carry (float estimates kept from epoch to epoch) or "
        "reestimate (new ambiguities every epoch)",
        _RTK,
    )
    prior_covariance: PriorCovariance = config_leaf(
        "reset",
        "position covariance of the prior scheme's next prior: reset (σ² I, uncorrelated with the "
        "ambiguities) or add (σ² I added to the posterior's, correlations kept)",
        _RTK,
    )
    ratio: float = config_leaf(3.0, "ratio-test threshold", _RTK)
    par_min: int = config_leaf(3, "smallest subset PAR may fix", _RTK)
    min_success_rate: float = config_leaf(
        0.0, "bootstrapped success rate a validated subset must reach", _RTK
    )
    amb_init_sigma_cyc: float = config_leaf(30.0, "initial ambiguity σ without known point (cycles)", _RTK)
    hold_sigma_cyc: float = config_leaf(0.01, "σ of the fix-and-hold pseudo-observation (cycles)", _RTK)
    hold_min_fix: int = config_leaf(0, "consecutive validated fixes before hold constrains the filter", _RTK)
    fix_residual_k: float = config_leaf(
        0.0,
        "a validated subset is accepted only when each fixed DD phase residual is within this many "
        "nominal σ (0 = off; RTKLIB uses 4)",
        _RTK,
    )
    ar_elev_mask_deg: float = config_leaf(
        0.0, "ambiguities below this elevation stay float (deg, 0 = off)", _RTK
    )
    ar_lock_epochs: int = config_leaf(0, "epochs of continuous lock before an ambiguity joins AR", _RTK)
    fix_confirm_epochs: int = config_leaf(
        0,
        "a fix is reported only after this many consecutive validated epochs with agreeing "
        "integers (0 = at once)",
        _RTK,
    )
    fix_max_sigma_m: float = config_leaf(
        0.0, "a fix is reported fixed only when the fixed position σ is at most this (m, 0 = off)", _RTK
    )


@dataclass(frozen=True)
class SlipConfig:
    """Cycle-slip detection."""

    detectors: str = config_leaf(
        "lli+poly", "slip detectors joined by + among lli, poly, gf, doppler; or none", _RTK, key="slip"
    )
    gf_threshold_m: float = config_leaf(0.05, "geometry-free slip threshold (m per epoch)", _RTK)
    gf_window_s: float = config_leaf(
        0.0,
        "window of the geometry-free drift test (phase-code inconsistency of one frequency; s, 0 = off)",
        _RTK,
    )
    gf_window_threshold_m: float = config_leaf(
        0.1, "geometry-free change over the window that flags a drift (m)", _RTK
    )
    doppler_threshold_cyc: float = config_leaf(0.5, "Doppler-minus-phase slip threshold (cycles)", _RTK)


@dataclass(frozen=True)
class GnssConfig:
    """Satellite selection for RINEX and phone input."""

    elev_mask_deg: float = config_leaf(15.0, "elevation mask (deg)", _GNSS)
    systems: str | None = config_leaf(
        None, "system letters to use, e.g. GEJ (None = the mode's default)", _GNSS
    )
    freqs: str = config_leaf("L1+L2", "frequency slots of DGNSS and RTK, e.g. L1+L2+L5", ("dgnss", "rtk"))
    glonass_ar: GlonassAr = config_leaf(
        "auto",
        "GLONASS (FDMA) ambiguity fixing when R is among the RTK systems: on (the receivers' inter-channel "
        "biases cancel: same make), off (float only) or auto (on when both receivers are the same make)",
        _RTK,
    )
    max_age_s: float = config_leaf(
        30.0,
        "largest age of differential (s): a rover epoch without a base epoch at its time uses the latest "
        "base epoch at most this old, carried to its time (RINEX; 0 = same epochs only)",
        ("dgnss", "rtk"),
    )
    sigma_age_m_s: float = config_leaf(
        5e-12 * 299_792_458.0,
        "growth of the base observations' σ per second of age (m/s; RTKLIB's clock-stability term, c·5e-12)",
        ("dgnss", "rtk"),
    )
    time_start: str | None = config_leaf(
        None,
        "first rover epoch solved: GPST 'yyyy/mm/dd hh:mm:ss' or 'hh:mm:ss' on the first epoch's date "
        "(None = from the first)",
        _GNSS,
    )
    time_end: str | None = config_leaf(
        None,
        "last rover epoch solved, as time_start; a time of day falls on time_start's date when that is a "
        "calendar time (None = to the last)",
        _GNSS,
    )
    interval_s: float = config_leaf(
        0.0, "solve only the rover epochs on this grid of GPS time of week (s; 0 = every epoch)", _GNSS
    )


@dataclass(frozen=True)
class SppSection:
    """Settings specific to single point positioning (undifferenced)."""

    cn0_ref_dbhz: float = config_leaf(45.0, "C/N0 above which no C/N0 down-weighting applies (dB-Hz)", _SPP)
    use_cn0: bool = config_leaf(True, "C/N0 term in the least-squares variance model", _SPP)
    kalman_use_cn0: bool = config_leaf(False, "C/N0 term in the Kalman SPP variance model", _SPP)
    raim: bool = config_leaf(True, "fault detection and exclusion in least squares", _SPP)
    raim_alpha: float = config_leaf(1e-3, "false-alarm probability of the FDE chi-square test", _SPP)
    max_exclusions: int = config_leaf(6, "most observations FDE may exclude per epoch", _SPP)
    max_iter: int = config_leaf(10, "Gauss-Newton iterations", _SPP)
    sigma_acc_up_m_s2: float = config_leaf(0.5, "vertical acceleration noise of the Kalman SPP (m/s²)", _SPP)
    q_clk_m2_s: float = config_leaf(1000.0, "receiver code-clock noise density (m²/s)", _SPP)
    q_drift_m2_s3: float = config_leaf(10.0, "receiver clock-drift noise density (m²/s³)", _SPP)
    q_phase_clk_m2_s: float = config_leaf(100.0, "carrier-phase clock noise density (m²/s)", _SPP)
    use_doppler: bool = config_leaf(True, "Doppler range-rate rows in the Kalman SPP", _SPP)
    doppler_sigma_m_s: float = config_leaf(0.5, "range-rate σ at zenith, elevation weighting (m/s)", _SPP)
    doppler_weighting: DopplerWeighting = config_leaf(
        "cn0", "range-rate variance: elevation (σ²/sin²el) or cn0 (frequency-lock-loop noise law)", _SPP
    )
    doppler_cn0_sigma_m_s: float = config_leaf(
        0.05, "range-rate σ at cn0_ref_dbhz under the cn0 weighting (m/s)", _SPP
    )
    zupt: bool = config_leaf(
        False, "zero-velocity update when the Doppler velocity says the receiver stands", _SPP
    )
    zupt_speed_m_s: float = config_leaf(0.1, "Doppler speed below which the receiver stands (m/s)", _SPP)
    zupt_sigma_m_s: float = config_leaf(0.01, "σ of each zero-velocity pseudo-observation (m/s)", _SPP)
    use_phase: bool = config_leaf(True, "carrier-phase rows with one float bias per arc (Kalman SPP)", _SPP)
    q_amb_m2_s: float = config_leaf(1e-4, "random walk of the carrier-phase biases (m²/s)", _SPP)
    amb_var0_m2: float = config_leaf(1e4, "variance of a new carrier-phase bias (m²)", _SPP)
    lli_reset: bool = config_leaf(False, "a loss-of-lock bit starts a new phase arc", _SPP)
    slip_var_m2: float = config_leaf(
        0.01, "variance added to a bias whose phase has a loss-of-lock flag (m²)", _SPP
    )
    dual_frequency: bool = config_leaf(True, "Kalman SPP also uses the second band", _SPP)
    code_bias: bool = config_leaf(
        False,
        "Kalman SPP: a Gauss-Markov code-bias state per satellite signal (multipath correlated in time)",
        _SPP,
    )
    code_elevation_delay: bool = config_leaf(
        False,
        "Kalman SPP: a Gauss-Markov code delay common to all satellites, growing as 1/sin(el) - 1 (the "
        "mean of multipath and NLOS delays)",
        _SPP,
    )
    code_elevation_delay_tau_s: float = config_leaf(
        3600.0, "correlation time of the elevation-dependent code delay (s)", _SPP
    )
    code_bias_sigma_m: float | None = config_leaf(
        None,
        "steady-state σ of the code biases and of the elevation-dependent delay at zenith "
        "(m; None = from the code minus carrier)",
        _SPP,
    )
    code_bias_tau_s: float | None = config_leaf(
        None, "correlation time of the code biases (s; None = from the code minus carrier)", _SPP
    )
    fgo: bool = config_leaf(
        False,
        "robust batch smoother over the whole track instead of the Kalman SPP (post-processing): code, "
        "Doppler, time-differenced carrier phase and the motion prior in one sparse least-squares problem",
        _SPP,
    )
    fgo_iono: bool = config_leaf(
        True,
        "batch smoother: estimate the broadcast ionosphere's error with the track (a field on the "
        "thin shell: vertical delay and gradients per minute) where the two bands can tell it",
        _SPP,
    )
    q_ifb_m2_s: float = config_leaf(1e-4, "random walk of the inter-frequency code biases (m²/s)", _SPP)
    clock_reset_m: float = config_leaf(
        1000.0, "a per-system median innovation beyond this resets the clock (m)", _SPP
    )
    reinit_m: float = config_leaf(
        100.0, "filter vs least-squares disagreement that counts toward re-init (m)", _SPP
    )


@dataclass(frozen=True)
class ReceiversConfig:
    """Receivers: names in pseudolite tables and how the base position is known."""

    base: str = config_leaf(
        "base", "base receiver name in the observation table", ("dpl", "rtk"), flag="--base-name"
    )
    rover: str = config_leaf(
        "rover", "rover receiver name in the observation table", ("dpl", "rtk"), flag="--rover-name"
    )
    base_position: BasePosition = config_leaf(
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

    filter: CoopFilter = config_leaf(
        "ekf", "each node's filter: ekf, ukf, pf (particle filter) or ls (epoch-wise least squares)", _COOP,
        key="coop_filter",
    )  # fmt: skip
    cooperation: Cooperation = config_leaf(
        "improved",
        "improved (range variance inflated by the reset peer covariance, eqs. 24, 29, 30), traditional "
        "(as measured) or off (no ranges)",
        _COOP,
    )
    sigma_pos_m_s: float = config_leaf(0.01, "eq. 8 position rate noise σ_ẋ per axis (m/s)", _COOP)
    sigma_clk_m_s: float = config_leaf(100.0, "eq. 8 clock rate noise σ_ḃ (m/s)", _COOP)
    n_particles: int = config_leaf(10_000, "particle-filter size", _COOP)
    ess_threshold: float = config_leaf(
        0.5, "particle filter: resample below this effective sample fraction", _COOP
    )
    roughening: float = config_leaf(
        0.2, "particle filter: roughening after resampling (fraction of the spread)", _COOP
    )
    seed: int = config_leaf(0, "particle-filter seed (node i uses seed + i)", _COOP)
    sigma_set_m: float | None = config_leaf(
        None, "σ_set of the covariance reset, eq. 29 (m; None = the short-window estimate)", _COOP
    )
    sigma_wset_m_s: float | None = config_leaf(
        None, "σ_wset of the UKF's reset noise block, eq. 30 (m/s; None = the short-window estimate)", _COOP
    )
    window: int = config_leaf(10, "peer broadcasts in the short window of the reset estimates (>= 2)", _COOP)
    sigma_set_floor_m: float = config_leaf(0.5, "floor of the short-window σ_set (m)", _COOP)
    sigma_wset_floor_m_s: float = config_leaf(0.01, "floor of the short-window σ_wset (m/s)", _COOP)
    max_broadcast_age_s: float = config_leaf(60.0, "older peer broadcasts are not used (s)", _COOP)
    init_floor_m: float = config_leaf(
        1.0, "floor of the initial position σ from the least-squares start (m)", _COOP
    )
