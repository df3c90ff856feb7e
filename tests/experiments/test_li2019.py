"""End-to-end tests of the Li et al. (2019) reproduction in quick mode."""

from __future__ import annotations

import dataclasses
import json
import re
import struct
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from robustrtk.cli.experiment import experiment
from robustrtk.estimation.robust import discriminant_statistic
from robustrtk.experiments.li2019 import (
    CONV_RTK_M,
    PAPER_DPL_EPOCHS,
    PAPER_TABLE1,
    Q_SIGMAS_M,
    Q_SIGMAS_QUICK_M,
    Report,
    build_claims,
    convergence_epoch,
    epochs_to_refix,
    gauss_dv_exceed_prob,
    impulse_share_bound,
    jump_m,
    rail_deviation_m,
    run_li2019,
)
from robustrtk.pipeline.config import Config, SlipConfig
from robustrtk.pipeline.results import RunResult
from robustrtk.pipeline.solve import solve_pseudolite
from robustrtk.sim.files import write_simulation
from robustrtk.sim.pseudolite import simulate
from robustrtk.sim.scenario import load_scenario


@pytest.fixture(scope="module")
def one(tmp_path_factory: pytest.TempPathFactory) -> Report:
    return run_li2019(tmp_path_factory.mktemp("li1"), runs=1, seed=0, workers=1, progress=False, quick=True)


@pytest.fixture(scope="module")
def two(tmp_path_factory: pytest.TempPathFactory) -> Report:
    return run_li2019(tmp_path_factory.mktemp("li2"), runs=2, seed=5, workers=2, progress=False, quick=True)


def _section(md: str, heading_start: str) -> str:
    i = md.index("## " + heading_start)
    j = md.find("\n## ", i + 3)
    return md[i : j if j > 0 else len(md)]


def _table_rows(section: str) -> list[list[str]]:
    rows = [ln for ln in section.splitlines() if ln.startswith("|")]
    return [
        [c.strip().replace("\\|", "|") for c in re.split(r"(?<!\\)\|", r.strip()[1:-1])] for r in rows[2:]
    ]


def _results(rep: Report) -> dict:
    return json.loads(rep.results_path.read_text(encoding="utf-8"))


# ------------------------------------------------------------------- helper definitions
def test_helpers_against_hand_values() -> None:
    d3 = np.array([0.01, 0.02, 0.20, 0.05, 0.01, 0.01])
    assert jump_m(d3, 2) == pytest.approx(0.18)
    assert convergence_epoch(d3, 0.03) == 4.0  # epoch 3 is the last one above
    assert convergence_epoch(d3, 1.0) == 0.0
    assert np.isnan(convergence_epoch(np.array([0.0, 1.0]), 0.5))
    status = ["fixed", "float", "float", "partial", "fixed"]
    assert epochs_to_refix(status, 1) == 2.0
    assert epochs_to_refix(status, 0) == 0.0
    # never re-fixed: censored at the epoch after the run, so a median cannot drop it
    assert epochs_to_refix(["float", "float"], 0) == 2.0
    assert epochs_to_refix(["fixed", "float", "float"], 1) == 2.0
    # rail along +45°: distance of (1, 0) from the line y = x is 1/sqrt(2)
    dev = rail_deviation_m(np.array([[1.0, 0.0, 5.0], [2.0, 2.0, 0.0]]), [0, 0, 0], [3, 3, 0])
    np.testing.assert_allclose(dev, [1 / np.sqrt(2), 0.0], atol=1e-12)


# ------------------------------------------------------------------- report == numbers
def test_table1_cells_match_results_and_independent_recount(one: Report) -> None:
    md = one.report_path.read_text(encoding="utf-8")
    res = _results(one)
    rows = _table_rows(_section(md, "DPL static — Table 1"))
    assert [r[0] for r in rows] == list(PAPER_TABLE1)
    # independent: simulate, write files, solve from the files, count by hand
    sim = simulate(load_scenario("li2019_dpl_static"), np.random.default_rng(0), n_epochs=600)
    paths = write_simulation(sim, one.out_dir / "indep")
    run = solve_pseudolite(paths["obs.csv"], paths["site.toml"], Config.of(robust="igg3"))
    dd = np.array([d.dd for d in run.diagnostics])
    sit = np.array([d.situation for d in run.diagnostics])
    t = np.array([d.t_s for d in run.diagnostics])
    for r in rows:
        lab = r[0]
        cells = [int(c) for c in r[1:4]]
        stats = [res["stats"][f"dpl.table1.{lab}.s{k}"]["median"] for k in (1, 2, 3)]
        assert cells == stats
        if lab in dd:
            sel = sit[dd == lab]
            assert cells == [int((sel == k).sum()) for k in (1, 2, 3)]
        else:  # all DDs: #3 if any DD is #3, #1 if all are #1
            per_epoch = [sit[t == tt] for tt in np.unique(t)]
            n3 = sum(int((s == 3).any()) for s in per_epoch)
            n1 = sum(int((s == 1).all()) for s in per_epoch)
            assert cells == [n1, len(per_epoch) - n1 - n3, n3]
    assert sum(int(c) for c in rows[-1][1:4]) == 600


