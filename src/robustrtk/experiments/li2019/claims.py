"""The paper's findings checked against the statistics: :class:`Claim` and the claims
table (:func:`build_claims`), with the paper's Table 1 counts."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from robustrtk.eval.situations import ALL_LABEL
from robustrtk.experiments.li2019.metrics import CONV_RTK_M, gauss_dv_exceed_prob, impulse_share_bound
from robustrtk.experiments.li2019.schemes import (
    FIX_RESIDUAL_K,
    INIT_OFFSETS_M,
    K0,
    K1,
    PRIOR_SIGMA_M,
    PRIOR_SIGMAS_SENS_M,
    Q_SIGMAS_M,
    dd_phase_sigma_m,
    prior_label,
)
from robustrtk.sim.scenario import PL_WAVELENGTH_M

#: Table 1 of the paper: epochs per situation (#1, #2, #3) for each DD and over all DDs.
PAPER_TABLE1 = {
    "PL1-PL6": (9887, 949, 29),
    "PL4-PL6": (7846, 2819, 200),
    "PL5-PL6": (10014, 826, 25),
    "PL8-PL6": (8255, 2486, 124),
    ALL_LABEL: (3693, 6794, 378),
}
PAPER_DPL_EPOCHS = 10865  # sum of each row of Table 1


@dataclass(frozen=True)
class Claim:
    """One finding of the paper checked against the simulation; ``why`` says, with the
    run's numbers, what makes it hold or not."""

    section: str
    claim: str
    paper: str
    ours: str
    holds: bool | None
    why: str = ""


def _verdict(ok: bool, yes: str, no: str) -> str:
    return yes if ok else no


def _q_sigmas(s: Callable[[str], float]) -> list[float]:
    """The σ of the process-noise sensitivity that the run has (a quick run has fewer)."""
    out = []
    for q in Q_SIGMAS_M:
        try:
            s(f"rtk015.q@{q:g}.SUKF.jump_m")
        except KeyError:
            continue
        out.append(q)
    return out


def _q_fig8_reason(s: Callable[[str], float]) -> str:
    """Fig. 8 over the process-noise sensitivity: where its shape holds, and Fig. 9's SUKF
    jump there."""
    qs = _q_sigmas(s)
    if not qs:
        return ""
    cells = []
    holds = []
    for q in qs:
        su = s(f"rtk.static_q@{q:g}.SUKF.max_extra_faulty_m")
        ru = s(f"rtk.static_q@{q:g}.RUKF.max_extra_faulty_m")
        cells.append(f"{1000 * su:.0f} / {1000 * ru:.0f} mm (σ {q:g} m)")
        if su >= 0.005 and ru < 0.5 * su:
            holds.append(q)
    text = (
        ". With the paper's identity state function and a coordinate random walk of σ per epoch "
        "(fix-and-hold; the paper states no Q), SUKF / RUKF move by " + "; ".join(cells)
    )
    if not holds:
        return text + ": for no σ does RUKF remove SUKF's jump"
    jumps = [s(f"rtk015.q@{q:g}.SUKF.jump_m") for q in holds]
    both = [q for q, j in zip(holds, jumps, strict=True) if abs(j - 0.16) <= 0.05]
    top = max(qs, key=lambda q: s(f"rtk015.q@{q:g}.SUKF.jump_m"))
    text += (
        f". The claim's shape holds for σ = {', '.join(f'{q:g}' for q in holds)} m, where Fig. 9's "
        f"SUKF jump is {min(jumps):.3f}–{max(jumps):.3f} m against the paper's 0.16 m"
    )
    if top not in holds:
        text += (
            f" (largest, {s(f'rtk015.q@{top:g}.SUKF.jump_m'):.3f} m at σ {top:g} m, where RUKF no "
            "longer removes the 5 cm error: with the coordinate free each epoch, four DDs leave one "
            "redundancy)"
        )
    if both:
        return text + f"; σ = {', '.join(f'{q:g}' for q in both)} m gives both"
    return text + ", so no single Q gives Fig. 8 and Fig. 9's jump together"


