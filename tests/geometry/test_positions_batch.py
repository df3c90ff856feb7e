"""Satellite positions vectorised over satellites and epochs give, row for row, the numbers
of one call per epoch (real broadcast ephemerides of the shared datasets; all five systems)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk.core import CLIGHT
from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.geometry.orbits import eccentric_anomaly, kepler_ecc_anomaly, kepler_position
from robustrtk.io.rinex_nav import read_rinex_nav
from robustrtk.measurement.signals import RowSource

MOSAIC_NAV = "mosaicx5_static_1m/base.nav"


def _source(shared_data: Path) -> tuple[EphemerisSource, list[str], float]:
    nav = read_rinex_nav(shared_data / MOSAIC_NAV)
    src = EphemerisSource(nav)
    sats = sorted(
        {str(s) for kep in nav.kepler.values() for s in kep.sat_id} | set(map(str, nav.glonass.sat_id))
    )
    t0 = float(np.median(nav.glonass.toe_s))  # inside every system's validity window
    return src, sats, t0


def _epochs(
    rng: np.random.Generator, sats: list[str], t0: float, n_ep: int
) -> list[tuple[float, list[str], np.ndarray]]:
    out = []
    for e in range(n_ep):
        pick = sorted(rng.choice(len(sats), size=min(len(sats), 25), replace=False))
        ids = [sats[i] for i in pick]
        code = rng.uniform(2.0e7, 2.6e7, len(ids))
        code[rng.random(len(ids)) < 0.1] = np.nan
        out.append((t0 + 30.0 * e + rng.uniform(-0.01, 0.01), ids, code))
    return out


def test_positions_at_many_epochs_equals_one_call_per_epoch(shared_data: Path) -> None:
    src, sats, t0 = _source(shared_data)
    epochs = _epochs(np.random.default_rng(5), sats, t0, 40)
    t_all = np.concatenate([np.full(len(ids), t) for t, ids, _ in epochs])
    ids_all = [s for _, ids, _ in epochs for s in ids]
    code_all = np.concatenate([c for _, _, c in epochs])
    pos_b, clk_b = src.positions_at(t_all, ids_all, code_all)
    i0 = 0
    n_finite = 0
    for t, ids, code in epochs:
        pos, clk = src.positions(t, ids, code)
        i1 = i0 + len(ids)
        np.testing.assert_array_equal(pos_b[i0:i1], pos)
        np.testing.assert_array_equal(clk_b[i0:i1], clk)
        n_finite += int(np.isfinite(clk).sum())
        i0 = i1
    assert n_finite > 200  # the comparison is about real positions, not NaN rows
    systems = {s[0] for s, c in zip(ids_all, clk_b, strict=True) if np.isfinite(c)}
    assert {"G", "E", "C", "R"} <= systems


def test_transmission_times_of_many_epochs_equal_one_call_per_epoch(shared_data: Path) -> None:
    """Rows of many epochs in one call give each epoch's transmission times exactly; a second
    source, whose selections are remembered from other lists of ids first, agrees too."""
    src, sats, t0 = _source(shared_data)
    epochs = _epochs(np.random.default_rng(8), sats, t0, 40)
    t_all = np.concatenate([np.full(len(ids), t) for t, ids, _ in epochs])
    ids_all = [s for _, ids, _ in epochs for s in ids]
    code_all = np.concatenate([c for _, _, c in epochs])
    batch = src.transmission_times(t_all, ids_all, code_all)
    warm = EphemerisSource(src.nav)
    for t, ids, code in reversed(epochs):  # the remembered codes of other epochs first
        warm.transmission_time(t, ids, code)
    i0 = 0
    for t, ids, code in epochs:
        i1 = i0 + len(ids)
        one = src.transmission_time(t, ids, code)
        np.testing.assert_array_equal(batch[i0:i1], one)
        np.testing.assert_array_equal(warm.transmission_time(t, ids, code), one)
        np.testing.assert_array_equal(warm.select(one, ids), EphemerisSource(src.nav).select(one, ids))
        i0 = i1
    fin = np.isfinite(batch)
    assert fin.sum() > 200 and np.all(np.abs(t_all[fin] - batch[fin]) < 0.1)  # travel times, not NaN


def test_row_source_prefetch_gives_the_per_epoch_results(shared_data: Path) -> None:
    src, sats, t0 = _source(shared_data)
    rng = np.random.default_rng(11)
    queries = []
    for t, ids, code in _epochs(rng, sats, t0, 20):
        rows = [f"{s}:{slot}" for s in ids for slot in ("L1", "L2")]
        code_rows = np.repeat(code, 2) + rng.normal(0.0, 3.0, len(rows))  # ionosphere-like
        queries.append((t, rows, code_rows))
    plain = RowSource(src)
    fetched = RowSource(src)
    fetched.prefetch(queries)
    for t, rows, code in queries:
        pos, clk = plain.positions(t, rows, code)
        pos_f, clk_f = fetched.positions(t, rows, code)
        np.testing.assert_array_equal(pos_f, pos)
        np.testing.assert_array_equal(clk_f, clk)
    # a query that was not prefetched (other pseudoranges) is computed, not mixed up
    t, rows, code = queries[0]
    fetched.prefetch(queries)
    pos_o, _ = fetched.positions(t, rows, code + 100.0)
    np.testing.assert_array_equal(pos_o, plain.positions(t, rows, code + 100.0)[0])


@settings(max_examples=40, deadline=None)
@given(
    m=st.lists(st.floats(-10.0, 10.0), min_size=2, max_size=12),
    e=st.lists(st.floats(0.0, 0.9), min_size=2, max_size=12),
)
def test_eccentric_anomaly_of_an_element_does_not_depend_on_the_others(
    m: list[float], e: list[float]
) -> None:
    k = min(len(m), len(e))
    mv, ev = np.array(m[:k]), np.array(e[:k])
    together = eccentric_anomaly(mv, ev)
    alone = np.array([eccentric_anomaly(mv[i : i + 1], ev[i : i + 1])[0] for i in range(k)])
    np.testing.assert_array_equal(together, alone)
    np.testing.assert_allclose(together - ev * np.sin(together), mv, atol=1e-12)


def test_ecc_anomaly_alone_is_that_of_the_position(shared_data: Path) -> None:
    nav = read_rinex_nav(shared_data / MOSAIC_NAV)
    for system in ("G", "E", "C", "J"):
        kep = nav.kepler.get(system)
        if kep is None or len(kep) == 0:
            pytest.skip(f"no {system} records")
        t = kep.toe_s + np.linspace(-3600.0, 3600.0, len(kep))
        _, big_e = kepler_position(kep, t, system)
        np.testing.assert_array_equal(kepler_ecc_anomaly(kep, t, system), big_e)


def test_transmission_time_is_the_one_iterated_on_full_satellite_states(shared_data: Path) -> None:
    src, sats, t0 = _source(shared_data)
    n_finite = 0
    for t, ids, code in _epochs(np.random.default_rng(8), sats, t0, 10):
        # the definition: three clock iterations on sat_states (orbits and all)
        t_sv = t - code / CLIGHT
        tgd = src.group_delay_s(t_sv, ids)
        ref = t_sv.copy()
        for _ in range(3):
            ref = t_sv - (src.sat_states(ref, ids)[2] - tgd)
        got = src.transmission_time(t, ids, code)
        np.testing.assert_array_equal(got, ref)
        n_finite += int(np.isfinite(got).sum())
    assert any(s.startswith("R") for s in sats) and n_finite > 100


def _select_whole_table(src: EphemerisSource, t_s: np.ndarray, sat_ids: list[str]) -> np.ndarray:
    """The selection rule written over each system's whole table (every record scored)."""
    t = np.broadcast_to(np.asarray(t_s, dtype=float), (len(sat_ids),))
    ids = np.asarray(sat_ids, dtype="U3")
    sys_letter = np.array([s[:1] for s in ids], dtype="U1")
    row = np.full(len(ids), -1, dtype=np.int64)
    for system in ("G", "E", "C", "J", "R"):
        q = np.nonzero(sys_letter == system)[0]
        tab = src.nav.glonass if system == "R" else src.nav.kepler.get(system)
        if q.size == 0 or tab is None or len(tab.sat_id) == 0:
            continue
        health = np.nan_to_num(tab.health, nan=1.0).astype(np.int64)  # unknown: unusable
        if system == "J":
            health = health & ~1  # bit 0: the L6 signal
        usable = health == 0
        penalty = np.zeros(len(tab.sat_id))
        if system == "E":  # F/NAV records only when no I/NAV one is valid
            src_bits = np.nan_to_num(src.nav.kepler["E"].code_or_source).astype(np.int64)
            penalty = np.where(src_bits & 0b101, 0.0, 1.0e7)
        dt = np.abs(t[q, None] - tab.toe_s[None, :])
        ok = (ids[q, None] == tab.sat_id[None, :]) & (dt <= src.max_age_s[system]) & usable[None, :]
        score = np.where(ok, dt + penalty[None, :], np.inf)
        best = np.argmin(score, axis=1)
        row[q] = np.where(np.isfinite(score[np.arange(q.size), best]), best, -1)
    return row


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_selection_is_the_rule_over_the_whole_table(shared_data: Path, seed: int) -> None:
    src, sats, t0 = _source(shared_data)
    rng = np.random.default_rng(seed)
    names = [*sats, "G99", "E77", "X01", "R"]  # unknown satellites and systems too
    ids = [names[i] for i in rng.integers(0, len(names), 300)]
    t = t0 + rng.choice([0.0, 900.0, 3600.0, 7200.0, 1.5e4, 4.0e4], 300) * rng.choice([-1.0, 1.0], 300)
    t[rng.random(300) < 0.05] = np.nan
    got = src.select(t, ids)
    np.testing.assert_array_equal(got, _select_whole_table(src, t, ids))
    assert np.count_nonzero(got >= 0) > 30  # real choices, not only misses


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 2**31), n_ep=st.integers(1, 30), span_s=st.sampled_from([1.0, 600.0, 7200.0]))
def test_code_states_equals_epoch_geometry_calls(
    shared_data: Path, seed: int, n_ep: int, span_s: float
) -> None:
    """The states of the single-point geometry of many epochs in one call are, bit for bit,
    those of transmission_time + sat_states + group_delay_s called epoch by epoch (times
    spread across record boundaries, satellites without records, missing codes)."""
    src, sats, t0 = _source(shared_data)
    rng = np.random.default_rng(seed)
    epochs = _epochs(rng, sats + ["G99", "E77"], t0 - span_s / 2, n_ep)
    epochs = [(t0 - span_s / 2 + span_s * rng.random(), ids, code) for _, ids, code in epochs]
    ids_all = [s for _, ids, _ in epochs for s in ids]
    letter, code_of = src.query_codes(sorted(set(ids_all)))
    col = {s: k for k, s in enumerate(sorted(set(ids_all)))}
    cols = np.array([col[s] for s in ids_all])
    t_all = np.concatenate([np.full(len(ids), t) for t, ids, _ in epochs])
    code_all = np.concatenate([c for _, _, c in epochs])
    has = np.isfinite(code_all)
    pos_b, clk_b, ok_b = src.code_states(t_all[has], letter[cols[has]], code_of[cols[has]], code_all[has])
    i0 = 0
    n_ok = 0
    for t, ids, code in epochs:
        keep = np.isfinite(code)
        kids = [s for s, k in zip(ids, keep, strict=True) if k]
        i1 = i0 + len(kids)
        if kids:
            t_tx = src.transmission_time(t, kids, code[keep])
            pos, _, clk, _, ok = src.sat_states(t_tx, kids)
            clk_m = (clk - src.group_delay_s(t_tx, kids)) * CLIGHT
            ok = ok & np.isfinite(clk_m)
            np.testing.assert_array_equal(ok_b[i0:i1], ok)
            np.testing.assert_array_equal(pos_b[i0:i1][ok], pos[ok])
            np.testing.assert_array_equal(clk_b[i0:i1][ok], clk_m[ok])
            n_ok += int(ok.sum())
        i0 = i1
    assert i0 == int(has.sum())
    assert n_ok > 0