def _tables(section: str) -> list[list[dict[str, str]]]:
    """Every Markdown table of a section as a list of {header: cell} rows."""
    blocks: list[list[str]] = []
    prev = False
    for ln in section.splitlines():
        is_row = ln.startswith("|")
        if is_row and not prev:
            blocks.append([])
        if is_row:
            blocks[-1].append(ln)
        prev = is_row
    out = []
    for b in blocks:
        head = [c.strip().replace("\\|", "|") for c in re.split(r"(?<!\\)\|", b[0].strip()[1:-1])]
        out.append([dict(zip(head, r, strict=True)) for r in _table_rows("\n".join(b))])
    return out


def _by_header(section: str, first_header: str | None = None) -> list[dict[str, str]]:
    """The rows of the section's first table (or of the one whose first column is named
    ``first_header``)."""
    for t in _tables(section):
        if first_header is None or (t and next(iter(t[0])) == first_header):
            return t
    raise AssertionError(f"no table {first_header!r}")


def test_jump_cell_matches_independent_solution(one: Report) -> None:
    md = one.report_path.read_text(encoding="utf-8")
    res = _results(one)
    rows = _by_header(_section(md, "RTK static, 0.15 m"))
    by = {(r["Scheme"], r["AR mode"]): r for r in rows}
    assert set(by) == {
        (n, m)
        for n in ("SUKF", "RUKF", "RUKF+PAR")
        for m in (
            "paper's scheme (prior)",
            "paper's scheme, literal Δv̄ (posterior)",
            "paper's scheme, default slip detectors",
            "paper's scheme, correlations kept (σ² added)",
            "fix-and-hold",
            "continuous AR",
        )
    }
    # independent: simulate, write files, solve from the files (fix-and-hold, SUKF)
    sim = simulate(load_scenario("li2019_rtk_static_015"), np.random.default_rng(0), n_epochs=130)
    paths = write_simulation(sim, one.out_dir / "indep015")
    run = solve_pseudolite(
        paths["obs.csv"],
        paths["site.toml"],
        Config.of(mode="rtk", robust="none", ar="lambda", hold=True, slip="lli"),
    )
    d3 = np.linalg.norm(np.array([s.pos_m for s in run.solutions]) - sim.truth_pos_m, axis=1)
    jump = d3[100] - d3[99]
    stat = res["stats"]["rtk015.hold.SUKF.jump_m"]["median"]
    assert stat == pytest.approx(jump, abs=1e-9)
    assert res["stats"]["rtk015.hold.SUKF.err_before_m"]["median"] == pytest.approx(d3[99], abs=1e-9)
    assert float(by[("SUKF", "fix-and-hold")]["Jump (m)"]) == pytest.approx(jump, abs=5e-4)
    # the error is on epoch 100 only
    f = sim.faults
    sel = (np.asarray(f.kind) == "gross") & (np.asarray(f.observable) == "phase")
    assert f.epoch[sel].tolist() == [100]
    for (name, mode), r in by.items():
        h = {
            "fix-and-hold": "hold",
            "continuous AR": "cont",
            "paper's scheme (prior)": "prior",
            "paper's scheme, literal Δv̄ (posterior)": "prior_lit",
            "paper's scheme, default slip detectors": "prior_poly",
            "paper's scheme, correlations kept (σ² added)": "prior_kept",
        }[mode]
        st = res["stats"]
        for col, key in (
            ("Jump (m)", "jump_m"),
            ("Fix rate", "fix_rate"),
            ("3D error at 99 (m)", "err_before_m"),
            ("Fix rate before 100", "fix_rate_before"),
        ):
            assert float(r[col]) == pytest.approx(st[f"rtk015.{h}.{name}.{key}"]["median"], abs=5e-4)
        assert float(r["3D σ at 99 (m)"]) == pytest.approx(
            st[f"rtk015.{h}.{name}.sigma_before_m"]["median"], abs=5e-5
        )


