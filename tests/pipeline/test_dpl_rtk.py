"""End-to-end behaviour of the DD engine on simulated rooms (the papers' claims)."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from robustrtk.eval.cli_support import contaminated_epochs, read_truth_csv
from robustrtk.pipeline.config import Config
from robustrtk.pipeline.engine import align_epochs
from robustrtk.pipeline.results import EpochInputs
from robustrtk.pipeline.solve import solve_pseudolite
from robustrtk.sim.files import run_simulate


def _extra(e3: np.ndarray, contaminated: np.ndarray, sel: np.ndarray) -> float:
    vals, last = [], -1
    for i in range(e3.size):
        if not contaminated[i]:
            last = i
        elif sel[i] and last >= 0:
            vals.append(e3[i] - e3[last])
    return float(np.mean(vals))


def _errors(out: Path, cfg: Config) -> tuple[np.ndarray, list]:
    res = solve_pseudolite(out / "obs.csv", out / "site.toml", cfg)
    t, truth = read_truth_csv(out / "truth.csv")
    pos = np.array([s.pos_m for s in res.solutions])
    assert np.allclose([s.t_s for s in res.solutions], t)
    return np.linalg.norm(pos - truth, axis=1), res.solutions


def _dpl_acceptance(preset: str, seed: int, tmp: Path) -> dict[str, float]:
    out = tmp / f"{preset}_{seed}"
    run_simulate(preset, seed, out)
    t, _ = read_truth_csv(out / "truth.csv")
    g = contaminated_epochs(out / "faults.csv")
    big, small = np.isin(t, g["large"]), np.isin(t, g["small"])
    cont = big | small
    e_s, _ = _errors(out, Config.of(robust="none", dynamics="kinematic"))
    e_r, _ = _errors(out, Config.of(robust="igg3", dynamics="kinematic"))
    return {
        "removed_big": 1 - _extra(e_r, cont, big) / _extra(e_s, cont, big),
        "removed_burst": 1 - _extra(e_r, cont, small) / _extra(e_s, cont, small),
        "p95_ratio": float(np.percentile(e_r[big], 95) / np.percentile(e_r[~cont], 95)),
    }


@pytest.mark.slow
@pytest.mark.parametrize("preset", ["dpl_static", "dpl_rail"])
def test_dpl_acceptance(preset: str, tmp_path: Path) -> None:
    """Issue acceptance: RUKF removes >= 80 % of SUKF's extra error on 10 m epochs and
    >= 50 % on burst epochs; its p95 on 10 m epochs within 1.5x of clean. Judged on the
    median over seeds (each run has only a handful of 10 m epochs)."""
    runs = [_dpl_acceptance(preset, s, tmp_path) for s in (1, 2, 3)]
    med = {k: float(np.median([r[k] for r in runs])) for k in runs[0]}
    print(preset, runs, med)
    assert med["removed_big"] >= 0.8
    assert med["removed_burst"] >= 0.5
    assert med["p95_ratio"] <= 1.5


def test_rukf_removes_most_of_the_10m_effect_short(tmp_path: Path) -> None:
    """A short static room: the robust filter's error on 10 m epochs stays at its clean
    level while the standard filter's jumps."""
    out = tmp_path / "d"
    run_simulate("demo", 4, out)
    t, _ = read_truth_csv(out / "truth.csv")
    g = contaminated_epochs(out / "faults.csv")
    big = np.isin(t, g["large"])
    cont = big | np.isin(t, g["small"]) | np.isin(t, g["phase"])
    e_s, _ = _errors(out, Config.of(robust="none", dynamics="kinematic"))
    e_r, _ = _errors(out, Config.of(robust="igg3", dynamics="kinematic"))
    assert _extra(e_r, cont, big) < 0.3 * _extra(e_s, cont, big)


def _true_amb(out: Path) -> dict[tuple[float, str], int]:
    with (out / "ambiguities.csv").open() as fh:
        return {(float(r["time"]), r["transmitter"]): int(r["N_cyc"]) for r in csv.DictReader(fh)}


@pytest.mark.parametrize("preset", ["li2019_rtk_static_015", "li2019_rtk_rail_015"])
def test_rukf_par_keeps_centimetre_fix_through_015m_error(preset: str, tmp_path: Path) -> None:
    out = tmp_path / preset
    run_simulate(preset, 1, out)
    dyn = "kinematic" if "rail" in preset else "static"
    e_par, sols = _errors(out, Config.of(mode="rtk", robust="igg3", ar="par", dynamics=dyn))
    status = np.array([s.status for s in sols])
    assert np.all(np.isin(status[5:], ["fixed", "partial"]))
    assert e_par.max() < 0.05
    # the standard filter is pulled off by the same error (the paper's contrast)
    e_std, _ = _errors(out, Config.of(mode="rtk", robust="none", ar="lambda", dynamics=dyn))
    assert e_std.max() > 2 * e_par.max()


def test_rtk_fixes_true_integers(tmp_path: Path) -> None:
    """The fixed DD ambiguities equal the simulator's true ones (no wrong integer)."""
    out = tmp_path / "rtk"
    run_simulate("li2019_rtk_static", 2, out)
    truth = _true_amb(out)
    from robustrtk.geometry.surveyed import SurveyedSource
    from robustrtk.io.obstable import read_obs_table
    from robustrtk.io.site import read_site
    from robustrtk.pipeline.engine import DDEngine

    site = read_site(out / "site.toml")
    b = read_obs_table(out / "obs.csv", wavelength_m=site.wavelength_m)
    eng = DDEngine(
        Config.of(mode="rtk", robust="igg3", ar="par"),
        SurveyedSource(site.transmitters),
        site.base_pos_m,
        site.rover_initial_pos_m,
        reference=site.reference,
    )
    checked = 0
    for i, j in align_epochs(b["rover"], b["base"]):
        sol = eng.step(EpochInputs(b["rover"].epoch(i), b["base"].epoch(j))).solution
        st = eng.state
        assert st is not None
        if sol.status == "fixed":
            for key in st.layout.amb_keys:
                est = st.x[st.layout.amb_index(key)]
                # the held float ambiguity sits on the true integer
                assert round(est) == truth[(sol.t_s, key[0])]
                checked += 1
    assert checked > 900
