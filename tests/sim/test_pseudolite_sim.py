"""Indoor pseudolite simulator: DD invariant, noise levels, fault placement, files, presets."""

from __future__ import annotations

import csv
import dataclasses
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk.core import InputError
from robustrtk.io.obstable import read_obs_table
from robustrtk.io.site import read_site
from robustrtk.sim import (
    OUTPUT_FILES,
    Scenario,
    SimResult,
    list_presets,
    load_scenario,
    run_simulate,
    simulate,
    write_simulation,
)
from robustrtk.sim.pseudolite import gauss_markov
from robustrtk.sim.scenario import (
    Bursts,
    Clocks,
    Multipath,
    Noise,
    RandomGross,
    ScheduledGross,
    ScheduledSlip,
    Slips,
    Trajectory,
)

QUIET = Noise(code_sigma_m=0.0, phase_sigma_m=0.0)
NO_MP = Multipath(code_sigma_m=0.0, phase_sigma_m=0.0)
RAIL = Trajectory(kind="rail", start_m=(-2.7, -0.5, -1.5), end_m=(2.7, -0.5, -1.5), speed_m_s=0.02)


def _clean(**kw: object) -> Scenario:
    base = dict(n_epochs=200, noise=(QUIET, QUIET), multipath=NO_MP)
    base.update(kw)
    return Scenario(**base)  # type: ignore[arg-type]


def _dd(res: SimResult) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """DD code (m), DD phase (cycles) and DD geometric range (m) from the simulated data,
    with the truth recomputed independently from the site and the rover truth."""
    ref = res.tx_ids.index(res.site.reference)
    tx = res.site.tx_positions_m(res.tx_ids)
    rho_r = np.linalg.norm(tx[None] - res.truth_pos_m[:, None], axis=2)
    rho_b = np.linalg.norm(tx - res.site.base_pos_m, axis=1)[None]
    sd_rho = rho_r - rho_b
    r, b = res.batches["rover"], res.batches["base"]
    sd_code = r.code_m[..., 0] - b.code_m[..., 0]
    sd_phase = r.phase_cyc[..., 0] - b.phase_cyc[..., 0]
    return (
        sd_code - sd_code[:, [ref]],
        sd_phase - sd_phase[:, [ref]],
        sd_rho - sd_rho[:, [ref]],
    )


@settings(max_examples=20, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    offset_s=st.sampled_from([0.0, 1e-6, 1e-4, 1e-2]),
    drift=st.sampled_from([0.0, 1e-8, 1e-6]),
    rw=st.sampled_from([0.0, 1e-10, 1e-8]),
    traj=st.sampled_from(["static", "rail", "free"]),
    reference=st.sampled_from(["PL1", "PL6", "PL8"]),
)
def test_double_difference_cancels_clocks_and_fractional_phases(
    seed: int, offset_s: float, drift: float, rw: float, traj: str, reference: str
) -> None:
    tr = {"static": Trajectory(), "rail": RAIL, "free": Trajectory(kind="free", speed_m_s=0.5)}
    clocks = Clocks(offset_s, drift, offset_s, drift, rw)
    res = simulate(
        _clean(clocks=clocks, trajectory=tr[traj], reference=reference), np.random.default_rng(seed)
    )
    dd_code, dd_phase, dd_rho = _dd(res)
    lam = res.scenario.wavelength_m
    np.testing.assert_allclose(dd_code, dd_rho, rtol=0, atol=1e-6)
    np.testing.assert_allclose(dd_phase * lam, dd_rho + lam * res.dd_ambiguity_cyc, rtol=0, atol=1e-6)
    # the ambiguities really are integers away from zero and the clocks really are there
    assert np.all(res.dd_ambiguity_cyc[:, res.tx_ids.index(reference)] == 0)
    if offset_s >= 1e-4:
        sd_code = res.batches["rover"].code_m[0, :, 0] - res.batches["base"].code_m[0, :, 0]
        assert np.ptp(sd_code) < 20 and np.max(np.abs(sd_code)) > 10.0  # receiver clocks