def test_rail_015_primary_is_the_paper_scheme_and_claims_use_it(one: Report) -> None:
    """Fig. 11 claims use the paper's scheme (previous coordinate as the prior, AR every
    epoch): the claim rows quote those statistics, and a track that is off the rail before
    the error cannot support the claim."""
    res = _results(one)
    st = res["stats"]
    md = one.report_path.read_text(encoding="utf-8")
    rows = _by_header(_section(md, "RTK kinematic rail"), "Scheme (0.15 m at 50)")
    modes = {r["AR mode"] for r in rows}
    assert modes == {
        "paper's scheme (prior)",
        "paper's scheme, ambiguities re-estimated",
        "single-epoch AR",
        "fix-and-hold",
    }
    re_rows = [r for r in rows if r["AR mode"] == "paper's scheme, ambiguities re-estimated"]
    for r in re_rows:
        n = r["Scheme (0.15 m at 50)"]
        assert float(r["mean dev. from 50 (m)"]) == pytest.approx(
            st[f"rail015.prior_re.{n}.mean_dev_after_m"]["median"], abs=5e-4
        )
    prim = {r["Scheme (0.15 m at 50)"]: r for r in rows if r["AR mode"] == "paper's scheme (prior)"}
    assert set(prim) == {"SUKF", "RUKF+PAR"}
    for n, r in prim.items():
        assert float(r["max dev. before 50 (m)"]) == pytest.approx(
            st[f"rail015.prior.{n}.max_dev_before_m"]["median"], abs=5e-4
        )
        assert float(r["max dev. from 50 (m)"]) == pytest.approx(
            st[f"rail015.prior.{n}.max_dev_after_m"]["median"], abs=5e-4
        )
    claims = [c for c in res["claims"] if "Fig. 11" in c["section"]]
    assert len(claims) == 2 and all("paper's ar scheme" in c["claim"].lower() for c in claims)
    sukf_after = st["rail015.prior.SUKF.max_dev_after_m"]["median"]
    before = max(st[f"rail015.prior.{n}.max_dev_before_m"]["median"] for n in ("SUKF", "RUKF+PAR"))
    assert claims[0]["ours"].startswith(f"{sukf_after:.3f} m")
    expect = st["rail015.prior.SUKF.max_dev_before_m"]["median"] < CONV_RTK_M and sukf_after >= 0.1
    assert claims[0]["holds"] is expect
    if before >= CONV_RTK_M:
        assert claims[1]["holds"] is False


def test_claims_logic_on_synthetic_statistics() -> None:
    """The claim rules themselves: hand-made statistics in, verdicts out."""
    base = {
        "rail015.prior.SUKF.max_dev_before_m": 0.01,
        "rail015.prior.RUKF+PAR.max_dev_before_m": 0.01,
        "rail015.prior.SUKF.max_dev_after_m": 0.3,
        "rail015.prior.improvement_mean_dev_m": 0.025,
    }

    def verdicts(over: dict[str, float]) -> dict[str, bool | None]:
        vals = {**base, **over}

        def s(key: str) -> float:
            return vals.get(key, 0.0)

        def f(key: str, fmt: str) -> str:
            return format(s(key), fmt if fmt != "d" else ".0f")

        return {
            c.section + "|" + c.claim[:40]: c.holds
            for c in build_claims(s, PAPER_DPL_EPOCHS, f)
            if "Fig. 11" in c.section
        }

    ok = verdicts({})
    assert list(ok.values()) == [True, True]
    # off the rail before the error: neither claim can hold, whatever happens after
    assert list(verdicts({"rail015.prior.SUKF.max_dev_before_m": 0.5}).values()) == [False, False]
    assert list(verdicts({"rail015.prior.RUKF+PAR.max_dev_before_m": 0.5}).values()) == [True, False]
    # on the rail, but SUKF stays within decimetres / the gain is below 2 cm
    assert list(verdicts({"rail015.prior.SUKF.max_dev_after_m": 0.05}).values()) == [False, True]
    assert list(verdicts({"rail015.prior.improvement_mean_dev_m": 0.01}).values()) == [True, False]


