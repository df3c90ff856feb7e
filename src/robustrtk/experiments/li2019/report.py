"""The Markdown report of the Li et al. (2019) reproduction: :class:`Report`, the table
cells (:func:`format_cell`), the result tables, the claims and the explanation of where
and why the numbers differ from the paper's (:func:`write_report`)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from robustrtk.eval.situations import ALL_LABEL
from robustrtk.experiments.li2019.claims import PAPER_DPL_EPOCHS, PAPER_TABLE1, Claim
from robustrtk.experiments.li2019.metrics import (
    AR_MODES_015,
    AR_MODES_RAIL,
    CONV_DPL_M,
    CONV_RTK_M,
    gauss_dv_exceed_prob,
    impulse_share_bound,
    stat_value,
)
from robustrtk.experiments.li2019.schemes import (
    DEFAULT_SLIP,
    FIX_RESIDUAL_K,
    INIT_OFFSETS_M,
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

#: Table labels of the AR modes.
MODE_LABEL = {
    "prior": "paper's scheme (prior)",
    "prior_lit": "paper's scheme, literal Δv̄ (posterior)",
    "prior_poly": "paper's scheme, default slip detectors",
    "prior_kept": "paper's scheme, correlations kept (σ² added)",
    "hold": "fix-and-hold",
    "cont": "continuous AR",
    "inst": "single-epoch AR",
    "prior_re": "paper's scheme, ambiguities re-estimated",
}


@dataclass
class Report:
    """What :func:`run_li2019` wrote and computed."""

    out_dir: Path
    report_path: Path
    results_path: Path
    stats: dict[str, dict[str, Any]]
    per_run: list[dict[str, float]]
    claims: list[Claim]
    figures: list[Path]
    elapsed_s: float
    seeds: list[int] = field(default_factory=list)


def format_cell(agg: Mapping[str, Any], fmt: str, runs: int) -> str:
    """One table cell: the value (one run) or ``median [p5, p95]`` (several runs)."""

    def one(v: float) -> str:
        if v is None or not math.isfinite(v):
            return "–"
        txt = format(int(round(v)), "d") if fmt == "d" else format(v, fmt)
        # no "-0.000": a value that rounds to zero is shown without a sign
        return txt[1:] if txt.startswith("-") and float(txt) == 0 else txt

    if runs == 1:
        return one(agg["median"])
    return f"{one(agg['median'])} [{one(agg['p5'])}, {one(agg['p95'])}]"


def _md_table(headers: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    lines = [
        "| " + " | ".join(h.replace("|", "\\|") for h in headers) + " |",
        "|" + "|".join("---" for _ in headers) + "|",
    ]
    lines += ["| " + " | ".join(c.replace("|", "\\|") for c in r) + " |" for r in rows]
    return "\n".join(lines)


def dd_dop(tx_m: Mapping[str, Any], ref: str, pos_m: Any, base_m: Any) -> tuple[float, float, float]:
    r"""Per-axis dilution of precision (X, Y, Z) of one epoch's DD ranges at ``pos_m``.

    :math:`\mathrm{DOP}_a = \sqrt{[(H^T C^{-1} H)^{-1}]_{aa}}` with :math:`H` the DD unit-vector
    differences (transmitter minus reference, rover side) and :math:`C = I + 11^T` the
    correlation of DDs that share the reference (unit single-difference variance): a DD
    σ of ``σ_SD`` gives the single-epoch position σ ``DOP_a σ_SD`` per axis.
    """
    import numpy as np

    x = np.asarray(pos_m, float)

    def u(t: str) -> Any:
        d = x - np.asarray(tx_m[t], float)
        return d / np.linalg.norm(d)

    others = [t for t in tx_m if t != ref]
    H = np.array([u(t) - u(ref) for t in others])
    C = np.eye(len(others)) + np.ones((len(others), len(others)))
    Q = np.linalg.inv(H.T @ np.linalg.solve(C, H))
    d = np.sqrt(np.diag(Q))
    return float(d[0]), float(d[1]), float(d[2])


def _calibration(stats: Mapping[str, dict[str, Any]], runs: int) -> str:
    """The simulated room against what the paper states: a table with the paper's numbers
    beside ours (scenario values and run-derived statistics)."""
    from robustrtk.sim.scenario import ROOM_SIZE_M, load_scenario

    def f(key: str, fmt: str = ".3f") -> str:
        return format_cell(stats[key], fmt, runs)

    dpl = load_scenario("li2019_dpl_static")
    rtk = load_scenario("li2019_rtk_static")
    rail = load_scenario("li2019_rtk_rail")
    tx = dict(dpl.transmitters)
    z_tx = [p[2] for p in tx.values()]
    dop = dd_dop(tx, dpl.reference, dpl.trajectory.start_m, dpl.base_position_m)
    rv = rtk.noise_of("rover")
    sd_code = (2 * (dpl.noise_of("rover").code_sigma_m ** 2 + dpl.multipath.code_sigma_m**2)) ** 0.5
    sd_phase = (2 * (rv.phase_sigma_m**2 + rtk.multipath.phase_sigma_m**2)) ** 0.5
    assert rail.trajectory.end_m is not None
    rail_len = (
        sum((a - b) ** 2 for a, b in zip(rail.trajectory.end_m, rail.trajectory.start_m, strict=True)) ** 0.5
    )
    rows = [
        [
            "Room",
            "10 m × 7 m × 4 m, origin at the centre",
            " × ".join(f"{v:g} m" for v in ROOM_SIZE_M),
            "as stated",
        ],
        [
            "Transmitters",
            "five PLs on the ceiling (GSG-L1, GPS L1 C/A), surveyed by total station; positions not listed",
            f"{len(tx)} ({', '.join(tx)}) at z = {min(z_tx):.2f}–{max(z_tx):.2f} m under the +2 m ceiling, "
            "spread over the room",
            "layout assumed (Fig. 2 is a photograph)",
        ],
        ["Wavelength", "GPS L1", f"{dpl.wavelength_m:.4f} m", "as stated"],
        ["DPL epochs", "≈ 11,000 (Table 1 rows sum to 10,865)", f"{dpl.n_epochs}", "as stated"],
        ["DPL DDs", "PL1, PL4, PL5, PL8 − PL6", f"reference {dpl.reference}", "as stated"],
        [
            "DPL 10 m errors",
            "≈ 20 epochs, some DDs",
            f"{dpl.random_gross[0].count} epochs, one random DD each",
            "as stated",
        ],
        [
            "DPL initial coordinates",
            "within 0.1 m",
            f"±{dpl.initial_position_error_m:g} m per axis",
            "as stated",
        ],
        [
            "RTK epochs (static, rail)",
            "270, 270",
            f"{rtk.n_epochs}, {rail.n_epochs}",
            "as stated",
        ],
        ["RTK DDs", "PL4, PL5, PL6, PL8 − PL1", f"reference {rtk.reference}", "as stated"],
        [
            "Code noise",
            "'approximate to GPS L1' (no number); Fig. 4 residuals are a plot",
            f"{dpl.noise_of('rover').code_sigma_m:g} m white + {dpl.multipath.code_sigma_m:g} m Gauss-Markov "
            f"(τ {dpl.multipath.code_tau_s:g} s) per receiver and link; SD σ {sd_code:.2f} m",
            "assumed (GPS L1 C/A level)",
        ],
        [
            "Code anomalies",
            "Table 1: #1 / #2 / #3 = 3693 / 6794 / 378 epochs over all DDs",
            "bursts of 0.6–2.5 m, see Table 1 above: "
            + " / ".join(f(f"dpl.table1.{ALL_LABEL}.s{k}", "d") for k in (1, 2, 3)),
            "burst rate and sizes chosen to resemble Table 1",
        ],
        [
            "Phase noise",
            "Fig. 7: 'most of the posterior residuals are less than 5 mm' (PL4-PL1, clean)",
            f"{rv.phase_sigma_m * 1000:g} mm white + {rtk.multipath.phase_sigma_m * 1000:g} mm Gauss-Markov; "
            f"SD σ {sd_phase * 1000:.1f} mm; clean PL4-PL1 |residual| median "
            + f("rtk.static_orig.PL4.median_abs_resid_clean_m", ".4f")
            + " m, share < 5 mm "
            + f("rtk.static_orig.PL4.frac_resid_lt_5mm", ".2f"),
            "run-derived; holds when the share is above 0.5",
        ],
        [
            "Geometry (static rover)",
            "not stated; all PLs on the ceiling",
            f"DD DOP X / Y / Z = {dop[0]:.2f} / {dop[1]:.2f} / {dop[2]:.2f}: one epoch's code gives "
            f"σ ≈ {dop[0] * sd_code:.2f} / {dop[1] * sd_code:.2f} / {dop[2] * sd_code:.2f} m",
            "follows from a ceiling layout",
        ],
        [
            "DPL accuracy, clean epochs",
            "decimetre level (Li et al. [27], good environment)",
            "SUKF mean |error| X / Y / Z in #1: "
            + " / ".join(f(f"dpl.fig6.SUKF.s1.{a}") for a in "XYZ")
            + " m",
            "run-derived",
        ],
        [
            "RTK accuracy",
            "centimetre level",
            "fix-and-hold static 3D RMS SUKF " + f("rtk.static.SUKF.rms_3d_m", ".4f") + " m",
            "run-derived",
        ],
        [
            "Rail",
            "straight fixed rail, one end to the other, 270 epochs; length and speed not stated",
            f"{rail_len:.1f} m at {rail.trajectory.speed_m_s:g} m/s",
            "assumed",
        ],
    ]
    return _md_table(["Quantity", "Paper", "Simulation", "Status"], rows)


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


def _differences(stats: Mapping[str, dict[str, Any]], runs: int) -> list[str]:
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


def write_report(
    out: Path,
    stats: Mapping[str, dict[str, Any]],
    claims: Sequence[Claim],
    figs: Mapping[str, str],
    runs: int,
    seeds: Sequence[int],
    n_dpl: int,
    elapsed_s: float,
    quick: bool,
) -> Path:
    """Write ``report.md`` (tables, figure links, claims, differences) to ``out``; return
    its path."""

    def f(key: str, fmt: str = ".3f") -> str:
        return format_cell(stats[key], fmt, runs)

    md: list[str] = []
    md.append("# Li et al. (2019) indoor pseudolite RUKF + PAR — simulated reproduction\n")
    md.append(
        f"Runs: {runs} (seeds {seeds[0]}–{seeds[-1]}); "
        + ("values are single-run numbers." if runs == 1 else "cells are `median [5 %, 95 %]` over runs.")
        + f" DPL epochs: {n_dpl}. Wall time: {elapsed_s:.0f} s."
        + (" **Quick mode: shortened experiments.**" if quick else "")
        + "\n"
    )
    md.append(
        "Schemes: SUKF = UKF without robust weighting; RUKF = UKF with Δv̄ and IGG-III "
        "(k0 = 2, k1 = 8); RUKF+PAR = RUKF with partial AR ranked by Δv̄. Errors are in "
        "the room frame (X, Y, Z), metres. Figures show the first seed.\n"
    )
    md.append("## The simulated room against the paper's stated setting\n")
    md.append(
        "What the paper states beside what the simulation uses; run-derived cells are "
        "statistics of this run. The scenario follows every number the paper gives; where it "
        "gives none (transmitter positions, noise levels, rail length) the value is assumed "
        "and marked so. The robust estimator and the claims' thresholds were not tuned.\n"
    )
    md.append(_calibration(stats, runs) + "\n")
    # Table 1
    md.append("## DPL static — Table 1 (epochs per situation, RUKF Δv̄)\n")
    labels = [k.split(".")[2] for k in stats if k.startswith("dpl.table1.") and k.endswith(".s1")]
    rows = []
    for lab in labels:
        pap = PAPER_TABLE1.get(lab)
        rows.append(
            [lab]
            + [f(f"dpl.table1.{lab}.s{k}", "d") for k in (1, 2, 3)]
            + [" / ".join(map(str, pap)) if pap else "–"]
        )
    md.append(
        _md_table(["DD", "Situation #1", "Situation #2", "Situation #3", "Paper #1 / #2 / #3"], rows) + "\n"
    )
    md.append(f"![Fig. 4]({figs['fig4_dpl_residuals_dv.png']})\n")
    md.append("## DPL static — Fig. 5 and Fig. 6\n")
    rows = [
        [name, f(f"dpl.{name}.rms_3d_m")] + [f(f"dpl.{name}.mean_abs_{a}_m") for a in "XYZ"]
        for name in ("SUKF", "RUKF")
    ]
    md.append(
        _md_table(["Scheme", "3D RMS (m)", "mean |X| (m)", "mean |Y| (m)", "mean |Z| (m)"], rows) + "\n"
    )
    md.append(f"![Fig. 5]({figs['fig5_dpl_errors.png']})\n")
    rows = [
        [name, f"#{k}"] + [f(f"dpl.fig6.{name}.s{k}.{a}") for a in "XYZ"]
        for k in (1, 2, 3)
        for name in ("SUKF", "RUKF")
    ]
    md.append(_md_table(["Scheme", "Situation", "mean |X| (m)", "mean |Y| (m)", "mean |Z| (m)"], rows) + "\n")
    md.append(f"![Fig. 6]({figs['fig6_dpl_situations.png']})\n")
    # RTK static
    md.append("## RTK static, 5 cm errors on PL4 — Fig. 7 and Fig. 8\n")
    rows = [
        [var_name]
        + [
            f(f"rtk.{var}.PL4.{m}", fm)
            for m, fm in (
                ("median_abs_resid_clean_m", ".4f"),
                ("max_abs_dv_clean", ".2f"),
                ("frac_clean_dv_gt_k0", ".3f"),
                ("frac_faulty_dv_gt_k0", ".3f"),
            )
        ]
        for var, var_name in (("static_orig", "Original (errors removed)"), ("static", "With 5 cm errors"))
    ]
    md.append(
        _md_table(
            [
                "PL4-PL1 (RUKF)",
                "median |resid| clean (m)",
                "max |Δv̄| clean",
                "frac clean |Δv̄|>k0",
                "frac faulty |Δv̄|>k0",
            ],
            rows,
        )
        + "\n"
    )
    md.append("In the original data the faulty-epoch column refers to the same epochs without the error.\n")
    md.append(f"![Fig. 7]({figs['fig7_rtk_pl4_dv.png']})\n")
    rows = [
        [
            n,
            f(f"rtk.static.{n}.max_extra_faulty_m", ".4f"),
            f(f"rtk.static.{n}.rms_3d_m", ".4f"),
            f(f"rtk.static.{n}.fix_rate"),
        ]
        for n in ("SUKF", "RUKF")
    ]
    md.append(
        _md_table(["Scheme", "max extra 3D error on faulty epochs (m)", "3D RMS (m)", "fix rate"], rows)
        + "\n"
    )
    md.append(f"![Fig. 8]({figs['fig8_rtk_static_errors.png']})\n")
    # 0.15 m
    md.append("## RTK static, 0.15 m on PL4 at epoch 100 — Fig. 9\n")
    md.append(
        "The 0.15 m error is added to PL4's phase on epoch 100 only: the paper adds it \"on "
        'the 100th epoch" and reports a jump there and re-fixing later, which a persisting '
        "0.15 m (0.79 cycle, not an integer) step would rule out. AR mode of the claims: "
        "the paper's own scheme (Sec. 2.1, `ar_scheme = prior`, docs/algorithms.md §20): "
        f"known-point start, then each epoch's float solution takes the previous epoch's "
        f"coordinate as its prior (σ = {PRIOR_SIGMA_M:g} m, the known-point accuracy the paper "
        "states), the float ambiguities carried, AR (LAMBDA, ratio 3) at every epoch, no "
        f"hold, and a fix accepted only when its DD phase residuals are within {FIX_RESIDUAL_K:g} σ "
        "(RTKLIB's test; the paper states none). Every RTK scheme detects cycle slips from the "
        f"loss-of-lock flags only (`slip = {RTK_SLIP}`): the paper adds its errors to the DD phase "
        "the estimator uses, and the simulated phase has no slips. Variants: the paper's scheme "
        "with the paper's RUKF recipe taken literally (Δv̄ from the posterior residuals of the "
        "nominal update, one re-update; the solver's `igg3` computes Δv̄ from the standardized "
        "innovations, docs/algorithms.md §4), the paper's scheme "
        f"with the solver's default detectors (`slip = {DEFAULT_SLIP}`, whose polynomial fit takes "
        "the 0.79-cycle error for a non-integer slip and, without a robust policy, resets PL4's "
        "ambiguity), fix-and-hold (the mode the paper states for Fig. 8 on the same data) and "
        "continuous AR (the filter's own position covariance carried on, AR at every epoch, "
        "no hold). Δv̄ and weight: PL4-PL1's error-discriminant statistic at epoch 100 and the "
        "weight 1/λ its IGG-III factor λ gives it (1: kept, 0: rejected; SUKF computes Δv̄ but "
        "keeps every weight at 1).\n"
    )
    md.append(
        "Jump = 3D error at epoch 100 minus at epoch 99. Epochs to re-fix = first epoch "
        "≥ 100 with fixed or partial status, minus 100 (0: fixed at epoch 100; a run that never "
        "re-fixes counts as the epochs left after 100, so the median ranks it slowest). "
        "3D σ = square root of the trace of the solution's position covariance.\n"
    )
    rows = []
    for h in AR_MODES_015:
        for n in ("SUKF", "RUKF", "RUKF+PAR"):
            p = f"rtk015.{h}.{n}"
            rows.append(
                [
                    n,
                    MODE_LABEL[h],
                    f(f"{p}.err_before_m"),
                    f(f"{p}.sigma_before_m", ".4f"),
                    f(f"{p}.jump_m"),
                    f(f"{p}.refix_epochs", ".0f"),
                    f(f"{p}.fixed_at_fault", ".0f"),
                    f(f"{p}.fix_rate_before"),
                    f(f"{p}.fix_rate"),
                    f(f"{p}.max_3d_after_m"),
                    f(f"{p}.pl4_dv_at_fault", ".1f"),
                    f(f"{p}.pl4_weight_at_fault", ".2f"),
                ]
            )
    md.append(
        _md_table(
            [
                "Scheme",
                "AR mode",
                "3D error at 99 (m)",
                "3D σ at 99 (m)",
                "Jump (m)",
                "Epochs to re-fix",
                "Fixed at 100",
                "Fix rate before 100",
                "Fix rate",
                "max 3D error from 100 (m)",
                "PL4 Δv̄ at 100",
                "PL4 weight at 100",
            ],
            rows,
        )
        + "\n"
    )
    md.append(
        "Sensitivity of the paper's scheme to the prior σ (not a paper setting; the claims use "
        f"σ = {PRIOR_SIGMA_M:g} m). Fixed at 100 is the share of seeds.\n"
    )
    rows = []
    for sig in PRIOR_SIGMAS_SENS_M:
        h = prior_label(sig)
        for n in ("SUKF", "RUKF", "RUKF+PAR"):
            p = f"rtk015.{h}.{n}"
            vals = [v for v in stats[f"{p}.fixed_at_fault"]["values"] if v is not None]
            rows.append(
                [
                    f"{sig:g}",
                    n,
                    f(f"{p}.err_before_m"),
                    f(f"{p}.jump_m"),
                    f"{sum(vals) / len(vals):.2f}" if vals else "–",
                    f(f"{p}.refix_epochs", ".0f"),
                    f(f"{p}.fix_rate_before"),
                    f(f"{p}.fix_rate"),
                    f(f"{p}.max_3d_after_m"),
                ]
            )
    md.append(
        _md_table(
            [
                "Prior σ (m)",
                "Scheme",
                "3D error at 99 (m)",
                "Jump (m)",
                "Fixed at 100 (share)",
                "Epochs to re-fix",
                "Fix rate before 100",
                "Fix rate",
                "max 3D error from 100 (m)",
            ],
            rows,
        )
        + "\n"
    )
    qs = [q for q in Q_SIGMAS_M if f"rtk015.q@{q:g}.SUKF.jump_m" in stats]
    if qs:
        md.append(
            "Sensitivity to the process noise (not a paper setting): the paper's state function "
            "is the identity with a process noise Q (its Eq. 3) whose value it does not state. "
            "Fix-and-hold (the mode it states for Fig. 8), the coordinate a random walk of σ per "
            f"1 s epoch (`dynamics = kinematic`, `kinematic_model = random-walk`, `sigma_vel_m_s = σ`), "
            f"the {FIX_RESIDUAL_K:g} σ residual test of a fix, on Fig. 8's data (largest extra 3D "
            "error on the epochs with 5 cm errors) and Fig. 9's (0.15 m at epoch 100). Fixed at "
            "100 is the share of seeds.\n"
        )
        rows = []
        for q in qs:
            a, b = f"rtk.static_q@{q:g}", f"rtk015.q@{q:g}"
            shares = []
            for n in ("SUKF", "RUKF"):
                vals = [v for v in stats[f"{b}.{n}.fixed_at_fault"]["values"] if v is not None]
                shares.append(f"{sum(vals) / len(vals):.2f}" if vals else "–")
            rows.append(
                [
                    f"{q:g}",
                    f(f"{a}.SUKF.max_extra_faulty_m", ".4f"),
                    f(f"{a}.RUKF.max_extra_faulty_m", ".4f"),
                    f(f"{b}.SUKF.jump_m"),
                    f(f"{b}.RUKF.jump_m"),
                    " / ".join(shares),
                    f(f"{b}.SUKF.refix_epochs", ".0f"),
                    f(f"{b}.RUKF.refix_epochs", ".0f"),
                    f(f"{b}.RUKF+PAR.fix_rate"),
                    f(f"{b}.SUKF.fix_rate_before"),
                ]
            )
        md.append(
            _md_table(
                [
                    "σ (m per epoch)",
                    "Fig. 8 SUKF extra (m)",
                    "Fig. 8 RUKF extra (m)",
                    "Fig. 9 SUKF jump (m)",
                    "Fig. 9 RUKF jump (m)",
                    "Fixed at 100 SUKF / RUKF",
                    "SUKF epochs to re-fix",
                    "RUKF epochs to re-fix",
                    "RUKF+PAR fix rate",
                    "SUKF fix rate before 100",
                ],
                rows,
            )
            + "\n"
        )
    md.append(f"![Fig. 9, paper's scheme]({figs['fig9_rtk_015_prior.png']})\n")
    md.append(f"![Fig. 9, paper's scheme, literal Δv̄]({figs['fig9_rtk_015_prior_lit.png']})\n")
    md.append(f"![Fig. 9, paper's scheme, default slip detectors]({figs['fig9_rtk_015_prior_poly.png']})\n")
    md.append(f"![Fig. 9, paper's scheme, correlations kept]({figs['fig9_rtk_015_prior_kept.png']})\n")
    md.append(f"![Fig. 9, fix-and-hold]({figs['fig9_rtk_015_hold.png']})\n")
    md.append(f"![Fig. 9, continuous AR]({figs['fig9_rtk_015_cont.png']})\n")
    # rail
    md.append("## RTK kinematic rail — Fig. 10 and Fig. 11\n")
    md.append("Fig. 10: 0.1 m errors on PL4 on some epochs, fix-and-hold as in the paper.\n")
    rows = [
        [n, f(f"rail.{n}.max_abs_x_faulty_m"), f(f"rail.{n}.max_abs_x_clean_m"), f(f"rail.{n}.rms_3d_m")]
        for n in ("SUKF", "RUKF")
    ]
    md.append(
        _md_table(["Scheme (0.1 m errors)", "max |X| faulty (m)", "max |X| clean (m)", "3D RMS (m)"], rows)
        + "\n"
    )
    md.append(f"![Fig. 10]({figs['fig10_rail_x_error.png']})\n")
    md.append(
        "Fig. 11: 0.15 m on PL4 at epoch 50 only. The claims use the paper's scheme, as for "
        'Fig. 9 ("the initial coordinate value of the current epoch is usually based on the '
        'coordinates of the previous epoch", PL-AR at every epoch; identity state function). '
        "Variants: the paper's scheme with the ambiguities re-estimated at every epoch (Sec. "
        '3.3.2 says "the single-epoch PL-AR model is used during the successive epochs"; each '
        "epoch's float solution then has the previous coordinate with σ = 0.1 m and new "
        "ambiguities), single-epoch AR in the filter scheme (new ambiguities at every epoch, each "
        "epoch starting from the previous fixed solution and its covariance) and "
        "fix-and-hold. Deviation = horizontal distance from the straight rail.\n"
    )
    rows = []
    for v in AR_MODES_RAIL:
        for n in ("SUKF", "RUKF+PAR"):
            p = f"rail015.{v}.{n}"
            rows.append(
                [
                    n,
                    MODE_LABEL[v],
                    f(f"{p}.mean_dev_before_m"),
                    f(f"{p}.max_dev_before_m"),
                    f(f"{p}.mean_dev_after_m"),
                    f(f"{p}.max_dev_after_m"),
                    f(f"{p}.fix_rate"),
                ]
            )
    md.append(
        _md_table(
            [
                "Scheme (0.15 m at 50)",
                "AR mode",
                "mean dev. before 50 (m)",
                "max dev. before 50 (m)",
                "mean dev. from 50 (m)",
                "max dev. from 50 (m)",
                "fix rate",
            ],
            rows,
        )
        + "\n"
    )
    md.append(
        "Largest 3D distance between the SUKF and RUKF+PAR positions: "
        + f("rail015.inst.max_pos_diff_m", ".4f")
        + " m (single-epoch AR), "
        + f("rail015.hold.max_pos_diff_m", ".4f")
        + " m (fix-and-hold).\n"
    )
    md.append(f"![Fig. 11, paper's scheme]({figs['fig11_rail_track_prior.png']})\n")
    md.append(
        f"![Fig. 11, paper's scheme, ambiguities re-estimated]({figs['fig11_rail_track_prior_re.png']})\n"
    )
    md.append(f"![Fig. 11, single-epoch AR]({figs['fig11_rail_track_inst.png']})\n")
    md.append(f"![Fig. 11, fix-and-hold]({figs['fig11_rail_track_hold.png']})\n")
    # EKF / UKF
    md.append("## EKF vs UKF with offset initial coordinates\n")
    md.append(
        f"Convergence epoch: first epoch after which the 3D error stays below "
        f"{CONV_DPL_M} m (DPL, first 1000 epochs of the static data) / {CONV_RTK_M} m (RTK). "
        "No robust weighting; the RTK runs "
        "use the fault-free static data and an initial position sigma equal to the "
        "offset (at least 0.1 m).\n"
    )
    rows = []
    for mode, name in (("dpl_init", "DPL"), ("rtk_init", "RTK")):
        for o in INIT_OFFSETS_M:
            rows.append(
                [name, f"{o:g}"]
                + [
                    f(f"{mode}.{fl}.{o:g}.{m}", fm)
                    for fl in ("EKF", "UKF")
                    for m, fm in (("rms_3d_m", ".4f"), ("conv_epoch", ".0f"))
                ]
            )
    md.append(
        _md_table(
            ["Mode", "Offset (m)", "EKF 3D RMS (m)", "EKF conv. epoch", "UKF 3D RMS (m)", "UKF conv. epoch"],
            rows,
        )
        + "\n"
    )
    # memory sensitivity
    md.append("## Filter memory — sensitivity, not a paper setting\n")
    md.append(
        "The DPL static data solved again with the solver's random-walk position model "
        f"(σ = {Config().estimator.sigma_vel_m_s:g} m/s, its default) instead of the static model "
        f"(q = {Config().estimator.q_static_m2_s:g} m²/s). The paper gives an identity state "
        "function but no process noise. Situations are RUKF's in each model. Not used in "
        "the claims.\n"
    )
    rows = [
        [
            lab,
            f(f"{pre}.SUKF.sigma_3d_end_m", ".4f"),
            f(f"{pre}.SUKF.rms_3d_m"),
            f(f"{pre}.RUKF.rms_3d_m"),
            f(f"{pre}.improvement.s2.max_axis_m"),
            f(f"{pre}.improvement.s3.max_axis_m"),
        ]
        for pre, lab in (("dpl", "static (claims)"), ("dpl_rw", "random walk"))
    ]
    md.append(
        _md_table(
            [
                "Position model",
                "SUKF 3D σ, last epoch (m)",
                "SUKF 3D RMS (m)",
                "RUKF 3D RMS (m)",
                "#2 gain, largest axis (m)",
                "#3 gain, largest axis (m)",
            ],
            rows,
        )
        + "\n"
    )
    # claims
    md.append("## Claims\n")
    rows = [
        [
            c.section,
            c.claim,
            c.paper,
            c.ours,
            "yes" if c.holds else ("n/a" if c.holds is None else "no"),
            c.why,
        ]
        for c in claims
    ]
    n_hold = sum(1 for c in claims if c.holds)
    md.append(f"{n_hold} of {len(claims)} claims hold (verdicts on the median over seeds).\n")
    head = "Ours (median)" if runs == 1 else "Ours (median [5 %, 95 %])"
    md.append(_md_table(["Section", "Finding", "Paper", head, "Holds", "Why (this run)"], rows) + "\n")
    md.append("## Why our numbers differ\n")
    md.extend(_differences(stats, runs))
    path = out / "report.md"
    path.write_text("\n".join(md), encoding="utf-8")
    return path


__all__ = ["MODE_LABEL", "Report", "format_cell", "write_report"]