def _refix_bound_reason(s: Callable[[str], float], js: float) -> str:
    """Why a one-epoch error cannot delay a re-fix by 12 (or 5) epochs in a linear filter,
    with the run's numbers; and the re-fix epochs of the process-noise sensitivity."""
    b11, b4 = impulse_share_bound(11), impulse_share_bound(4)
    tol_mm = 1000 * FIX_RESIDUAL_K * dd_phase_sigma_m()
    b11_mm, b4_mm = 1000 * b11 * js, 1000 * b4 * js
    text = (
        " A one-epoch error moves a coordinate of per-epoch gain K by K·e and leaves K(1 − K)^j·e "
        f"of it j clean epochs later: whatever K, at most {100 * b11:.1f} % of e for j = 11 (a re-fix "
        f"after 12 epochs) and {100 * b4:.1f} % for j = 4 (after 5; docs/algorithms.md §20). With e "
        f"SUKF's full response, its jump in the paper's scheme ({js:.3f} m), that is {b11_mm:.1f} mm "
        f"and {b4_mm:.1f} mm, which move a DD phase by at most twice as much ({2 * b11_mm:.1f} and "
        f"{2 * b4_mm:.1f} mm), against the {tol_mm:.0f} mm ({FIX_RESIDUAL_K:g} σ of a DD phase) beyond "
        "which the residual test of a fix refuses it: "
        + (
            "the paper's 12 epochs need an error on more than one epoch, or a state reset after it"
            if 2 * b11_mm < tol_mm
            else "the bound does not exclude the paper's 12 epochs here"
        )
        + (
            ", and its 5 epochs need the worst gain and the worst projection at once."
            if 2 * b4_mm >= tol_mm
            else ", nor its 5 epochs."
        )
    )
    qs = _q_sigmas(s)
    if qs:
        text += (
            " With fix-and-hold and a coordinate random walk of σ per epoch, SUKF / RUKF re-fix after "
            + "; ".join(
                f"{s(f'rtk015.q@{q:g}.SUKF.refix_epochs'):.0f} / "
                f"{s(f'rtk015.q@{q:g}.RUKF.refix_epochs'):.0f} "
                f"(σ {q:g} m, SUKF jump {s(f'rtk015.q@{q:g}.SUKF.jump_m'):.3f} m)"
                for q in qs
            )
            + "."
        )
    return text


