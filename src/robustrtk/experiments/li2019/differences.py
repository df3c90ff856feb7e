"""Where and why the reproduction's numbers differ from the paper's: the report's closing
paragraphs (:func:`differences`) and the sentences on the process-noise and prior-σ
sensitivity they quote."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from robustrtk.eval.situations import ALL_LABEL
from robustrtk.experiments.li2019.cells import format_cell
from robustrtk.experiments.li2019.claims import PAPER_DPL_EPOCHS, PAPER_TABLE1
from robustrtk.experiments.li2019.metrics import (
    CONV_RTK_M,
    gauss_dv_exceed_prob,
    impulse_share_bound,
    stat_value,
)
from robustrtk.experiments.li2019.schemes import (
    FIX_RESIDUAL_K,
    K0,
    K1,
    PRIOR_SIGMA_M,
    PRIOR_SIGMAS_SENS_M,
    Q_SIGMAS_M,
    RTK_SLIP,
    prior_label,
)
from robustrtk.pipeline.config import Config
from robustrtk.sim.scenario import PL_WAVELENGTH_M


def _q_present(stats: Mapping[str, dict[str, Any]]) -> list[float]:
    """The σ of the process-noise sensitivity that the run has."""
    return [q for q in Q_SIGMAS_M if f"rtk015.q@{q:g}.SUKF.jump_m" in stats]


def _q_span(stats: Mapping[str, dict[str, Any]], runs: int, group: str, key: str, fmt: str, sep: str) -> str:
    """A statistic of the process-noise sensitivity at its smallest and largest σ:
    ``"<cell at σ_min><sep><cell at σ_max>"`` (``group``: ``rtk.static_q`` or ``rtk015.q``)."""
    qs = _q_present(stats)
    ends = [format_cell(stats[f"{group}@{q:g}.{key}"], fmt, runs) for q in (qs[0], qs[-1])]
    return sep.join(ends)


def _q_fig8_sentence(stats: Mapping[str, dict[str, Any]], runs: int) -> str:
    """Fig. 8 with a coordinate random walk: SUKF's and RUKF's largest extra errors at the
    smallest and largest σ of the run."""
    qs = _q_present(stats)
    if not qs:
        return ""

    def span(name: str) -> str:
        return _q_span(stats, runs, "rtk.static_q", f"{name}.max_extra_faulty_m", ".4f", " … ")

    return (
        f": with fix-and-hold and a coordinate random walk of σ = {qs[0]:g} … {qs[-1]:g} m per epoch "
        f"(the process-noise table with Fig. 9) SUKF moves by {span('SUKF')} m and RUKF by "
        f"{span('RUKF')} m: the looser the coordinate, the larger SUKF's jump and the less one "
        "redundancy lets RUKF tell the faulty DD"
    )


def _q_fig9_sentence(stats: Mapping[str, dict[str, Any]], runs: int) -> str:
    """Fig. 9 with a coordinate random walk: SUKF's jump and both re-fix times at the
    smallest and largest σ of the run."""
    qs = _q_present(stats)
    if not qs:
        return ""
    lost = all(
        stat_value(stats, f"rtk015.q@{q:g}.{n}.fixed_at_fault") == 0 for q in qs for n in ("SUKF", "RUKF")
    )
    refix = [
        " / ".join(
            format_cell(stats[f"rtk015.q@{q:g}.{n}.refix_epochs"], ".0f", runs) for n in ("SUKF", "RUKF")
        )
        for q in (qs[0], qs[-1])
    ]
    return (
        f". With a coordinate random walk of σ = {qs[0]:g} … {qs[-1]:g} m per epoch and the "
        f"{FIX_RESIDUAL_K:g} σ residual test (process-noise table) SUKF's jump grows from "
        + _q_span(stats, runs, "rtk015.q", "SUKF.jump_m", ".3f", " to ")
        + " m, "
        + (
            "both lose the fix at epoch 100 at every σ"
            if lost
            else "not both lose the fix at epoch 100 at every σ (median over seeds)"
        )
        + f", and SUKF / RUKF re-fix after {refix[0]} and {refix[1]} epochs: a one-epoch error "
        f"leaves at most {100 * impulse_share_bound(11):.1f} % of its effect 11 epochs later, "
        "whatever the filter's gain (docs/algorithms.md §20)"
    )


def slow_refix_sentence(stats: Mapping[str, dict[str, Any]], runs: int) -> str:
    """Which prior σ of the sensitivity table re-fix SUKF slowly (median over seeds above one
    epoch), with SUKF's fix rate before the error there: the paper's slow re-fix against a
    stable fix before it."""
    slow = []
    for sig in PRIOR_SIGMAS_SENS_M:
        p = f"rtk015.{prior_label(sig)}.SUKF"
        if f"{p}.refix_epochs" not in stats:
            continue
        med = stats[f"{p}.refix_epochs"]["median"]
        if med is not None and math.isfinite(med) and med > 1:
            before = format_cell(stats[f"{p}.fix_rate_before"], ".2f", runs)
            slow.append(f"σ = {sig:g} m (SUKF fix rate before 100: {before})")
    grid = ", ".join(f"{sig:g}" for sig in PRIOR_SIGMAS_SENS_M)
    if not slow:
        return f"no prior σ of the sensitivity table ({grid} m) re-fixes SUKF after more than one epoch."
    return (
        f"of the prior σ of the sensitivity table ({grid} m), SUKF re-fixes after more than one "
        "epoch (median) only at "
        + "; ".join(slow)
        + ", where the fix was not stable before the error either."
    )


def differences(stats: Mapping[str, dict[str, Any]], runs: int) -> list[str]:
    """Plain-language explanation of where and why our numbers differ from the paper's,
    one paragraph per experiment, with the run's numbers."""

    def s(key: str) -> float:
        return stat_value(stats, key)

    def f(key: str, fmt: str = ".3f") -> str:
        return format_cell(stats[key], fmt, runs)

    cfg = Config()
    out: list[str] = []
    out.append(
        "These are simulations, not the authors' laboratory: five pseudolites at assumed "
        "ceiling positions, white noise plus first-order Gauss-Markov multipath, code bursts "
        "whose rate and size were chosen to resemble Table 1, and the 10 m, 5 cm, 0.1 m and "
        "0.15 m errors placed where the paper puts them. Apart from the burst rate and sizes, "
        "the simulation and the solver settings were not adjusted towards the paper's numbers; "
        "settings the paper does not give (process noise, how the hold is applied, the "
        "accuracy of the RTK initial coordinates) are the solver's defaults, except that the RTK "
        f"schemes detect slips from loss-of-lock flags only (`slip = {RTK_SLIP}`; the paper's "
        "errors are for the estimator and the simulated phase has no slips). A claim that does "
        "not hold is reported as it came out. Point by point:\n"
    )
    n_dpl = sum(s(f"dpl.table1.{ALL_LABEL}.s{k}") for k in (1, 2, 3))
    scaled = " / ".join(str(round(p * n_dpl / PAPER_DPL_EPOCHS)) for p in PAPER_TABLE1[ALL_LABEL])
    out.append(
        "- **Table 1.** Our counts over all DDs are "
        + " / ".join(f(f"dpl.table1.{ALL_LABEL}.s{k}", "d") for k in (1, 2, 3))
        + f" against the paper's scaled to our epochs, {scaled}. Table 1 is the only description "
        "the paper gives of its code anomalies, so the burst rate, sizes and links were "
        "calibrated against it (3000-epoch runs; bursts on PL4 and PL8 only, 0.3–1.5 m): the "
        "Table 1 claims check that calibration, they are not independent evidence. Per DD, "
        "PL1-PL6 and PL5-PL6 have #2 on "
        + f("dpl.table1.PL1-PL6.s2", "d")
        + " / "
        + f("dpl.table1.PL5-PL6.s2", "d")
        + " epochs against the paper's 949 / 826: with no anomaly at all, four independent "
        f"Gaussian residuals give Δv̄ > k0 on {100 * gauss_dv_exceed_prob(K0, 4):.0f} % of the "
        "epochs of each DD, above the paper's 8–9 % for these two links.\n"
    )
    out.append(
        f"- **DPL, Fig. 6 and conclusion 1.** Our static filter (q = {cfg.estimator.q_static_m2_s:g} m²/s) "
        "averages over all past epochs: SUKF's own 3D σ at the last epoch is "
        + f("dpl.SUKF.sigma_3d_end_m", ".4f")
        + " m, and its mean |error| X / Y / Z is "
        + " / ".join(f(f"dpl.fig6.SUKF.s1.{a}") for a in "XYZ")
        + " m in clean epochs (#1) and "
        + " / ".join(f(f"dpl.fig6.SUKF.s2.{a}") for a in "XYZ")
        + " m in epochs with small gross "
        "errors (#2). An error that hardly depends on the epoch's situation is the slowly "
        "varying bias of a long average, not the effect of that epoch's bad DD, so "
        "down-weighting the bad DD changes little: "
        "the largest per-axis gain in #2 is " + f("dpl.improvement.s2.max_axis_m") + " m. The "
        "paper's Fig. 5 shows errors that follow the epochs' observations, i.e. a filter that "
        "remembers much less. With the solver's random-walk position model on the same data "
        "(sensitivity table, not used in the claims) SUKF's σ is "
        + f("dpl_rw.SUKF.sigma_3d_end_m", ".4f")
        + " m and the #2 gain "
        + f("dpl_rw.improvement.s2.max_axis_m")
        + " m.\n"
    )
    out.append(
        "- **Fig. 7.** Δv̄ divides one DD's standardized residual by the mean of the other "
        "three. With four independent Gaussian residuals it exceeds k0 = 2 with probability "
        f"{100 * gauss_dv_exceed_prob(K0, 4):.0f} % (sampled), and on clean PL4-PL1 epochs we "
        "see a fraction of " + f("rtk.static_orig.PL4.frac_clean_dv_gt_k0") + ". The paper's "
        '"all below 2" is not what independent noise gives.\n'
    )
    out.append(
        "- **Fig. 8.** With fix-and-hold and the static model, SUKF's position is known to "
        + f("rtk.static.SUKF.sigma_3d_first_fault_m", ".4f")
        + " m (3D σ) when the first 5 cm "
        "error arrives, so the errors move it by at most "
        + f("rtk.static.SUKF.max_extra_faulty_m", ".4f")
        + " m. A centimetre jump, as in the paper, needs a position that follows each epoch"
        + _q_fig8_sentence(stats, runs)
        + ".\n"
    )
    p = "rtk015.hold.SUKF"
    if abs(s(f"{p}.jump_m")) < 0.01 and s(f"{p}.fixed_at_fault") == 1:
        what = (
            "A single epoch's 0.15 m error can move neither, so SUKF does not jump ("
            + f(f"{p}.jump_m")
            + " m) and keeps its fix at epoch 100."
        )
    else:
        what = (
            "SUKF jumps by "
            + f(f"{p}.jump_m")
            + " m and is "
            + ("fixed" if s(f"{p}.fixed_at_fault") == 1 else "not fixed")
            + " at epoch 100."
        )
    q = "rtk015.prior"
    names = ("SUKF", "RUKF", "RUKF+PAR")
    lit, poly = "rtk015.prior_lit", "rtk015.prior_poly"
    out.append(
        "- **Fig. 9, the paper's scheme (the claims).** Each epoch's float solution starts from "
        f"the previous coordinate with σ = {PRIOR_SIGMA_M:g} m and the carried float ambiguities. "
        "SUKF / RUKF / RUKF+PAR: 3D error at epoch 99 "
        + " / ".join(f(f"{q}.{n}.err_before_m") for n in names)
        + " m, fix rate before epoch 100 "
        + " / ".join(f(f"{q}.{n}.fix_rate_before") for n in names)
        + ", jump at 100 "
        + " / ".join(f(f"{q}.{n}.jump_m") for n in names)
        + " m, share of seeds fixed at 100 "
        + " / ".join(f"{s(f'{q}.{n}.fixed_at_fault_share'):.2f}" for n in names)
        + ", epochs to re-fix "
        + " / ".join(f(f"{q}.{n}.refix_epochs", ".0f") for n in names)
        + ". SUKF takes the 0.15 m (0.79 cycle) error into its position; PL4-PL1's post-fit "
        "residual at epoch 100, "
        + f(f"{q}.SUKF.pl4_resid_at_fault_m")
        + f" m, is what the {FIX_RESIDUAL_K:g} σ residual test of the fixed solution sees. The "
        "solver's RUKF gives PL4-PL1 Δv̄ = "
        + f(f"{q}.RUKF.pl4_dv_at_fault", ".1f")
        + f" (> k1 = {K1:g}) and weight "
        + f(f"{q}.RUKF.pl4_weight_at_fault", ".2f")
        + ": the row is removed, the position stays, and RUKF+PAR fixes the other three "
        "ambiguities. After the error the carried ambiguities, updated on 99 epochs of the "
        "same geometry, are stiffer than the coordinate prior and pull the position back: "
        "PL4-PL1's innovation on the first clean epoch is "
        + " / ".join(f(f"{q}.{n}.pl4_innov_after_m") for n in names)
        + f" m (half a wavelength: {PL_WAVELENGTH_M / 2:.3f} m) and that epoch fixes again. A "
        "12-epoch re-fix as in the paper needs float ambiguities that stay biased by a large "
        "part of a cycle for 11 clean epochs; " + slow_refix_sentence(stats, runs) + "\n"
    )
    out.append(
        "- **Fig. 9, the paper's literal Δv̄ (variant).** Computed as Sec. 2.2 writes it, from "
        "the posterior residuals of the nominal update, PL4-PL1's Δv̄ at epoch 100 is "
        + f(f"{lit}.RUKF.pl4_dv_at_fault", ".2f")
        + f" (< k0 = {K0:g}), weight "
        + f(f"{lit}.RUKF.pl4_weight_at_fault", ".2f")
        + ". Four DD phases and three coordinates leave one redundancy, and with one "
        "redundancy every standardized residual has the same magnitude (docs/algorithms.md "
        "§20): the statistic cannot point at PL4, RUKF does what SUKF does (jump "
        + " / ".join(f(f"{lit}.{n}.jump_m") for n in names)
        + " m, fixed at 100 on a share "
        + " / ".join(f"{s(f'{lit}.{n}.fixed_at_fault_share'):.2f}" for n in names)
        + " of the seeds) and PAR, ranking by the same Δv̄, has no subset to prefer. The "
        "paper's RUKF result (PL4 down-weighted, not removed: 0.12 m against 0.16 m) needs "
        "a Δv̄ between k0 and k1, which neither the literal nor the solver's statistic gives "
        "in this geometry.\n"
    )
    out.append(
        "- **Fig. 9, default slip detectors (variant).** With the polynomial detector the "
        "0.79-cycle jump at epoch 100 is a non-integer slip; SUKF (no robust policy) resets "
        "PL4's ambiguity there, the new ambiguity absorbs the error and SUKF jumps "
        + f(f"{poly}.SUKF.jump_m")
        + " m only (fixed at 100 on a share "
        + f"{s(f'{poly}.SUKF.fixed_at_fault_share'):.2f}"
        + " of the seeds). The robust schemes defer the slip to the robust filter, but the "
        "detector's repair still changes what they see on PL4-PL1 (RUKF: Δv̄ "
        + f(f"{poly}.RUKF.pl4_dv_at_fault", ".1f")
        + ", weight "
        + f(f"{poly}.RUKF.pl4_weight_at_fault", ".2f")
        + ", jump "
        + f(f"{poly}.RUKF.jump_m")
        + " m). The claims use loss-of-lock flags only: the paper's SUKF does jump, so its "
        "error reached the estimator.\n"
    )
    out.append(
        "- **Fig. 9, fix-and-hold.** Our hold adds the validated integers as pseudo-observations "
        f"(σ = {cfg.ar.hold_sigma_cyc:g} cycle) at every fixed epoch, and the static position has "
        "been averaged over 99 epochs (SUKF 3D σ at epoch 99: "
        + f(f"{p}.sigma_before_m", ".4f")
        + " m). "
        + what
        + " The paper's 0.16 m jump is about the size of the error itself: its "
        "position followed that one epoch, in a filter that remembers far less than ours. The "
        "paper does not give its process noise or how its hold is applied"
        + _q_fig9_sentence(stats, runs)
        + ".\n"
    )
    p = "rtk015.cont.SUKF"
    if s(f"{p}.err_before_m") >= CONV_RTK_M:
        what = (
            "In our runs the float position wanders away from the known point long before "
            "the error: SUKF's 3D error at epoch 99 is " + f(f"{p}.err_before_m") + " m and "
            "it was fixed on a fraction " + f(f"{p}.fix_rate_before") + " of the epochs "
            "before 100, so there is no fix left to lose at epoch 100."
        )
    else:
        what = (
            "SUKF / RUKF / RUKF+PAR jump by "
            + " / ".join(f(f"rtk015.cont.{n}.jump_m") for n in ("SUKF", "RUKF", "RUKF+PAR"))
            + " m and re-fix "
            "after "
            + " / ".join(f(f"rtk015.cont.{n}.refix_epochs", ".0f") for n in ("SUKF", "RUKF", "RUKF+PAR"))
            + " epochs."
        )
    out.append(
        "- **Fig. 9, continuous AR.** With five fixed transmitters and a static rover the phase "
        "cannot separate the position from the ambiguities (the paper says so in Sec. 2.1); "
        f"without hold only the known-point prior (σ = {cfg.estimator.init_sigma_m:g} m) holds the float "
        "position. " + what + "\n"
    )
    out.append(
        "- **Fig. 10.** The rail runs use the solver's RTK kinematic model, constant velocity "
        f"with σ_a = {cfg.estimator.sigma_acc_m_s2:g} m/s², and fix-and-hold: SUKF moves "
        "by at most " + f("rail.SUKF.max_abs_x_faulty_m") + " m in X on the faulty epochs "
        "(clean epochs: "
        + f("rail.SUKF.max_abs_x_clean_m")
        + " m) and RUKF by "
        + f("rail.RUKF.max_abs_x_faulty_m")
        + " m. The paper's state function is "
        "the identity (no velocity) with unstated noise; how much of one epoch's error reaches "
        "the position depends on that choice.\n"
    )
    q = "rail015.prior"
    out.append(
        "- **Fig. 11, the paper's scheme (the claims).** SUKF / RUKF+PAR: max deviation from "
        "the rail before epoch 50 "
        + f(f"{q}.SUKF.max_dev_before_m")
        + " / "
        + f(f"{q}.RUKF+PAR.max_dev_before_m")
        + " m, after "
        + f(f"{q}.SUKF.max_dev_after_m")
        + " / "
        + f(f"{q}.RUKF+PAR.max_dev_after_m")
        + " m, fix rate "
        + f(f"{q}.SUKF.fix_rate")
        + " / "
        + f(f"{q}.RUKF+PAR.fix_rate")
        + ". SUKF leaves the rail by "
        + f(f"{q}.SUKF.dev_at_fault_m")
        + " m at epoch 50 and re-fixes after "
        + f(f"{q}.SUKF.refix_epochs", ".0f")
        + " epoch(s). The rover moves 2 cm per epoch, inside the prior's σ; as in Fig. 9 the "
        "carried ambiguities let the epochs after the error fix again on the right integers, so "
        "SUKF's one biased epoch does not carry into the next ones: the divergence of the "
        "paper's SUKF needs a wrong fix that is accepted and then followed.\n"
    )
    q = "rail015.prior_re"
    out.append(
        "- **Fig. 11, the paper's scheme with the ambiguities re-estimated (variant).** Sec. 3.3.2 "
        "says single-epoch PL-AR. With new ambiguities at every epoch each DD phase is absorbed "
        "by its own ambiguity, so the float position is the prior, the previous epoch's "
        "coordinate (docs/algorithms.md §20), and only an epoch that fixes moves the coordinate. "
        "SUKF / RUKF+PAR: deviation at epoch 50 "
        + f(f"{q}.SUKF.dev_at_fault_m")
        + " / "
        + f(f"{q}.RUKF+PAR.dev_at_fault_m")
        + " m, max deviation from 50 "
        + f(f"{q}.SUKF.max_dev_after_m")
        + " / "
        + f(f"{q}.RUKF+PAR.max_dev_after_m")
        + " m, mean "
        + f(f"{q}.SUKF.mean_dev_after_m")
        + " / "
        + f(f"{q}.RUKF+PAR.mean_dev_after_m")
        + " m (RUKF+PAR closer by "
        + f(f"{q}.improvement_mean_dev_m")
        + " m), fix rate before / from 50 "
        + f(f"{q}.SUKF.fix_rate_before")
        + " / "
        + f(f"{q}.SUKF.fix_rate_after")
        + " (SUKF) and "
        + f(f"{q}.RUKF+PAR.fix_rate_before")
        + " / "
        + f(f"{q}.RUKF+PAR.fix_rate_after")
        + " (RUKF+PAR), largest 3D error before 50 "
        + f(f"{q}.SUKF.max_err3d_before_m")
        + " / "
        + f(f"{q}.RUKF+PAR.max_err3d_before_m")
        + " m and from 50 "
        + f(f"{q}.SUKF.max_err3d_after_m")
        + " / "
        + f(f"{q}.RUKF+PAR.max_err3d_after_m")
        + " m. An epoch that does not fix keeps the previous coordinate while the rover moves "
        "2 cm along the rail: that lag is carried into the next prior and shows in the 3D error, "
        "not in the deviation across the rail. Leaving the rail by decimetres needs wrong "
        "integers accepted at the faulty epoch and then followed.\n"
    )
    p = "rail015.inst"
    txt = "- **Fig. 11, single-epoch AR (variant).** "
    worst_before = max(s(f"{p}.{n}.max_dev_before_m") for n in ("SUKF", "RUKF+PAR"))
    if worst_before >= CONV_RTK_M:
        txt += (
            "In this run the tracks leave the rail before the error (max deviation before "
            "epoch 50, SUKF / RUKF+PAR: "
            + f(f"{p}.SUKF.max_dev_before_m")
            + " / "
            + f(f"{p}.RUKF+PAR.max_dev_before_m")
            + " m; the fix-and-hold variant stays "
            "within " + f("rail015.hold.SUKF.max_dev_before_m") + " m on the same data). "
            "After a fixed epoch the solver carries the fixed position into the next epoch "
            "with the float covariance, which in single-epoch AR only grows, so the integer "
            "search widens until it fails (the position then coasts on the prediction) or "
            "accepts wrong integers (tests/pipeline/test_rtk_instantaneous.py). The Fig. 11 "
            "claims cannot be tested on such tracks."
        )
    else:
        txt += (
            "Every ambiguity is new at every epoch, so each DD phase is absorbed by its own "
            "new ambiguity: the four phases carry no redundancy and their post-fit "
            "residuals are practically zero (largest "
            + f(f"{p}.RUKF+PAR.max_abs_resid_m", ".1e")
            + " m). Δv̄ then reflects the "
            "geometry, not the data: PL4-PL1's Δv̄ is "
            + f(f"{p}.RUKF+PAR.PL4_dv_before_fault", ".2f")
            + " at epoch 49 and "
            + f(f"{p}.RUKF+PAR.PL4_dv_at_fault", ".2f")
            + " at epoch "
            "50, and down-weighting a row that its own ambiguity absorbs changes nothing: "
            "SUKF and RUKF+PAR positions differ by at most "
            + f(f"{p}.max_pos_diff_m", ".4f")
            + " m. Both follow the rail before the error; after it SUKF deviates by at most "
            + f(f"{p}.SUKF.max_dev_after_m")
            + " m. The paper does not say where its RUKF "
            "found the redundancy to detect the error in this mode."
        )
    out.append(txt + "\n")
    e1, u1 = s("dpl_init.EKF.1.rms_3d_m"), s("dpl_init.UKF.1.rms_3d_m")
    txt = (
        "- **EKF vs UKF.** Our EKF re-linearizes at every epoch. In DPL with a 1 m offset its "
        "3D RMS is "
        + f("dpl_init.EKF.1.rms_3d_m")
        + " m against the UKF's "
        + f("dpl_init.UKF.1.rms_3d_m")
        + " m"
    )
    if abs(e1 - u1) < 0.01:
        txt += (
            ", the same within a centimetre: at ranges of a few metres the linearization "
            "error of a 1 m offset is gone after the first updates."
        )
    else:
        txt += "."
    txt += (
        " In RTK with a 1 m offset the 3D RMS is " + f("rtk_init.EKF.1.rms_3d_m") + " m (EKF) "
        "and " + f("rtk_init.UKF.1.rms_3d_m") + " m (UKF)"
    )
    if all(not math.isfinite(s(f"rtk_init.{fl}.1.conv_epoch")) for fl in ("EKF", "UKF")):
        txt += (
            f"; neither gets below {CONV_RTK_M:g} m for good: a known point 1 m off does not "
            "lead either filter to the right integers."
        )
    else:
        txt += "."
    out.append(txt + "\n")
    return out


__all__ = ["differences", "slow_refix_sentence"]