def test_undifferenced_model_matches_equation() -> None:
    """Without clocks the undifferenced code is the range and the phase is range / lambda +
    an offset constant in time (integer + fractional parts)."""
    clocks = Clocks(0.0, 0.0, 0.0, 0.0, 0.0)
    res = simulate(_clean(clocks=clocks, trajectory=RAIL), np.random.default_rng(5))
    tx = res.site.tx_positions_m(res.tx_ids)
    rho = np.linalg.norm(tx[None] - res.truth_pos_m[:, None], axis=2)
    r = res.batches["rover"]
    np.testing.assert_allclose(r.code_m[..., 0], rho, atol=1e-9)
    off = r.phase_cyc[..., 0] - rho / res.scenario.wavelength_m
    np.testing.assert_allclose(off - off[0], 0.0, atol=1e-6)
    assert np.any(np.abs(off[0] - np.round(off[0])) > 1e-3)  # fractional offsets present


def test_noise_levels_of_double_differences() -> None:
    n = Noise(code_sigma_m=0.4, phase_sigma_m=0.003)
    sc = Scenario(n_epochs=4000, noise=(n, n), multipath=NO_MP)
    res = simulate(sc, np.random.default_rng(11))
    dd_code, dd_phase, dd_rho = _dd(res)
    lam = sc.wavelength_m
    ref = res.tx_ids.index(sc.reference)
    keep = [i for i in range(len(res.tx_ids)) if i != ref]
    e_code = (dd_code - dd_rho)[:, keep]
    e_phase = (dd_phase * lam - dd_rho - lam * res.dd_ambiguity_cyc)[:, keep]
    # four independent undifferenced errors per DD: sigma_DD = 2 sigma
    np.testing.assert_allclose(e_code.std(axis=0), 0.8, rtol=0.06)
    np.testing.assert_allclose(e_phase.std(axis=0), 0.006, rtol=0.06)
    # DDs sharing the reference are correlated with coefficient 1/2
    c = np.corrcoef(e_code.T)
    np.testing.assert_allclose(c[np.triu_indices(len(keep), 1)], 0.5, atol=0.06)


def test_gauss_markov_statistics() -> None:
    rng = np.random.default_rng(2)
    x = gauss_markov((20000, 8), 0.5, 30.0, 1.0, rng)
    assert x.std() == pytest.approx(0.5, rel=0.05)
    a = np.exp(-1.0 / 30.0)
    lag1 = np.mean(x[1:] * x[:-1]) / np.mean(x * x)
    lag30 = np.mean(x[30:] * x[:-30]) / np.mean(x * x)
    assert lag1 == pytest.approx(a, abs=0.01)
    assert lag30 == pytest.approx(np.exp(-1.0), abs=0.08)
    assert abs(x[0].std() - 0.5) < 0.35  # stationary start (no warm-up transient)


def test_multipath_only_on_selected_receivers() -> None:
    mp = Multipath(code_sigma_m=0.5, code_tau_s=60.0, phase_sigma_m=0.0, receivers=("rover",))
    res = simulate(_clean(multipath=mp, n_epochs=3000), np.random.default_rng(4))
    clean = simulate(_clean(n_epochs=3000), np.random.default_rng(4))
    d_rover = res.batches["rover"].code_m - clean.batches["rover"].code_m
    d_base = res.batches["base"].code_m - clean.batches["base"].code_m
    assert np.all(d_base == 0)
    assert d_rover.std() == pytest.approx(0.5, rel=0.2)


# ------------------------------------------------------------------------------- faults