def test_gaussian_dv_exceedance() -> None:
    """Δv̄ of four independent N(0, 1) residuals: P(Δv̄ > 2) by sampling matches a
    numerical integral: P(|x| > 2 m) with m the mean of three |N(0, 1)|."""
    p = gauss_dv_exceed_prob(2.0, 4)
    rng = np.random.default_rng(123)
    m = np.abs(rng.standard_normal((400_000, 3))).mean(axis=1)
    from math import erfc, sqrt

    ref = float(np.mean([erfc(2.0 * mm / sqrt(2.0)) for mm in m[:20_000]]))
    assert p == pytest.approx(ref, abs=0.01)
    assert 0.1 < p < 0.3


def test_every_number_cell_is_a_results_value(one: Report) -> None:
    """Each numeric cell of the DPL accuracy table equals its statistic in results.json."""
    md = one.report_path.read_text(encoding="utf-8")
    st = _results(one)["stats"]
    rows = _table_rows(_section(md, "DPL static — Fig. 5"))
    by = {r[0]: r for r in rows if r[0] in ("SUKF", "RUKF") and not r[1].startswith("#")}
    assert len(by) == 2
    for name, r in by.items():
        assert float(r[1]) == pytest.approx(st[f"dpl.{name}.rms_3d_m"]["median"], abs=5e-4)
        for i, ax in enumerate("XYZ"):
            assert float(r[2 + i]) == pytest.approx(st[f"dpl.{name}.mean_abs_{ax}_m"]["median"], abs=5e-4)


def test_claims_cover_every_conclusion(one: Report) -> None:
    md = one.report_path.read_text(encoding="utf-8")
    rows = _table_rows(_section(md, "Claims"))
    res = _results(one)
    assert len(rows) == len(res["claims"]) == len(one.claims) >= 14
    text = "\n".join(" | ".join(r) for r in rows)
    for needle in (
        "Concl. 1",
        "Concl. 2",
        "Concl. 3",
        "3693 / 6794 / 378",
        "decimetre",
        "0.16 m",
        "0.12 m",
        "12 vs 5",
        "100 %",
        "2–3 cm",
        "UKF better",
    ):
        assert needle in text, needle
    for r, c in zip(rows, res["claims"], strict=True):
        assert r[4] == ("yes" if c["holds"] else ("n/a" if c["holds"] is None else "no"))
        assert r[3] == c["ours"]
    assert "## Why our numbers differ" in md


def test_figures_are_nonempty_pngs(one: Report) -> None:
    md = one.report_path.read_text(encoding="utf-8")
    linked = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", md)
    assert len(one.figures) == 16
    assert sorted(linked) == sorted(p.name for p in one.figures)
    for p in one.figures:
        data = p.read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n"
        w, h = struct.unpack(">II", data[16:24])
        assert w >= 600 and h >= 300
        assert len(data) > 20_000


# ------------------------------------------------------------------- several runs
def test_runs2_aggregates_with_numpy(two: Report) -> None:
    res = _results(two)
    assert res["seeds"] == [5, 6]
    assert len(res["per_run"]) == 2
    n_checked = 0
    for key, agg in res["stats"].items():
        v = np.array([np.nan if x is None else x for x in agg["values"]], dtype=float)
        np.testing.assert_allclose(
            v, [np.nan if r.get(key) is None else r[key] for r in res["per_run"]], equal_nan=True
        )
        f = v[np.isfinite(v)]
        if f.size:
            assert agg["median"] == pytest.approx(float(np.median(f)))
            assert agg["p5"] == pytest.approx(float(np.percentile(f, 5)))
            assert agg["p95"] == pytest.approx(float(np.percentile(f, 95)))
            n_checked += 1
    assert n_checked > 100
    # the two seeds differ, so some statistic has a non-zero range
    assert any(a["p95"] > a["p5"] for a in res["stats"].values() if a["p5"] is not None)
    md = two.report_path.read_text(encoding="utf-8")
    row = _table_rows(_section(md, "DPL static — Table 1"))[-1]
    m = re.fullmatch(r"(\d+) \[(\d+), (\d+)\]", row[2])
    assert m is not None
    agg = res["stats"]["dpl.table1.All DDs.s2"]
    vals = agg["values"]
    assert int(m.group(1)) == round(np.median(vals))
    assert (int(m.group(2)), int(m.group(3))) == (
        round(np.percentile(vals, 5)),
        round(np.percentile(vals, 95)),
    )