def build_claims(s: Callable[[str], float], n_dpl: int, f: Callable[[str, str], str]) -> list[Claim]:
    """The claims table. ``s(key)`` is a statistic's median (``key + "_share"``: its mean
    over seeds, for 0/1 statistics), ``n_dpl`` the DPL epoch count and ``f(key, fmt)`` a
    statistic formatted for the table (median [5 %, 95 %])."""
    c: list[Claim] = []
    scale = n_dpl / PAPER_DPL_EPOCHS
    all_ = [s(f"dpl.table1.{ALL_LABEL}.s{k}") for k in (1, 2, 3)]
    paper_all = PAPER_TABLE1[ALL_LABEL]
    dev = [(o - p * scale) / (p * scale) for o, p in zip(all_, paper_all, strict=True)]
    within = all(abs(d) <= 0.3 for d in dev)
    c.append(
        Claim(
            "3.2, Table 1",
            "Epochs per situation over all DDs (#1/#2/#3); within ±30 % "
            "of the paper's counts scaled to our epoch count",
            "3693 / 6794 / 378",
            " / ".join(f(f"dpl.table1.{ALL_LABEL}.s{k}", "d") for k in (1, 2, 3)),
            within,
            "deviation from the scaled counts #1/#2/#3: "
            + " / ".join(f"{100 * d:+.0f} %" for d in dev)
            + " (the code bursts are calibrated against Table 1: a check of that calibration)",
        )
    )
    frac2 = all_[1] / max(sum(all_), 1.0)
    c.append(
        Claim(
            "3.2, Table 1",
            "Most epochs (~63 %) carry a small gross error (#2)",
            "63 %",
            f"{100 * frac2:.0f} %",
            frac2 > 0.5,
            f"median share of #2 epochs {100 * frac2:.0f} % (calibration target, see Table 1)",
        )
    )
    imp2 = s("dpl.improvement.s2.max_axis_m")
    c.append(
        Claim(
            "3.2, Fig. 6",
            "RUKF improves DPL mean |error| in situation #2 at decimetre "
            "level (largest per-axis SUKF − RUKF ≥ 0.05 m)",
            "decimetre",
            f("dpl.improvement.s2.max_axis_m", ".3f") + " m",
            imp2 >= 0.05,
            _verdict(
                imp2 >= 0.05,
                f"largest per-axis gain {imp2:.3f} m",
                f"largest per-axis gain {imp2:.3f} m: SUKF's mean |error| in #2 is within "
                f"{abs(s('dpl.fig6.SUKF.s2.Z') - s('dpl.fig6.SUKF.s1.Z')):.3f} m (Z) of its clean-epoch "
                "value, so a #2 epoch's bad DD moves the static average little and there is little "
                "to win; with a random-walk position that follows the epochs (first seed, "
                f"SUKF 3D σ {s('dpl_rw.SUKF.sigma_3d_end_m'):.2f} m) the gain is "
                f"{s('dpl_rw.improvement.s2.max_axis_m'):.3f} m, still not a decimetre: the "
                "situation-#2 code errors that reproduce Table 1 (0.3–1.5 m bursts on PL4 and PL8) "
                "are too small for it (see 'Why our numbers differ')",
            ),
        )
    )
    s3 = [s(f"dpl.fig6.SUKF.s3.{a}") - s(f"dpl.fig6.RUKF.s3.{a}") for a in "XYZ"]
    ok = all(v > 0 for v in s3) and s("dpl.RUKF.rms_3d_m") < s("dpl.SUKF.rms_3d_m")
    c.append(
        Claim(
            "Concl. 1",
            "RUKF beats SUKF in DPL, especially with large gross errors "
            "(situation #3 mean |error| smaller on every axis, and smaller 3D RMS)",
            "yes",
            "Δ#3 X/Y/Z = "
            + " / ".join(f"{v:+.3f}" for v in s3)
            + " m; RMS "
            + f("dpl.SUKF.rms_3d_m", ".3f")
            + " vs "
            + f("dpl.RUKF.rms_3d_m", ".3f")
            + " m",
            ok,
            _verdict(ok, "every #3 axis and the 3D RMS favour RUKF", "an axis or the RMS favours SUKF"),
        )
    )
    clean = s("rtk.static_orig.PL4.frac_clean_dv_gt_k0")
    flagged = s("rtk.static.PL4.frac_faulty_dv_gt_k0")
    ok = clean < 0.05 and flagged >= 0.5
    c.append(
        Claim(
            "3.3.1, Fig. 7",
            "Without errors PL4-PL1 Δv̄ stays below k0 = 2; the 5 cm "
            "errors push it above k0 (fraction of faulty epochs flagged)",
            "all clean < 2; errors detected",
            "clean >2: "
            + f("rtk.static_orig.PL4.frac_clean_dv_gt_k0", ".2f")
            + "; flagged: "
            + f("rtk.static.PL4.frac_faulty_dv_gt_k0", ".2f"),
            ok,
            _verdict(
                ok,
                "clean epochs stay below k0, faulty ones are flagged",
                f"{100 * clean:.0f} % of clean epochs exceed k0: Δv̄ of four independent Gaussian "
                f"residuals exceeds 2 with probability {100 * gauss_dv_exceed_prob(2.0, 4):.0f} %, so "
                "'all below 2' cannot come from white noise"
                if clean >= 0.05
                else f"only {100 * flagged:.0f} % of faulty epochs flagged",
            ),
        )
    )
    su, ru = s("rtk.static.SUKF.max_extra_faulty_m"), s("rtk.static.RUKF.max_extra_faulty_m")
    ok = su >= 0.005 and ru < 0.5 * su
    c.append(
        Claim(
            "Concl. 2, Fig. 8",
            "RUKF identifies the cm-level phase errors and removes the "
            "cm-level jump of SUKF (largest extra 3D error on faulty epochs)",
            "cm jump (SUKF) vs none (RUKF)",
            f("rtk.static.SUKF.max_extra_faulty_m", ".4f")
            + " vs "
            + f("rtk.static.RUKF.max_extra_faulty_m", ".4f")
            + " m",
            ok,
            _verdict(
                ok,
                "SUKF moves by ≥ 5 mm on faulty epochs, RUKF by less than half",
                f"SUKF moves by {1000 * su:.1f} mm only: fix-and-hold with a static position "
                f"(3D σ {s('rtk.static.SUKF.sigma_3d_first_fault_m'):.4f} m at the first error) leaves a "
                "5 cm error nothing to move; the same data in the per-epoch scheme (variant): SUKF "
                f"{1000 * s('rtk.static_prior.SUKF.max_extra_faulty_m'):.1f} mm, RUKF "
                f"{1000 * s('rtk.static_prior.RUKF.max_extra_faulty_m'):.1f} mm (fix rate "
                f"{s('rtk.static_prior.RUKF.fix_rate'):.3f}): a cm jump needs a position that follows "
                "each epoch, which the fix-and-hold mode the paper states for Fig. 8 does not have"
                + _q_fig8_reason(s)
                if su < 0.005
                else "RUKF moves by more than half of SUKF",
            ),
        )
    )
    # Fig. 9 in the paper's own scheme (previous coordinate as the prior, AR every epoch)
    p = "rtk015.prior"
    js, jr = s(f"{p}.SUKF.jump_m"), s(f"{p}.RUKF.jump_m")
    fs, fr = s(f"{p}.SUKF.fixed_at_fault"), s(f"{p}.RUKF.fixed_at_fault")
    ok = abs(js - 0.16) <= 0.05
    c.append(
        Claim(
            "3.3.1, Fig. 9",
            "SUKF jump at epoch 100 (0.15 m error), paper's AR scheme",
            "0.16 m",
            f(f"{p}.SUKF.jump_m", ".3f") + " m",
            ok,
            _verdict(
                ok,
                "within 5 cm of the paper's",
                f"the 0.15 m error moves SUKF by {js:.3f} m: with carried float ambiguities the update "
                f"shares the error between the position (prior σ {PRIOR_SIGMA_M:g} m) and PL4's "
                f"ambiguity (post-fit residual {s(f'{p}.SUKF.pl4_resid_at_fault_m'):.3f} m); the same "
                "holds for every prior σ of the sensitivity table",
            ),
        )
    )
    ok = abs(jr - 0.12) <= 0.05 and jr < js
    lit = "rtk015.prior_lit.RUKF"
    dv_r, w_r = s(f"{p}.RUKF.pl4_dv_at_fault"), s(f"{p}.RUKF.pl4_weight_at_fault")
    dv_l, w_l = s(f"{lit}.pl4_dv_at_fault"), s(f"{lit}.pl4_weight_at_fault")
    c.append(
        Claim(
            "3.3.1, Fig. 9",
            "RUKF jump at epoch 100, smaller than SUKF's, paper's AR scheme",
            "0.12 m",
            f(f"{p}.RUKF.jump_m", ".3f") + " m",
            ok,
            _verdict(
                ok,
                "near 0.12 m and below SUKF's",
                f"RUKF jumps {jr:.3f} m against SUKF's {js:.3f} m. A jump between zero and SUKF's "
                f"(the paper's 0.12 m is {100 * 0.12 / 0.16:.0f} % of its 0.16 m) needs PL4-PL1 "
                f"down-weighted, not removed: IGG-III weight strictly between 0 and 1, i.e. "
                f"{K0:g} < |Δv̄| < {K1:g}. The solver's RUKF (Δv̄ from the innovations) has "
                f"Δv̄ = {dv_r:.1f} > k1 at epoch 100, weight {w_r:.2f}: PL4 is removed and the "
                f"position stays. The paper's recipe taken literally (Δv̄ from the posterior "
                f"residuals) has Δv̄ = {dv_l:.2f} < k0, weight {w_l:.2f}: with four DDs and three "
                "coordinates the nominal update spreads the error evenly over the four "
                "standardized residuals (docs/algorithms.md §20), nothing is down-weighted and "
                f"RUKF jumps {s(f'{lit}.jump_m'):.3f} m, as SUKF. Neither statistic falls "
                "between k0 and k1",
            ),
        )
    )
    ok = fs == 0 and fr == 0
    c.append(
        Claim(
            "3.3.1, Fig. 9",
            "SUKF / RUKF fail AR at epoch 100 (median over seeds), paper's AR scheme",
            "both float",
            "fixed at 100: "
            + f(f"{p}.SUKF.fixed_at_fault", ".0f")
            + " / "
            + f(f"{p}.RUKF.fixed_at_fault", ".0f"),
            ok,
            "share of seeds fixed at epoch 100, SUKF / RUKF: "
            f"{s(f'{p}.SUKF.fixed_at_fault_share'):.2f} / {s(f'{p}.RUKF.fixed_at_fault_share'):.2f}; "
            "LAMBDA ratio at 100: "
            f"{s(f'{p}.SUKF.ratio_at_fault'):.1f} / {s(f'{p}.RUKF.ratio_at_fault'):.1f} (threshold 3); "
            "PL4-PL1 post-fit residual at 100: "
            f"{s(f'{p}.SUKF.pl4_resid_at_fault_m'):.3f} / {s(f'{p}.RUKF.pl4_resid_at_fault_m'):.3f} m"
            + (
                f", beyond the {FIX_RESIDUAL_K:g} σ residual test of the fixed solution: where the "
                "ratio test passes, that test refuses the fix (the paper names no test)"
                if ok
                else "; where the float update absorbs the error the ratio and residual tests pass"
            ),
        )
    )
    rs, rr = s(f"{p}.SUKF.refix_epochs"), s(f"{p}.RUKF.refix_epochs")
    ok = rr < rs
    c.append(
        Claim(
            "Concl. 3, Fig. 9",
            "Epochs to re-fix: RUKF re-converges faster than SUKF, paper's AR scheme",
            "12 vs 5",
            f(f"{p}.SUKF.refix_epochs", ".0f") + " vs " + f(f"{p}.RUKF.refix_epochs", ".0f"),
            ok,
            _verdict(
                ok,
                "RUKF re-fixes sooner",
                f"SUKF / RUKF re-fix after {rs:.0f} / {rr:.0f} epochs. "
                + (
                    "SUKF re-fixes on the first clean epoch after the error; a RUKF that also loses "
                    "the fix at epoch 100 cannot re-fix before that epoch, so 'faster' is impossible "
                    "unless SUKF needs two or more. "
                    if rs <= 1
                    else ""
                )
                + "The carried float ambiguities have been updated on 99 epochs of the same "
                "geometry and are stiffer than the coordinate prior, so the first clean epoch's "
                "phases pull the position back through them (PL4-PL1 innovation at epoch 101 "
                f"{s(f'{p}.SUKF.pl4_innov_after_m'):.3f} / {s(f'{p}.RUKF.pl4_innov_after_m'):.3f} m). "
                "Over the prior σ of the sensitivity table, SUKF / RUKF re-fix after "
                + "; ".join(
                    f"{s(f'{pk}.SUKF.refix_epochs'):.0f} / {s(f'{pk}.RUKF.refix_epochs'):.0f} "
                    f"(σ {sig:g} m, fix rate before 100 {s(f'{pk}.SUKF.fix_rate_before'):.2f})"
                    for sig, pk in ((sg, f"rtk015.{prior_label(sg)}") for sg in PRIOR_SIGMAS_SENS_M)
                )
                + ": a slow re-fix comes only with a prior so loose that the fix is not stable "
                "before the error either. Keeping the position's correlations with the "
                "ambiguities (σ² added instead of reset, the filter that counts each epoch's "
                "information once) leaves the float ambiguities as weak as the static geometry "
                "makes them: SUKF / RUKF / RUKF+PAR fix "
                + " / ".join(
                    f"{s(f'rtk015.prior_kept.{n}.fix_rate_before'):.2f}" for n in ("SUKF", "RUKF", "RUKF+PAR")
                )
                + " of the epochs before 100 and re-fix after "
                + " / ".join(f(f"rtk015.prior_kept.{n}.refix_epochs", ".0f") for n in ("SUKF", "RUKF"))
                + f" epochs ({s('rtk015.n_after'):.0f}: not within the run)."
                + _refix_bound_reason(s, js),
            ),
        )
    )
    par = s(f"{p}.RUKF+PAR.fix_rate")
    c.append(
        Claim(
            "Concl. 3, Fig. 9",
            "RUKF+PAR is fixed at every epoch, paper's AR scheme",
            "100 %",
            f(f"{p}.RUKF+PAR.fix_rate", ".3f")
            + " (SUKF "
            + f(f"{p}.SUKF.fix_rate", ".3f")
            + ", RUKF "
            + f(f"{p}.RUKF.fix_rate", ".3f")
            + ")",
            par >= 0.999,
            f"RUKF+PAR fixed at epoch 100 on a share {s(f'{p}.RUKF+PAR.fixed_at_fault_share'):.2f} of the "
            f"seeds; fix rate before epoch 100 {s(f'{p}.RUKF+PAR.fix_rate_before'):.3f}",
        )
    )
    xs, xr = s("rail.SUKF.max_abs_x_faulty_m"), s("rail.RUKF.max_abs_x_faulty_m")
    ok = xs >= 0.01 and xr < xs
    c.append(
        Claim(
            "3.3.2, Fig. 10",
            "Rail, 0.1 m errors: SUKF shows cm-level X jumps, RUKF no "
            "large fluctuation (max |X error| on faulty epochs)",
            "cm vs none",
            f("rail.SUKF.max_abs_x_faulty_m", ".3f")
            + " vs "
            + f("rail.RUKF.max_abs_x_faulty_m", ".3f")
            + " m",
            ok,
            _verdict(
                ok,
                "SUKF ≥ 1 cm, RUKF smaller",
                f"SUKF {xs:.3f} m, RUKF {xr:.3f} m "
                f"(clean epochs: SUKF {s('rail.SUKF.max_abs_x_clean_m'):.3f} m)",
            ),
        )
    )
    # Fig. 11 in the paper's own scheme; both tracks must follow the rail before epoch 50
    p = "rail015.prior"
    on_rail = [s(f"{p}.{n}.max_dev_before_m") < CONV_RTK_M for n in ("SUKF", "RUKF+PAR")]
    before = (
        f"; max dev. before 50: {f(f'{p}.SUKF.max_dev_before_m', '.3f')} / "
        f"{f(f'{p}.RUKF+PAR.max_dev_before_m', '.3f')} m"
    )
    after = s(f"{p}.SUKF.max_dev_after_m")
    re_ = "rail015.prior_re"
    literal = (
        ". With the ambiguities re-estimated at every epoch (Sec. 3.3.2's single-epoch PL-AR, "
        f"variant), SUKF's largest deviation after the error is {s(f'{re_}.SUKF.max_dev_after_m'):.3f} m "
        f"(at epoch 50: {s(f'{re_}.SUKF.dev_at_fault_m'):.3f} m) and RUKF+PAR is closer by "
        f"{s(f'{re_}.improvement_mean_dev_m'):.3f} m on average: there the float position is the "
        "previous coordinate, so the faulty epoch moves the track only through a fix"
    )
    ok = on_rail[0] and after >= 0.1
    c.append(
        Claim(
            "3.3.2, Fig. 11",
            "Rail, 0.15 m at epoch 50, paper's AR scheme: SUKF follows "
            f"the rail before the error (max deviation < {CONV_RTK_M:g} m) and leaves it "
            "by decimetres after it (max deviation ≥ 0.1 m)",
            "several dm",
            f(f"{p}.SUKF.max_dev_after_m", ".3f") + " m" + before,
            ok,
            _verdict(
                ok,
                "SUKF on the rail before, ≥ 0.1 m off after",
                "SUKF is off the rail before the error"
                if not on_rail[0]
                else f"SUKF's largest deviation after the error is {after:.3f} m (at epoch 50: "
                f"{s(f'{p}.SUKF.dev_at_fault_m'):.3f} m, the one-epoch effect of the 0.15 m error); it "
                f"re-fixes after {s(f'{p}.SUKF.refix_epochs'):.0f} epoch(s) on the carried ambiguities, "
                "which pull the coordinate back to the rail (as in Fig. 9). Decimetres and a "
                "divergence need the biased coordinate to be followed by the next epochs, which "
                "carried ambiguities stiffer than the coordinate prior prevent" + literal,
            ),
        )
    )
    imp = s(f"{p}.improvement_mean_dev_m")
    ok2: bool | None = (imp >= 0.02 and all(on_rail)) if math.isfinite(imp) else None
    c.append(
        Claim(
            "Concl. 3, Fig. 11",
            "Paper's AR scheme: RUKF+PAR is closer to the rail than "
            "SUKF by at least 2 cm (mean deviation from epoch 50), both on the rail "
            "before the error",
            "2–3 cm better",
            f(f"{p}.improvement_mean_dev_m", ".3f") + " m better" + before,
            ok2,
            _verdict(
                bool(ok2),
                "RUKF+PAR ≥ 2 cm closer",
                f"mean deviation from epoch 50, SUKF / RUKF+PAR: {s(f'{p}.SUKF.mean_dev_after_m'):.3f} / "
                f"{s(f'{p}.RUKF+PAR.mean_dev_after_m'):.3f} m"
                + ("" if all(on_rail) else "; a track is off the rail before the error")
                + f". SUKF's deviation at epoch 50 ({s(f'{p}.SUKF.dev_at_fault_m'):.3f} m) spread over "
                f"the {s(f'{p}.n_after'):.0f} epochs from 50 adds "
                f"{s(f'{p}.SUKF.dev_at_fault_m') / max(s(f'{p}.n_after'), 1.0):.4f} m to its mean; a "
                "2 cm gain needs SUKF about 2 cm off the rail on average after the error, i.e. a "
                f"track that does not come back, and SUKF re-fixes after "
                f"{s(f'{p}.SUKF.refix_epochs'):.0f} epoch(s)" + literal,
            ),
        )
    )
    ekf = [s(f"dpl_init.EKF.{o:g}.rms_3d_m") for o in INIT_OFFSETS_M]
    ukf = [s(f"dpl_init.UKF.{o:g}.rms_3d_m") for o in INIT_OFFSETS_M]
    rek = [s(f"rtk_init.EKF.{o:g}.rms_3d_m") for o in INIT_OFFSETS_M]
    ruk = [s(f"rtk_init.UKF.{o:g}.rms_3d_m") for o in INIT_OFFSETS_M]
    ok = ukf[-1] < ekf[-1] and ruk[-1] < rek[-1]
    rmin = s("geom.min_range_m")
    lin1 = INIT_OFFSETS_M[-1] ** 2 / (2.0 * rmin) if rmin > 0 else math.nan
    lin_after = ukf[-1] ** 2 / (2.0 * rmin) if rmin > 0 else math.nan
    c.append(
        Claim(
            "1 (Li et al. [27])",
            "UKF depends less on the initial coordinates than EKF (3D RMS with 1 m offset, DPL / RTK)",
            "UKF better",
            f"DPL {ekf[-1]:.3f} vs {ukf[-1]:.3f} m; RTK {rek[-1]:.3f} vs {ruk[-1]:.3f} m",
            ok,
            _verdict(
                ok,
                "UKF's RMS smaller in both",
                f"EKF − UKF 3D RMS: DPL {ekf[-1] - ukf[-1]:+.3f} m, RTK {rek[-1] - ruk[-1]:+.3f} m. The "
                "linearization error of a range at an offset d is at most d²/(2r): with the shortest "
                f"range r = {rmin:.2f} m it is {lin1:.3f} m for d = {INIT_OFFSETS_M[-1]:g} m before the "
                f"first update and {lin_after:.4f} m once the EKF, which re-linearizes every epoch, is "
                f"within the DPL error ({ukf[-1]:.3f} m), far under the code noise: the UKF's "
                "unscented transform has nothing left to win in DPL. In RTK a known point "
                f"{INIT_OFFSETS_M[-1]:g} m off ({INIT_OFFSETS_M[-1] / PL_WAVELENGTH_M:.1f} cycles) leads "
                "neither filter to the right integers (convergence epoch: EKF "
                f"{s(f'rtk_init.EKF.{INIT_OFFSETS_M[-1]:g}.conv_epoch'):.0f}, UKF "
                f"{s(f'rtk_init.UKF.{INIT_OFFSETS_M[-1]:g}.conv_epoch'):.0f}; nan: never), so which "
                "one ends nearer is the luck of the wrong integers",
            ),
        )
    )
    return c


__all__ = ["PAPER_DPL_EPOCHS", "PAPER_TABLE1", "Claim", "build_claims"]
