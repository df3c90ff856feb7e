"""Per-run metrics of Li et al. (2019) and their aggregation over runs: errors against
the truth, jumps, epochs to re-fix, convergence epochs, rail deviations, every statistic
of one seed (:func:`seed_stats`) and the median and percentiles over seeds
(:func:`aggregate`)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from robustrtk.core import FloatArray
from robustrtk.eval.situations import epoch_situations, situation_counts, situation_mean_abs_errors
from robustrtk.experiments.li2019.schemes import (
    INIT_OFFSETS_M,
    K0,
    PRIOR_SIGMA_M,
    PRIOR_SIGMAS_SENS_M,
    Q_SIGMAS_M,
    RAIL_FAULT_EPOCH,
    STATIC_FAULT_EPOCH,
    Raw,
    prior_label,
)
from robustrtk.io.solution import DiagTable
from robustrtk.sim.scenario import load_scenario

#: Convergence thresholds on the 3D error (m).
CONV_DPL_M, CONV_RTK_M = 0.5, 0.05
#: Solution statuses counted as fixed.
FIXED = ("fixed", "partial")
#: AR modes of the 0.15 m static test (primary first: the paper's prior scheme;
#: ``prior_lit``: the same with the paper's literal RUKF recipe; ``prior_poly``: the same
#: with the solver's default slip detectors; ``prior_kept``: the same with the position's
#: correlations kept, σ² added to its covariance) and of the 0.15 m rail test (``prior_re``:
#: the paper's scheme with new ambiguities at every epoch, Sec. 3.3.2's "single-epoch PL-AR").
AR_MODES_015 = ("prior", "prior_lit", "prior_poly", "prior_kept", "hold", "cont")
AR_MODES_RAIL = ("prior", "prior_re", "inst", "hold")


def pos_error_m(raw: Raw) -> FloatArray:
    """Solution minus truth (T, 3) (solutions and truth share the simulated epochs)."""
    t = raw["t_s"]
    idx = np.searchsorted(raw["truth_t_s"], t)
    return np.asarray(raw["pos_m"] - raw["truth_m"][idx], dtype=float)


def error_3d_m(raw: Raw) -> FloatArray:
    """3D error per epoch (m)."""
    return np.asarray(np.linalg.norm(pos_error_m(raw), axis=1), dtype=float)


def diag_table(raw: Raw) -> DiagTable:
    """The raw diagnostics as a :class:`DiagTable`."""
    d = raw["diag"]
    return DiagTable(
        t_s=d["t_s"],
        dd=d["dd"],
        innovation=d["innovation"],
        residual=d["residual"],
        std_residual=d["std_residual"],
        dv=d["dv"],
        factor=d["factor"],
        situation=d["situation"],
    )


def dd_series(raw: Raw, label: str, field_name: str) -> FloatArray:
    """Per-epoch value of one DD (NaN where absent), aligned with ``raw['t_s']``."""
    d = raw["diag"]
    sel = d["dd"] == label
    out = np.full(raw["t_s"].size, np.nan)
    idx = np.searchsorted(raw["t_s"], d["t_s"][sel])
    ok = idx < out.size
    out[idx[ok]] = d[field_name][sel][ok]
    return out


def fault_epochs(raw: Raw, n: int) -> npt.NDArray[np.bool_]:
    """Mask of the first ``n`` epochs that carry a scheduled gross error."""
    m = np.zeros(n, dtype=bool)
    ep = raw["faults"]["epoch"]
    kind = raw["faults"]["kind"]
    ep = ep[(kind == "gross") & (ep < n)] if kind.size else ep[ep < n]
    m[ep] = True
    return m


def jump_m(d3: FloatArray, k: int) -> float:
    """3D error at epoch ``k`` minus at epoch ``k - 1`` (m)."""
    return float(d3[k] - d3[k - 1])


def epochs_to_refix(status: Sequence[str] | npt.NDArray[Any], k: int) -> float:
    """Epochs from ``k`` to the first epoch ``>= k`` with a fixed or partial status.

    0 when epoch ``k`` is itself fixed. A run that never fixes again counts as fixing on
    the epoch after its last (``len(status) − k``, censored): the median over seeds then
    ranks it slowest instead of dropping it, as a NaN would be.
    """
    s = np.asarray(status)[k:]
    hit = np.flatnonzero(np.isin(s, FIXED))
    return float(hit[0]) if hit.size else float(s.size)


def impulse_share_bound(j: int) -> float:
    r"""Largest share of a one-epoch error's effect that a filter of scalar gain still carries
    ``j`` epochs after it (docs/algorithms.md §20).

    A coordinate updated with gain :math:`K \in [0, 1]` per epoch moves by :math:`K e` on the
    faulty epoch (:math:`e` the full-gain response) and keeps :math:`K (1 − K)^j e` of it ``j``
    clean epochs later; over all :math:`K` the largest share is

    .. math:: \max_K K (1 − K)^j = \frac{1}{j + 1} \Big(\frac{j}{j + 1}\Big)^j

    at :math:`K = 1/(j + 1)` (1 for ``j = 0``).
    """
    if j < 0:
        raise ValueError(f"j must be non-negative, got {j}")
    return (1.0 / (j + 1)) * (j / (j + 1)) ** j


def convergence_epoch(d3: FloatArray, threshold_m: float) -> float:
    """First epoch after which the 3D error stays below ``threshold_m`` (NaN if never)."""
    bad = np.flatnonzero(~(d3 < threshold_m))
    if bad.size == 0:
        return 0.0
    return float(bad[-1] + 1) if bad[-1] + 1 < d3.size else float("nan")


def rail_deviation_m(pos_m: FloatArray, start_m: npt.ArrayLike, end_m: npt.ArrayLike) -> FloatArray:
    """Horizontal distance of each position (T, 3) from the straight rail start→end (m)."""
    a = np.asarray(start_m, float)[:2]
    u = np.asarray(end_m, float)[:2] - a
    u = u / np.linalg.norm(u)
    r = np.asarray(pos_m, float)[:, :2] - a
    return np.asarray(np.abs(r[:, 0] * u[1] - r[:, 1] * u[0]), dtype=float)


def seed_stats(raws: Mapping[str, Raw]) -> dict[str, float]:
    """Every statistic of one seed as a flat ``{key: value}`` mapping."""
    st: dict[str, float] = {}
    # ---- DPL
    sukf, rukf = raws["dpl/SUKF"], raws["dpl/RUKF"]
    counts = situation_counts(diag_table(rukf))
    for lab, c in counts.items():
        for k in range(3):
            st[f"dpl.table1.{lab}.s{k + 1}"] = float(c[k])
    et, es = epoch_situations(diag_table(rukf))
    mean_abs = situation_mean_abs_errors(
        et, es, {"SUKF": (sukf["t_s"], pos_error_m(sukf)), "RUKF": (rukf["t_s"], pos_error_m(rukf))}
    )
    for name, per in mean_abs.items():
        for k, vals in per.items():
            for ax, val in zip("XYZ", vals, strict=True):
                st[f"dpl.fig6.{name}.s{k}.{ax}"] = float(val)
    for name, raw in (("SUKF", sukf), ("RUKF", rukf)):
        e = pos_error_m(raw)
        st[f"dpl.{name}.rms_3d_m"] = float(np.sqrt(np.mean(np.sum(e**2, axis=1))))
        for ax, val in zip("XYZ", np.abs(e).mean(axis=0), strict=True):
            st[f"dpl.{name}.mean_abs_{ax}_m"] = float(val)
    for k in (2, 3):
        imp = mean_abs["SUKF"][k] - mean_abs["RUKF"][k]
        st[f"dpl.improvement.s{k}.max_axis_m"] = (
            float(np.nanmax(imp)) if np.isfinite(imp).any() else float("nan")
        )
    # how many epochs the static filter averages: its 3D sigma at the last epoch, and the
    # SUKF error in clean epochs (#1) against epochs with small gross errors (#2)
    st["dpl.SUKF.sigma_3d_end_m"] = float(sukf["sigma_3d_m"][-1])
    # ---- DPL memory sensitivity: random-walk position, same data, same situations
    # (first seed only)
    if "dpl_rw/SUKF" in raws:
        _memory_stats(raws, st)
    _rtk_stats(raws, st)
    return st


def _memory_stats(raws: Mapping[str, Raw], st: dict[str, float]) -> None:
    rw = {n: raws[f"dpl_rw/{n}"] for n in ("SUKF", "RUKF")}
    et_rw, es_rw = epoch_situations(diag_table(rw["RUKF"]))
    mean_rw = situation_mean_abs_errors(et_rw, es_rw, {n: (r["t_s"], pos_error_m(r)) for n, r in rw.items()})
    for name, per in mean_rw.items():
        for k, vals in per.items():
            for ax, val in zip("XYZ", vals, strict=True):
                st[f"dpl_rw.fig6.{name}.s{k}.{ax}"] = float(val)
    for name, raw in rw.items():
        e = pos_error_m(raw)
        st[f"dpl_rw.{name}.rms_3d_m"] = float(np.sqrt(np.mean(np.sum(e**2, axis=1))))
    st["dpl_rw.SUKF.sigma_3d_end_m"] = float(rw["SUKF"]["sigma_3d_m"][-1])
    for k in (2, 3):
        imp = mean_rw["SUKF"][k] - mean_rw["RUKF"][k]
        st[f"dpl_rw.improvement.s{k}.max_axis_m"] = (
            float(np.nanmax(imp)) if np.isfinite(imp).any() else float("nan")
        )


def _rtk_stats(raws: Mapping[str, Raw], st: dict[str, float]) -> None:
    # ---- RTK static 5 cm
    lab = "PL4-PL1"
    for var in ("static", "static_orig"):
        r = raws[f"{var}/RUKF"]
        n = r["t_s"].size
        faulty = fault_epochs(raws["static/RUKF"], n)
        dv = np.abs(dd_series(r, lab, "dv"))
        res = np.abs(dd_series(r, lab, "residual"))
        st[f"rtk.{var}.PL4.max_abs_dv_clean"] = float(np.nanmax(dv[~faulty]))
        have = np.isfinite(dv)
        st[f"rtk.{var}.PL4.frac_clean_dv_gt_k0"] = float(np.mean(dv[~faulty & have] > K0))
        st[f"rtk.{var}.PL4.median_abs_resid_clean_m"] = float(np.nanmedian(res[~faulty]))
        ok = ~faulty & np.isfinite(res)
        st[f"rtk.{var}.PL4.frac_resid_lt_5mm"] = float(np.mean(res[ok] < 0.005)) if ok.any() else float("nan")
        st[f"rtk.{var}.PL4.frac_faulty_dv_gt_k0"] = (
            float(np.mean(dv[faulty & have] > K0)) if (faulty & have).any() else float("nan")
        )
    faulty = fault_epochs(raws["static/SUKF"], raws["static/SUKF"]["t_s"].size)
    for name in ("SUKF", "RUKF"):
        d3 = error_3d_m(raws[f"static/{name}"])
        d0 = error_3d_m(raws[f"static_orig/{name}"])
        st[f"rtk.static.{name}.max_extra_faulty_m"] = float(np.max(np.abs(d3 - d0)[faulty]))
        if f"static_prior/{name}" in raws:
            # the paper's per-epoch scheme on the same data (variant)
            dp = error_3d_m(raws[f"static_prior/{name}"])
            dp0 = error_3d_m(raws[f"static_prior_orig/{name}"])
            st[f"rtk.static_prior.{name}.max_extra_faulty_m"] = float(np.max(np.abs(dp - dp0)[faulty]))
            st[f"rtk.static_prior.{name}.fix_rate"] = float(
                np.isin(raws[f"static_prior/{name}"]["status"], FIXED).mean()
            )
        for q in Q_SIGMAS_M:
            # the same data with fix-and-hold and a coordinate random walk (sensitivity)
            if f"static_q@{q:g}/{name}" in raws:
                dq = error_3d_m(raws[f"static_q@{q:g}/{name}"])
                dq0 = error_3d_m(raws[f"static_q@{q:g}_orig/{name}"])
                st[f"rtk.static_q@{q:g}.{name}.max_extra_faulty_m"] = float(np.max(np.abs(dq - dq0)[faulty]))
        st[f"rtk.static.{name}.rms_3d_m"] = float(np.sqrt(np.mean(d3**2)))
        st[f"rtk.static.{name}.fix_rate"] = float(np.isin(raws[f"static/{name}"]["status"], FIXED).mean())
        first = int(np.flatnonzero(faulty)[0]) if faulty.any() else -1
        st[f"rtk.static.{name}.sigma_3d_first_fault_m"] = (
            float(raws[f"static/{name}"]["sigma_3d_m"][first - 1]) if first > 0 else float("nan")
        )
    # ---- RTK static 0.15 m
    k = STATIC_FAULT_EPOCH
    sens = [prior_label(sig) for sig in PRIOR_SIGMAS_SENS_M if sig != PRIOR_SIGMA_M]
    # the process-noise sensitivity (fix-and-hold, coordinate random walk of σ per epoch):
    # the σ a run has (a quick run has fewer)
    qs = [f"q@{q:g}" for q in Q_SIGMAS_M if f"s015_q@{q:g}/SUKF" in raws]
    for h in (*AR_MODES_015, *sens, *qs):
        for name in ("SUKF", "RUKF", "RUKF+PAR"):
            r = raws[f"s015_{h}/{name}"]
            d3 = error_3d_m(r)
            p = f"rtk015.{h}.{name}"
            st[f"{p}.jump_m"] = jump_m(d3, k)
            st[f"{p}.err_before_m"] = float(d3[k - 1])
            st[f"{p}.sigma_before_m"] = float(r["sigma_3d_m"][k - 1])
            st[f"{p}.fix_rate_before"] = float(np.isin(r["status"][:k], FIXED).mean())
            st[f"{p}.refix_epochs"] = epochs_to_refix(r["status"], k)
            st["rtk015.n_after"] = float(len(r["status"]) - k)
            st[f"{p}.fixed_at_fault"] = float(r["status"][k] in FIXED)
            st[f"{p}.fix_rate"] = float(np.isin(r["status"], FIXED).mean())
            st[f"{p}.max_3d_after_m"] = float(d3[k:].max())
            # what the float state kept of the error: PL4-PL1's innovation on the first
            # clean epoch after it (m), and its post-fit residual on the faulty epoch (m)
            inn = dd_series(r, "PL4-PL1", "innovation")
            res = dd_series(r, "PL4-PL1", "residual")
            st[f"{p}.pl4_innov_after_m"] = float(inn[k + 1]) if k + 1 < inn.size else float("nan")
            st[f"{p}.pl4_resid_at_fault_m"] = float(res[k])
            # the robust policy's view of PL4-PL1 on the faulty epoch: Δv̄ and the weight
            # 1/λ of its IGG-III variance factor λ (1: kept, 0: rejected)
            st[f"{p}.pl4_dv_at_fault"] = float(dd_series(r, "PL4-PL1", "dv")[k])
            # the LAMBDA ratio of the epoch's integer search (NaN: no search)
            st[f"{p}.ratio_at_fault"] = float(r["ratio"][k]) if "ratio" in r else float("nan")
            st[f"{p}.pl4_weight_at_fault"] = float(1.0 / dd_series(r, "PL4-PL1", "factor")[k])
    # ---- rail 0.1 m
    faulty = fault_epochs(raws["rail/SUKF"], raws["rail/SUKF"]["t_s"].size)
    for name in ("SUKF", "RUKF"):
        e = pos_error_m(raws[f"rail/{name}"])
        st[f"rail.{name}.max_abs_x_faulty_m"] = float(np.max(np.abs(e[faulty, 0])))
        st[f"rail.{name}.max_abs_x_clean_m"] = float(np.max(np.abs(e[~faulty, 0])))
        st[f"rail.{name}.rms_3d_m"] = float(np.sqrt(np.mean(np.sum(e**2, axis=1))))
    # ---- rail 0.15 m
    rail_tr = load_scenario("li2019_rtk_rail_015").trajectory
    assert rail_tr.end_m is not None
    for v in AR_MODES_RAIL:
        for name in ("SUKF", "RUKF+PAR"):
            r = raws[f"rail015_{v}/{name}"]
            dev = rail_deviation_m(r["pos_m"], rail_tr.start_m, rail_tr.end_m)
            after = dev[RAIL_FAULT_EPOCH:]
            st[f"rail015.{v}.{name}.mean_dev_after_m"] = float(np.mean(after))
            st[f"rail015.{v}.{name}.max_dev_after_m"] = float(np.max(after))
            st[f"rail015.{v}.{name}.mean_dev_before_m"] = float(np.mean(dev[:RAIL_FAULT_EPOCH]))
            st[f"rail015.{v}.{name}.max_dev_before_m"] = float(np.max(dev[:RAIL_FAULT_EPOCH]))
            fixed = np.isin(r["status"], FIXED)
            st[f"rail015.{v}.{name}.fix_rate"] = float(fixed.mean())
            st[f"rail015.{v}.{name}.refix_epochs"] = epochs_to_refix(r["status"], RAIL_FAULT_EPOCH)
            st[f"rail015.{v}.{name}.dev_at_fault_m"] = float(dev[RAIL_FAULT_EPOCH])
            st[f"rail015.{v}.{name}.fix_rate_before"] = float(fixed[:RAIL_FAULT_EPOCH].mean())
            st[f"rail015.{v}.{name}.fix_rate_after"] = float(fixed[RAIL_FAULT_EPOCH:].mean())
            e3 = error_3d_m(r)
            st[f"rail015.{v}.{name}.max_err3d_before_m"] = float(np.max(e3[:RAIL_FAULT_EPOCH]))
            st[f"rail015.{v}.{name}.max_err3d_after_m"] = float(np.max(e3[RAIL_FAULT_EPOCH:]))
            st[f"rail015.{v}.n_after"] = float(after.size)
        st[f"rail015.{v}.improvement_mean_dev_m"] = (
            st[f"rail015.{v}.SUKF.mean_dev_after_m"] - st[f"rail015.{v}.RUKF+PAR.mean_dev_after_m"]
        )
        a, b = raws[f"rail015_{v}/SUKF"]["pos_m"], raws[f"rail015_{v}/RUKF+PAR"]["pos_m"]
        st[f"rail015.{v}.max_pos_diff_m"] = float(np.max(np.linalg.norm(a - b, axis=1)))
        r = raws[f"rail015_{v}/RUKF+PAR"]
        st[f"rail015.{v}.RUKF+PAR.max_abs_resid_m"] = float(np.nanmax(np.abs(r["diag"]["residual"])))
        dv_pl4 = dd_series(r, "PL4-PL1", "dv")
        k = min(RAIL_FAULT_EPOCH, dv_pl4.size - 1)
        st[f"rail015.{v}.RUKF+PAR.PL4_dv_at_fault"] = float(dv_pl4[k])
        st[f"rail015.{v}.RUKF+PAR.PL4_dv_before_fault"] = float(dv_pl4[k - 1])
    # ---- EKF vs UKF: the geometry's shortest rover-transmitter range (m), which sets the
    # linearization error of an offset start
    sc = load_scenario("li2019_dpl_static")
    x0 = np.asarray(sc.trajectory.start_m, dtype=float)
    st["geom.min_range_m"] = float(min(np.linalg.norm(x0 - np.asarray(p, float)) for _, p in sc.transmitters))
    for mode, thr in (("dpl_init", CONV_DPL_M), ("rtk_init", CONV_RTK_M)):
        for filt in ("EKF", "UKF"):
            for off in INIT_OFFSETS_M:
                d3 = error_3d_m(raws[f"{mode}/{filt}@{off:g}"])
                st[f"{mode}.{filt}.{off:g}.rms_3d_m"] = float(np.sqrt(np.mean(d3**2)))
                st[f"{mode}.{filt}.{off:g}.conv_epoch"] = convergence_epoch(d3, thr)


def aggregate(per_run: Sequence[Mapping[str, float]]) -> dict[str, dict[str, Any]]:
    """Median, mean and 5/95 percentiles of each statistic over runs (NaN runs ignored)."""
    keys = list(per_run[0])
    out: dict[str, dict[str, Any]] = {}
    for key in keys:
        v = np.array([r.get(key, np.nan) for r in per_run], dtype=float)
        f = v[np.isfinite(v)]
        med, lo, hi = (
            (float(np.median(f)), float(np.percentile(f, 5)), float(np.percentile(f, 95)))
            if f.size
            else (math.nan,) * 3
        )
        out[key] = {
            "median": med,
            "mean": float(np.mean(f)) if f.size else math.nan,
            "p5": lo,
            "p95": hi,
            "values": [None if not np.isfinite(x) else float(x) for x in v],
        }
    return out


def stat_value(stats: Mapping[str, Mapping[str, Any]], key: str) -> float:
    """A statistic's median over seeds; ``key + "_share"``: its mean (for 0/1 statistics,
    the share of seeds where it is 1). NaN when no seed has a value."""
    if key.endswith("_share"):
        v = stats[key.removesuffix("_share")]["mean"]
    else:
        v = stats[key]["median"]
    return float("nan") if v is None else float(v)


def gauss_dv_exceed_prob(k0: float, n_dd: int, samples: int = 200_000, seed: int = 0) -> float:
    r"""Probability that :math:`|\Delta\bar v|` of one of ``n_dd`` DDs exceeds ``k0`` when the
    standardized residuals are independent standard normal (Monte Carlo, fixed seed).

    :math:`\Delta\bar v_1 = \bar v_1 / (\sum_{j \ne 1} |\bar v_j| / (n - 1))` (Li et al. 2019,
    Eq. 13).
    """
    v = np.abs(np.random.default_rng(seed).standard_normal((samples, n_dd)))
    return float(np.mean(v[:, 0] / v[:, 1:].mean(axis=1) > k0))


__all__ = [
    "AR_MODES_015",
    "AR_MODES_RAIL",
    "CONV_DPL_M",
    "CONV_RTK_M",
    "FIXED",
    "aggregate",
    "convergence_epoch",
    "dd_series",
    "diag_table",
    "epochs_to_refix",
    "error_3d_m",
    "fault_epochs",
    "gauss_dv_exceed_prob",
    "impulse_share_bound",
    "jump_m",
    "pos_error_m",
    "rail_deviation_m",
    "seed_stats",
    "stat_value",
]