# ------------------------------------------------------------------- CLI
def test_cli_bad_input_is_one_line(tmp_path: Path) -> None:
    runner = CliRunner()
    r = runner.invoke(experiment, ["li2019", "--runs", "0", "--out", str(tmp_path / "o")])
    assert r.exit_code == 2
    assert r.output.strip().startswith("error:") and "--runs" in r.output
    f = tmp_path / "afile"
    f.write_text("x")
    r = runner.invoke(experiment, ["li2019", "--quick", "--no-progress", "--out", str(f)])
    assert r.exit_code == 2
    assert len(r.output.strip().splitlines()) == 1 and "afile" in r.output
    args = ["li2019", "--quick", "--no-progress", "--engine", "local", "--scheduler", "tcp://127.0.0.1:1"]
    r = runner.invoke(experiment, [*args, "--out", str(tmp_path / "o2")])
    assert r.exit_code == 2
    assert len(r.output.strip().splitlines()) == 1 and "needs the dask engine" in r.output
    assert not (tmp_path / "o2").exists()  # refused before any work


# ------------------------------------------------------------------- the paper's AR scheme
def _prior_cfg(robust: str, ar: str) -> Config:
    """The paper's scheme spelled out with flat keys (as ``solve`` flags would give it),
    independently of the experiment's ``rtk_config``."""
    return Config.of(
        mode="rtk", robust=robust, k0=2.0, k1=8.0, ar=ar, dynamics="static", hold=False,
        ar_scheme="prior", prior_sigma_m=0.1, prior_ambiguities="carry", fix_residual_k=4.0, slip="lli",
    )  # fmt: skip


def test_fig9_prior_scheme_cells_match_a_solve_from_files(one: Report) -> None:
    """Fig. 9 in the paper's scheme: the report's cells equal a solve of the written files
    with the scheme's flat settings, counted by hand."""
    res = _results(one)
    st = res["stats"]
    md = one.report_path.read_text(encoding="utf-8")
    rows = _by_header(_section(md, "RTK static, 0.15 m"))
    by = {r["Scheme"]: r for r in rows if r["AR mode"] == "paper's scheme (prior)"}
    sim = simulate(load_scenario("li2019_rtk_static_015"), np.random.default_rng(0), n_epochs=130)
    paths = write_simulation(sim, one.out_dir / "indep_prior")
    for name, rob, ar in (
        ("SUKF", "none", "lambda"),
        ("RUKF", "igg3", "lambda"),
        ("RUKF+PAR", "igg3", "par"),
    ):
        run = solve_pseudolite(paths["obs.csv"], paths["site.toml"], _prior_cfg(rob, ar))
        d3 = np.linalg.norm(np.array([s.pos_m for s in run.solutions]) - sim.truth_pos_m, axis=1)
        status = [s.status for s in run.solutions]
        fixed = [s in ("fixed", "partial") for s in status]
        later = [k for k in range(100, len(fixed)) if fixed[k]]
        refix = float(later[0] - 100) if later else float(len(fixed) - 100)
        p = f"rtk015.prior.{name}"
        assert st[f"{p}.jump_m"]["median"] == pytest.approx(d3[100] - d3[99], abs=1e-9)
        assert st[f"{p}.fixed_at_fault"]["median"] == float(fixed[100])
        assert st[f"{p}.fix_rate"]["median"] == pytest.approx(np.mean(fixed))
        assert st[f"{p}.refix_epochs"]["median"] == refix
        assert float(by[name]["Jump (m)"]) == pytest.approx(d3[100] - d3[99], abs=5e-4)
        assert float(by[name]["Fixed at 100"]) == float(fixed[100])
        # PL4-PL1's Δv̄ and IGG-III weight at epoch 100, from the solve's own diagnostics
        t100 = run.solutions[100].t_s
        row = next(r for r in run.diagnostics if r.dd == "PL4-PL1" and r.t_s == t100)
        assert float(by[name]["PL4 Δv̄ at 100"]) == pytest.approx(row.dv, abs=0.05)
        assert float(by[name]["PL4 weight at 100"]) == pytest.approx(1.0 / row.factor, abs=0.005)
        if name == "SUKF":
            assert row.factor == 1.0  # no robust policy: every weight stays 1