def _read_faults(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


FAULTY = dict(
    bursts=Bursts(
        code_probability=0.05,
        code_length_epochs=(1, 6),
        phase_probability=0.03,
        phase_size_m=(0.02, 0.05),
        weights=(("PL4", 3.0), ("PL8", 1.0), ("PL1", 0.0)),
    ),
    random_gross=(RandomGross("code", 12, 10.0), RandomGross("phase", 3, 0.15, random_sign=True)),
    gross=(
        ScheduledGross("phase", "PL4", (10, 11, 12, 100), 0.05),
        ScheduledGross("code", "PL5", (7,), 3.0, receiver="base"),
    ),
    slips=Slips(
        probability=0.002,
        receivers=("base", "rover"),
        scheduled=(ScheduledSlip("rover", "PL6", 150, -4, silent=True),),
    ),
)


def test_faults_csv_equals_difference_of_faulty_and_clean_runs(tmp_path: Path) -> None:
    n = Noise()
    common = dict(n_epochs=400, noise=(n, n))
    clean = simulate(Scenario(**common), np.random.default_rng(99))  # type: ignore[arg-type]
    faulty = simulate(
        Scenario(**common, **FAULTY),  # type: ignore[arg-type]
        np.random.default_rng(99),
    )
    write_simulation(faulty, tmp_path)
    rows = _read_faults(tmp_path / "faults.csv")
    assert len(rows) == len(faulty.faults) > 30
    T, N = 400, len(clean.tx_ids)
    lam = clean.scenario.wavelength_m
    for rx in ("base", "rover"):
        exp_code = np.zeros((T, N))
        exp_phase_m = np.zeros((T, N))
        exp_slip = np.zeros((T, N))
        exp_lli = np.zeros((T, N), dtype=int)
        for row in rows:
            if row["receiver"] != rx:
                continue
            k, i = int(row["epoch"]), clean.tx_ids.index(row["transmitter"])
            assert float(row["time"]) == clean.t_s[k]
            if row["kind"] == "gross":
                assert row["unit"] == "m"
                target = exp_code if row["observable"] == "code" else exp_phase_m
                target[k, i] += float(row["size"])
            else:
                assert row["kind"] == "slip" and row["unit"] == "cyc"
                exp_slip[k, i] += float(row["size"])
                exp_lli[k, i] = 0 if (k, i) == (150, clean.tx_ids.index("PL6")) else 1
        got_code = faulty.batches[rx].code_m[..., 0] - clean.batches[rx].code_m[..., 0]
        got_phase = faulty.batches[rx].phase_cyc[..., 0] - clean.batches[rx].phase_cyc[..., 0]
        np.testing.assert_allclose(got_code, exp_code, atol=1e-6)
        np.testing.assert_allclose(got_phase, exp_phase_m / lam + np.cumsum(exp_slip, axis=0), atol=1e-6)
        np.testing.assert_array_equal(faulty.batches[rx].lli[..., 0], exp_lli)
        np.testing.assert_array_equal(faulty.batches[rx].cn0_dbhz, clean.batches[rx].cn0_dbhz)
    # no burst / random gross error on the reference or on the zero-weight transmitter
    for row in rows:
        if row["source"] in ("burst", "random_gross"):
            assert row["transmitter"] != "PL6"
        if row["source"] == "burst":
            assert row["transmitter"] != "PL1"
            lo, hi = (0.6, 2.5) if row["observable"] == "code" else (0.02, 0.05)
            assert lo <= abs(float(row["size"])) <= hi
    sched = [(r["epoch"], r["transmitter"]) for r in rows if r["source"] == "scheduled"]
    assert sorted(sched) == sorted(
        [("10", "PL4"), ("11", "PL4"), ("12", "PL4"), ("100", "PL4"), ("7", "PL5")]
    )
    rg = [r for r in rows if r["source"] == "random_gross" and r["observable"] == "code"]
    assert len(rg) == 12 and len({r["epoch"] for r in rg}) == 12
    assert all(float(r["size"]) == 10.0 for r in rg)


def test_scheduled_gross_error_enters_exactly_one_dd() -> None:
    g = (ScheduledGross("phase", "PL4", (20, 21), 0.15), ScheduledGross("code", "PL8", (30,), 10.0))
    res = simulate(_clean(reference="PL1", gross=g, n_epochs=60), np.random.default_rng(1))
    dd_code, dd_phase, dd_rho = _dd(res)
    lam = res.scenario.wavelength_m
    e_phase = dd_phase * lam - dd_rho - lam * res.dd_ambiguity_cyc
    e_code = dd_code - dd_rho
    hit_phase = np.argwhere(np.abs(e_phase) > 1e-6)
    hit_code = np.argwhere(np.abs(e_code) > 1e-6)
    i4, i8 = res.tx_ids.index("PL4"), res.tx_ids.index("PL8")
    np.testing.assert_array_equal(hit_phase, [[20, i4], [21, i4]])
    np.testing.assert_array_equal(hit_code, [[30, i8]])
    np.testing.assert_allclose(e_phase[20, i4], 0.15, atol=1e-6)
    np.testing.assert_allclose(e_code[30, i8], 10.0, atol=1e-6)


def test_slip_changes_true_dd_ambiguity() -> None:
    slips = Slips(scheduled=(ScheduledSlip("rover", "PL5", 40, 7), ScheduledSlip("base", "PL6", 50, 3)))
    res = simulate(_clean(slips=slips, n_epochs=80), np.random.default_rng(8))
    n = res.dd_ambiguity_cyc
    i5 = res.tx_ids.index("PL5")
    others = [i for i in range(len(res.tx_ids)) if res.tx_ids[i] != "PL6"]
    np.testing.assert_array_equal(n[40, i5] - n[39, i5], 7)
    # DD = (N_r^s - N_b^s) - (N_r^ref - N_b^ref): +3 cycles on the base reference phase
    # enters with two minus signs, adding +3 to every DD
    np.testing.assert_array_equal(n[50, others] - n[49, others], 3)
    assert np.count_nonzero(np.diff(n, axis=0)) == 1 + len(others)
    dd_code, dd_phase, dd_rho = _dd(res)  # the invariant holds across the slips
    np.testing.assert_allclose(dd_phase * res.scenario.wavelength_m, dd_rho + 0.19029367 * n, atol=1e-6)
    assert res.batches["rover"].lli[40, i5, 0] == 1 and res.batches["rover"].lli.sum() == 1


def test_gross_error_on_reference_is_rejected() -> None:
    with pytest.raises(InputError, match=r"gross\[0\]\.transmitter: PL6 is the reference"):
        Scenario(n_epochs=10, gross=(ScheduledGross("code", "PL6", (1,), 10.0),))
    with pytest.raises(InputError, match=r"gross\[0\]\.epochs: epoch 10 outside 0\.\.9"):
        Scenario(n_epochs=10, gross=(ScheduledGross("code", "PL4", (10,), 10.0),))


# ------------------------------------------------------------------------- trajectories


def test_rail_trajectory_speed_and_ends() -> None:
    res = simulate(_clean(trajectory=RAIL, n_epochs=270), np.random.default_rng(0))
    p = res.truth_pos_m
    np.testing.assert_allclose(p[0], RAIL.start_m)
    step = np.linalg.norm(np.diff(p, axis=0), axis=1)
    np.testing.assert_allclose(step, 0.02, atol=1e-12)
    back = dataclasses.replace(RAIL, rail_mode="back_and_forth", speed_m_s=0.5)
    res = simulate(_clean(trajectory=back, n_epochs=60), np.random.default_rng(0))
    x = res.truth_pos_m[:, 0]
    assert x.min() == pytest.approx(-2.7) and x.max() == pytest.approx(2.7)
    step = np.abs(np.diff(x))
    assert np.all(step <= 0.5 + 1e-9)  # 0.5 m per epoch of path, less across a turn
    assert np.count_nonzero(np.isclose(step, 0.5)) >= 54
    # 30 m of path over a 5.4 m rail: five turns
    assert np.count_nonzero(np.diff(np.sign(np.diff(x)))) == 5


def test_free_drive_stays_in_area() -> None:
    tr = Trajectory(kind="free", start_m=(0, 0, -1.7), speed_m_s=0.3, area_m=(-4, 4, -2.5, 2.5))
    res = simulate(_clean(trajectory=tr, n_epochs=3000), np.random.default_rng(6))
    p = res.truth_pos_m
    assert p[:, 0].min() >= -4 and p[:, 0].max() <= 4
    assert p[:, 1].min() >= -2.5 and p[:, 1].max() <= 2.5
    assert np.all(p[:, 2] == -1.7)
    speed = np.linalg.norm(np.diff(p, axis=0), axis=1)
    assert 0.05 < np.median(speed) < 1.0
    assert np.ptp(p[:, 0]) > 3 and np.ptp(p[:, 1]) > 2  # covers the room


# -------------------------------------------------------------- determinism and files


def test_determinism() -> None:
    sc = load_scenario("demo")
    a = simulate(sc, np.random.default_rng(123), n_epochs=100)
    b = simulate(sc, np.random.default_rng(123), n_epochs=100)
    c = simulate(sc, np.random.default_rng(124), n_epochs=100)
    for rx in ("base", "rover"):
        np.testing.assert_array_equal(a.batches[rx].phase_cyc, b.batches[rx].phase_cyc)
        np.testing.assert_array_equal(a.batches[rx].code_m, b.batches[rx].code_m)
        assert not np.array_equal(a.batches[rx].code_m, c.batches[rx].code_m)
    np.testing.assert_array_equal(a.faults.size, b.faults.size)


def test_written_files_read_back(tmp_path: Path) -> None:
    res = run_simulate("li2019_rtk_rail", 7, tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(OUTPUT_FILES)
    site = read_site(tmp_path / "site.toml")
    assert site.reference == "PL1" and site.wavelength_m == 0.19029367
    obs = read_obs_table(tmp_path / "obs.csv", wavelength_m=site.wavelength_m)
    for rx in ("base", "rover"):
        np.testing.assert_array_equal(obs[rx].phase_cyc, res.batches[rx].phase_cyc)
        np.testing.assert_array_equal(obs[rx].code_m, res.batches[rx].code_m)
        np.testing.assert_array_equal(obs[rx].lli, res.batches[rx].lli)
    truth = np.loadtxt(tmp_path / "truth.csv", delimiter=",", skiprows=1)
    np.testing.assert_array_equal(truth[:, 1:], res.truth_pos_m)
    with open(tmp_path / "ambiguities.csv", newline="") as fh:
        amb = list(csv.DictReader(fh))
    assert len(amb) == 270 * 4 and {r["reference"] for r in amb} == {"PL1"}
    for r in amb[::37]:
        k = int(float(r["time"]))
        assert int(r["N_cyc"]) == res.dd_ambiguity_cyc[k, res.tx_ids.index(r["transmitter"])]
    np.testing.assert_array_equal(site.rover_initial_pos_m, res.truth_pos_m[0])  # KPI exact


# ------------------------------------------------------------------------------ presets


@pytest.mark.parametrize("name", list_presets())
def test_every_preset_loads_and_simulates(name: str) -> None:
    sc = load_scenario(name)
    assert sc.name == name and sc.description
    res = simulate(sc, np.random.default_rng(0), n_epochs=120)
    assert res.truth_pos_m.shape == (120, 3)
    for b in res.batches.values():
        assert b.code_m.shape == (120, 5, 1) and np.all(np.isfinite(b.phase_cyc))
        assert np.all((b.cn0_dbhz > 30) & (b.cn0_dbhz < 60))
    assert np.all(res.faults.epoch < 120)
    # inside the room (10 x 7 x 4 m centred on the origin)
    assert np.all(np.abs(res.truth_pos_m) <= [5, 3.5, 2])


def test_presets_match_the_experiments() -> None:
    assert set(list_presets()) >= {
        "li2019_dpl_static",
        "dpl_static",
        "dpl_rail",
        "li2019_rtk_static",
        "li2019_rtk_static_015",
        "li2019_rtk_rail",
        "li2019_rtk_rail_015",
        "demo",
        "free_drive",
    }
    s = load_scenario("li2019_rtk_static_015")
    assert s.n_epochs == 270 and s.reference == "PL1"
    assert s.gross == (ScheduledGross("phase", "PL4", (100,), 0.15),)
    r = load_scenario("li2019_rtk_rail_015")
    assert r.trajectory.kind == "rail" and r.gross[0].epochs == (50,)
    res = simulate(load_scenario("li2019_dpl_static"), np.random.default_rng(1))
    assert len(res.t_s) == 11000
    rg = [k for k, s_ in enumerate(res.faults.source) if s_ == "random_gross"]
    assert len(rg) == 20 and np.all(res.faults.size[rg] == 10.0)
    burst = np.array([s_ == "burst" for s_ in res.faults.source])
    assert np.unique(res.faults.epoch[burst]).size > 2000  # frequent small gross errors
    assert "PL6" not in {res.faults.transmitter[k] for k in np.flatnonzero(burst)}


# ------------------------------------------------------------------------ bad scenarios


def _scn(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "s.toml"
    p.write_text(text)
    return p


@pytest.mark.parametrize(
    ("text", "pattern"),
    [
        ("n_epochs = 10\nnepochs = 3\n", r"nepochs: unknown key"),
        ("interval_s = 1\n", r"n_epochs: missing"),
        ("n_epochs = 'a'\n", r"n_epochs: expected an integer"),
        ("n_epochs = 5\n[trajectory]\nkind = 'fly'\n", r"trajectory\.kind: expected one of"),
        ("n_epochs = 5\n[trajectory]\nkind = 'rail'\n", r"trajectory\.end_m: expected the rail"),
        ("n_epochs = 5\n[noise.rover]\ncode_sigma_m = -1\n", r"noise\.rover\.code_sigma_m"),
        ("n_epochs = 5\nreference = 'PL9'\n", r"reference: unknown transmitter 'PL9'"),
        (
            "n_epochs = 5\n[[gross]]\ntransmitter='PL4'\nepochs=[1]\nsize_m=1\nobservable='dd'\n",
            r"gross\[0\]\.observable",
        ),
        ("n_epochs = 5\n[[gross]]\ntransmitter='PL4'\nsize_m=1\n", r"gross\[0\]\.epochs"),
        (
            "n_epochs = 5\n[[random_gross]]\nobservable='code'\ncount=2\n",
            r"random_gross\[0\]\.size_m: missing",
        ),
        ("n_epochs = 5\n[bursts]\ncode_size_m = [2, 1]\n", r"bursts\.code_size_m"),
        ("n_epochs = 5\n[transmitters]\nPL1 = [0, 0]\n", r"transmitters\.PL1: expected a list of 3"),
    ],
)
def test_bad_scenario_names_field(tmp_path: Path, text: str, pattern: str) -> None:
    p = _scn(tmp_path, text)
    with pytest.raises(InputError, match=pattern) as ei:
        load_scenario(str(p))
    assert str(ei.value).startswith(str(p))


def test_scenario_syntax_error_and_unknown_preset(tmp_path: Path) -> None:
    p = _scn(tmp_path, "n_epochs = 5\n[noise\n")
    with pytest.raises(InputError) as ei:
        load_scenario(p)
    assert ei.value.line == 2
    with pytest.raises(InputError, match="unknown scenario 'nope'.*demo"):
        load_scenario("nope")


def test_scenario_file_with_epoch_ranges(tmp_path: Path) -> None:
    p = _scn(
        tmp_path,
        "n_epochs = 30\nreference = 'PL1'\n"
        "[[gross]]\nobservable = 'phase'\ntransmitter = 'PL5'\nepochs = [3, [10, 12], 3]\n"
        "size_m = 0.1\n",
    )
    sc = load_scenario(p)
    assert sc.gross[0].epochs == (3, 10, 11, 12)
    assert sc.gross[0].receiver == "rover"