def test_fig9_variants_follow_their_mechanisms(one: Report) -> None:
    """The two Fig. 9 variants do what the report says: with the solver's default slip
    detectors SUKF's PL4 ambiguity is reset at epoch 100 and absorbs the error (post-fit
    residual near zero, unlike with loss-of-lock flags only); with the paper's literal Δv̄
    PL4-PL1 is not down-weighted, so RUKF's solution equals SUKF's at that epoch."""
    st = _results(one)["stats"]
    sim = simulate(load_scenario("li2019_rtk_static_015"), np.random.default_rng(0), n_epochs=130)
    paths = write_simulation(sim, one.out_dir / "indep_variants")
    poly = dataclasses.replace(_prior_cfg("none", "lambda"), slip=SlipConfig(detectors="lli+poly"))
    run_poly = solve_pseudolite(paths["obs.csv"], paths["site.toml"], poly)
    run_lli = solve_pseudolite(paths["obs.csv"], paths["site.toml"], _prior_cfg("none", "lambda"))
    t100 = run_lli.solutions[100].t_s

    def resid(run: RunResult) -> float:
        return next(r.residual for r in run.diagnostics if r.dd == "PL4-PL1" and r.t_s == t100)

    assert abs(resid(run_poly)) < 0.2 * abs(resid(run_lli))
    d3 = np.linalg.norm(np.array([s.pos_m for s in run_poly.solutions]) - sim.truth_pos_m, axis=1)
    assert st["rtk015.prior_poly.SUKF.jump_m"]["median"] == pytest.approx(d3[100] - d3[99], abs=1e-9)
    # the literal recipe: weight 1 on PL4-PL1 at epoch 100, and then the same update as SUKF
    lit = "rtk015.prior_lit"
    if st[f"{lit}.RUKF.pl4_weight_at_fault"]["median"] == 1.0:
        assert st[f"{lit}.RUKF.jump_m"]["median"] == pytest.approx(
            st[f"{lit}.SUKF.jump_m"]["median"], abs=0.01
        )


def test_one_redundancy_makes_every_standardized_residual_equal() -> None:
    """docs/algorithms.md §20: with one redundancy (four DDs, three coordinates) the
    posterior residuals of a least-squares update, standardized with their covariance, all
    have the same magnitude, so Δv̄ = ±1 on every row whatever the error; with a second
    redundancy the statistics differ and the row with the gross error has the largest."""
    rng = np.random.default_rng(11)
    for n_obs in (4, 5):
        H = rng.standard_normal((n_obs, 3))
        R = np.diag(rng.uniform(0.5, 2.0, n_obs))
        W = np.linalg.inv(R)
        y = rng.standard_normal(n_obs) * 0.1
        y[1] += 5.0  # gross error on one row
        x = np.linalg.solve(H.T @ W @ H, H.T @ W @ y)
        v = y - H @ x
        Cvv = R - H @ np.linalg.inv(H.T @ W @ H) @ H.T
        std = v / np.sqrt(np.diag(Cvv))
        dv = discriminant_statistic(std)
        if n_obs == 4:
            np.testing.assert_allclose(np.abs(std), np.abs(std[0]), rtol=1e-9)
            np.testing.assert_allclose(np.abs(dv), 1.0, rtol=1e-9)
        else:
            assert int(np.argmax(np.abs(dv))) == 1 and np.abs(dv).max() > 2.0 * np.abs(dv).min()


def test_claims_count_and_why_column(one: Report) -> None:
    """The report states how many claims hold, and every claim row carries a reason."""
    md = one.report_path.read_text(encoding="utf-8")
    sec = _section(md, "Claims")
    n = sum(1 for c in one.claims if c.holds)
    assert f"{n} of {len(one.claims)} claims hold" in sec
    rows = _table_rows(sec)
    assert all(len(r) == 6 and r[5] for r in rows)
    assert all(c.why for c in one.claims)


def test_calibration_table_states_paper_and_simulation(one: Report) -> None:
    """The calibration table puts the paper's stated setting beside the scenario, and its
    run-derived cells equal the statistics."""
    md = one.report_path.read_text(encoding="utf-8")
    rows = _by_header(_section(md, "The simulated room"))
    by = {r["Quantity"]: r for r in rows}
    assert "10 m × 7 m × 4 m" in by["Room"]["Paper"] and by["Room"]["Simulation"] == "10 m × 7 m × 4 m"
    assert by["DPL epochs"]["Simulation"] == str(load_scenario("li2019_dpl_static").n_epochs)
    assert by["RTK epochs (static, rail)"]["Simulation"] == "270, 270"
    st = _results(one)["stats"]
    share = st["rtk.static_orig.PL4.frac_resid_lt_5mm"]["median"]
    assert f"share < 5 mm {share:.2f}" in by["Phase noise"]["Simulation"]


def test_dd_dop_against_brute_force() -> None:
    """DD DOP: the formula against the covariance of least-squares positions from sampled
    unit-variance single differences (Monte Carlo)."""
    from robustrtk.experiments.li2019.calibration import dd_dop

    sc = load_scenario("li2019_dpl_static")
    tx = dict(sc.transmitters)
    x = np.asarray(sc.trajectory.start_m)
    dop = dd_dop(tx, sc.reference, x, sc.base_position_m)
    ids = list(tx)
    u = {t: (x - np.asarray(tx[t])) / np.linalg.norm(x - np.asarray(tx[t])) for t in ids}
    others = [t for t in ids if t != sc.reference]
    H = np.array([u[t] - u[sc.reference] for t in others])
    rng = np.random.default_rng(3)
    sd = rng.standard_normal((40_000, len(ids)))  # single differences, unit variance
    i_ref = ids.index(sc.reference)
    dd = np.stack([sd[:, ids.index(t)] - sd[:, i_ref] for t in others], axis=1)
    C = np.eye(len(others)) + np.ones((len(others), len(others)))
    W = np.linalg.inv(C)
    est = dd @ (W @ H @ np.linalg.inv(H.T @ W @ H))
    np.testing.assert_allclose(est.std(axis=0), dop, rtol=0.02)


@pytest.mark.slow
def test_full_run_claims_and_fig9_acceptance(tmp_path: Path) -> None:
    """The full run (paper sizes, 5 seeds): the claims table agrees with an independent
    recount of the per-seed values, and the Fig. 9 verdicts follow from them."""
    rep = run_li2019(tmp_path / "full", runs=5, seed=0, progress=False, quick=False)
    res = _results(rep)
    per = res["per_run"]
    assert len(per) == 5 and res["dpl_epochs"] == 11000

    def med(key: str) -> float:
        v = np.array([np.nan if r.get(key) is None else r[key] for r in per], dtype=float)
        return float(np.median(v[np.isfinite(v)]))

    by = {c["claim"]: c for c in res["claims"]}
    p = "rtk015.prior"
    fail = next(c for k, c in by.items() if k.startswith("SUKF / RUKF fail AR at epoch 100"))
    assert fail["holds"] is (med(f"{p}.SUKF.fixed_at_fault") == 0 and med(f"{p}.RUKF.fixed_at_fault") == 0)
    refix = next(c for k, c in by.items() if k.startswith("Epochs to re-fix"))
    assert refix["holds"] is (med(f"{p}.RUKF.refix_epochs") < med(f"{p}.SUKF.refix_epochs"))
    par = next(c for k, c in by.items() if k.startswith("RUKF+PAR is fixed at every epoch"))
    assert par["holds"] is (med(f"{p}.RUKF+PAR.fix_rate") >= 0.999)
    md = rep.report_path.read_text(encoding="utf-8")
    n = sum(1 for c in res["claims"] if c["holds"])
    assert f"{n} of {len(res['claims'])} claims hold" in md


def test_impulse_share_bound_against_brute_force() -> None:
    """max_K K (1 − K)^j over a fine grid of gains equals the closed form, at K = 1/(j+1)."""
    K = np.linspace(0.0, 1.0, 200_001)
    for j in range(16):
        share = K * (1.0 - K) ** j
        assert impulse_share_bound(j) == pytest.approx(share.max(), rel=1e-8)
        assert K[np.argmax(share)] == pytest.approx(1.0 / (j + 1), abs=1e-5)
    # the longer after the error, the less any gain can keep
    assert all(impulse_share_bound(j + 1) < impulse_share_bound(j) for j in range(30))
    with pytest.raises(ValueError, match="non-negative"):
        impulse_share_bound(-1)


def _q_cfg(robust: str, ar: str, sigma_m: float) -> Config:
    """The process-noise sensitivity spelled out with flat keys, independently of
    ``q_config``: fix-and-hold, random-walk coordinate of σ per second, 4 σ residual test."""
    return Config.of(
        mode="rtk", filter="ukf", robust=robust, k0=2.0, k1=8.0, ar=ar, dynamics="kinematic",
        kinematic_model="random-walk", sigma_vel_m_s=sigma_m, hold=True, init_sigma_m=0.1,
        fix_residual_k=4.0, slip="lli",
    )  # fmt: skip


def test_process_noise_sweep_matches_a_solve_from_files(one: Report) -> None:
    """The process-noise table: one row per σ of a quick run, its Fig. 9 cells equal a solve
    of the written files with the flat settings, counted by hand, and its Fig. 8 cells equal
    the statistics."""
    st = _results(one)["stats"]
    md = one.report_path.read_text(encoding="utf-8")
    rows = _by_header(_section(md, "RTK static, 0.15 m"), "σ (m per epoch)")
    assert [float(r["σ (m per epoch)"]) for r in rows] == list(Q_SIGMAS_QUICK_M)
    sim = simulate(load_scenario("li2019_rtk_static_015"), np.random.default_rng(0), n_epochs=130)
    paths = write_simulation(sim, one.out_dir / "indep_q")
    q = Q_SIGMAS_QUICK_M[0]
    row = rows[0]
    for name, rob, ar in (("SUKF", "none", "lambda"), ("RUKF", "igg3", "lambda")):
        run = solve_pseudolite(paths["obs.csv"], paths["site.toml"], _q_cfg(rob, ar, q))
        d3 = np.linalg.norm(np.array([s.pos_m for s in run.solutions]) - sim.truth_pos_m, axis=1)
        fixed = [s.status in ("fixed", "partial") for s in run.solutions]
        later = [k for k in range(100, len(fixed)) if fixed[k]]
        refix = float(later[0] - 100) if later else float(len(fixed) - 100)
        p = f"rtk015.q@{q:g}.{name}"
        assert st[f"{p}.jump_m"]["median"] == pytest.approx(d3[100] - d3[99], abs=1e-9)
        assert st[f"{p}.refix_epochs"]["median"] == refix
        assert float(row[f"Fig. 9 {name} jump (m)"]) == pytest.approx(d3[100] - d3[99], abs=5e-4)
        assert float(row[f"{name} epochs to re-fix"]) == refix
        assert float(row[f"Fig. 8 {name} extra (m)"]) == pytest.approx(
            st[f"rtk.static_q@{q:g}.{name}.max_extra_faulty_m"]["median"], abs=5e-5
        )


def test_q_claim_reasons_follow_the_sweep() -> None:
    """The Fig. 8 reason names the σ where SUKF jumps and RUKF removes the jump, and the
    re-fix reason quotes the impulse bound with the run's SUKF jump."""
    vals: dict[str, float] = {
        "rtk015.prior.SUKF.jump_m": 0.15,
        "rtk015.prior.SUKF.refix_epochs": 1.0,
        "rtk015.prior.RUKF.refix_epochs": 1.0,
    }
    for q in Q_SIGMAS_M:
        su, ru = (0.04, 0.004) if q == 0.003 else (0.05, 0.05)
        vals[f"rtk.static_q@{q:g}.SUKF.max_extra_faulty_m"] = su
        vals[f"rtk.static_q@{q:g}.RUKF.max_extra_faulty_m"] = ru
        vals[f"rtk015.q@{q:g}.SUKF.jump_m"] = 0.1 * q / 0.003

    def s(key: str) -> float:
        return vals.get(key, 0.0)

    def f(key: str, fmt: str) -> str:
        return format(s(key), fmt if fmt != "d" else ".0f")

    claims = {c.claim[:30]: c for c in build_claims(s, PAPER_DPL_EPOCHS, f)}
    fig8 = next(c for k, c in claims.items() if k.startswith("RUKF identifies the cm-level"))
    assert "holds for σ = 0.003 m" in fig8.why and "0.100–0.100 m" in fig8.why
    assert "no single Q gives Fig. 8 and Fig. 9's jump together" in fig8.why
    # a σ whose Fig. 9 jump is within 5 cm of the paper's 0.16 m and whose Fig. 8 shape holds
    vals["rtk015.q@0.003.SUKF.jump_m"] = 0.15
    fig8 = next(c for c in build_claims(s, PAPER_DPL_EPOCHS, f) if c.claim.startswith("RUKF identifies"))
    assert "σ = 0.003 m gives both" in fig8.why
    refix = next(c for k, c in claims.items() if k.startswith("Epochs to re-fix"))
    assert f"{100 * impulse_share_bound(11):.1f} %" in refix.why
    assert f"{1000 * impulse_share_bound(11) * 0.15:.1f} mm" in refix.why
