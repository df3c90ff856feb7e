"""Double differences cancel every clock; D R Dᵀ is the exact DD covariance."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk.measurement.dd import (
    DDRangeModel,
    RangeMemo,
    StackedModel,
    choose_references,
    dd_rows,
    form_dd,
    ranges,
)
from robustrtk.measurement.weighting import elevation_sin2, local_elevation, variance

IDS = ("PL1", "PL4", "PL5", "PL6", "PL8")
TX_POS = np.array([[-3.5, -2.0, 4.0], [3.8, -2.4, 3.9], [3.2, 2.6, 4.0], [0.2, 0.1, 4.0], [-3.0, 2.8, 3.95]])


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1), clk_scale=st.sampled_from([1.0, 1e3, 1e5, 3e7]), ref=st.sampled_from(IDS)
)
def test_dd_removes_every_clock(seed, clk_scale, ref):
    rng = np.random.default_rng(seed)
    rover = rng.uniform([-4, -3, 0.5], [4, 3, 2.0])
    base = rng.uniform([-4, -3, 0.5], [4, 3, 2.0])
    rr, rb = ranges(rover, TX_POS), ranges(base, TX_POS)
    clk_tx = rng.normal(0, clk_scale, 5)
    obs_r = rr + clk_tx + rng.normal(0, clk_scale)
    obs_b = rb + clk_tx + rng.normal(0, clk_scale)
    var = np.ones(5)
    dd = form_dd(IDS, ["P:L1"] * 5, obs_r, obs_b, var, var, {"P:L1": ref})
    assert dd.m == 4 and ref not in dd.tx and all(r == ref for r in dd.ref)
    geo = (rr[dd.i_tx] - rr[dd.i_ref]) - (rb[dd.i_tx] - rb[dd.i_ref])
    np.testing.assert_allclose(dd.z, geo, atol=1e-9 * max(1.0, clk_scale) * 10)
    model = DDRangeModel(
        TX_POS, rb, dd.i_tx, dd.i_ref, slice(0, 3), np.full(4, -1), np.zeros(4), dd.z, dd.R, dd.labels
    )
    np.testing.assert_allclose(model.h(rover), dd.z, atol=1e-9 * max(1.0, clk_scale) * 10)


def test_dd_covariance_is_d_r_dt():
    var_r = np.array([1.0, 2.0, 3.0, 4.0, 5.0])
    var_b = np.array([0.5, 0.5, 0.5, 0.5, 0.5])
    dd = form_dd(IDS, ["P:L1"] * 5, np.zeros(5), np.zeros(5), var_r, var_b, {"P:L1": "PL6"})
    # rows share the reference: off-diagonals = var_r(ref) + var_b(ref)
    np.testing.assert_allclose(dd.R[0, 1], 4.0 + 0.5)
    np.testing.assert_allclose(dd.R[0, 0], 1.0 + 0.5 + 4.0 + 0.5)
    np.testing.assert_allclose(dd.R, dd.D @ np.diag(np.r_[var_r, var_b]) @ dd.D.T)


def test_missing_observations_and_reference_choice():
    obs = np.array([1.0, np.nan, 3.0, 4.0, 5.0])
    avail = np.isfinite(obs)
    score = np.array([0.1, 0.9, 0.5, 0.2, 0.3])
    refs = choose_references(IDS, ["P:L1"] * 5, avail, score)
    assert refs == {"P:L1": "PL5"}  # PL4 scores best but is absent
    assert choose_references(IDS, ["P:L1"] * 5, avail, score, preferred={"P:L1": "PL8"}) == {"P:L1": "PL8"}
    assert choose_references(IDS, ["P:L1"] * 5, avail, score, previous={"P:L1": "PL1"}) == {"P:L1": "PL1"}
    dd = form_dd(IDS, ["P:L1"] * 5, obs, obs, np.ones(5), np.ones(5), refs)
    assert dd.tx == ("PL1", "PL6", "PL8")


def test_jacobian_matches_finite_difference():
    rb = ranges(np.zeros(3), TX_POS)
    dd = form_dd(IDS, ["P:L1"] * 5, np.zeros(5), np.zeros(5), np.ones(5), np.ones(5), {"P:L1": "PL6"})
    model = DDRangeModel(
        TX_POS,
        rb,
        dd.i_tx,
        dd.i_ref,
        slice(0, 3),
        np.array([3, 4, -1, 5]),
        np.full(4, 0.19),
        dd.z,
        dd.R,
        dd.labels,
    )
    x = np.array([1.0, 0.5, 1.2, 10, 20, 30])
    H = model.jacobian(x)
    eps = 1e-6
    num = np.column_stack([(model.h(x + eps * e) - model.h(x - eps * e)) / (2 * eps) for e in np.eye(6)])
    np.testing.assert_allclose(H, num, atol=1e-7)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), sagnac=st.booleans(), delays=st.booleans())
def test_h_of_a_batch_is_the_dd_formula_bit_for_bit(seed, sagnac, delays):
    """``h`` of a batch of states (sigma points) equals, for every state and row,
    ``(ρᵢ − ρ_ref) − (ρ_q^i − ρ_q^ref) + λᵢ Nᵢ`` computed on that state alone (the same
    operations in the same order, so bit for bit); rows without an ambiguity add nothing."""
    rng = np.random.default_rng(seed)
    tx = rng.uniform(-2e7, 2e7, (6, 3))
    base_r = rng.uniform(2e7, 2.6e7, 6)
    i_tx = np.array([0, 1, 2, 4, 5, 0, 1])
    i_ref = np.array([3, 3, 3, 3, 3, 2, 2])
    amb = np.array([3, -1, 4, 5, -1, 6, 7])
    wl = rng.uniform(0.18, 0.26, 7)
    corr = rng.uniform(2.0, 20.0, 6) if delays else None
    model = DDRangeModel(
        tx, base_r, i_tx, i_ref, slice(0, 3), amb, wl, np.zeros(7), np.eye(7), tuple("abcdefg"),
        sagnac=sagnac, tx_corr_m=corr,
    )  # fmt: skip
    X = np.column_stack([rng.uniform(-6.4e6, 6.4e6, (9, 3)), rng.normal(0, 1e3, (9, 5))])
    Y = model.h(X)
    assert Y.shape == (9, 7)
    for k in range(9):
        r = ranges(X[k, :3], tx, sagnac)
        if corr is not None:
            r = r + corr
        ref = (r[i_tx] - r[i_ref]) - (base_r[i_tx] - base_r[i_ref])
        ref[amb >= 0] = ref[amb >= 0] + X[k, amb[amb >= 0]] * wl[amb >= 0]
        assert Y[k].tobytes() == ref.tobytes()
        assert model.h(X[k]).tobytes() == ref.tobytes()


def test_weighting_models():
    el = np.deg2rad([90.0, 30.0, 1.0])
    v = variance(0.1, "elevation", elev_rad=el)
    np.testing.assert_allclose(v[:2], [0.01, 0.04])
    assert np.isclose(v[2], 0.01 / np.sin(np.deg2rad(5.0)) ** 2)  # floored at 5 deg
    np.testing.assert_allclose(variance(0.1, "snr", snr_dbhz=np.array([45.0, 35.0])), [0.01, 0.1])
    np.testing.assert_allclose(variance(0.1, "distance", dist_m=np.array([5.0, 10.0])), [0.01, 0.04])
    assert variance(0.2, "equal", n=3).tolist() == [0.04000000000000001] * 3
    np.testing.assert_allclose(
        local_elevation(np.zeros(3), np.array([[0, 0, 4.0], [4, 0, 4.0]])), [np.pi / 2, np.pi / 4]
    )


def test_rows_of_another_observable_are_reused_only_when_they_match():
    ids = ("G01", "G02", "G03", "E11", "E12", "E13", "G04")
    groups = ["G:1C", "G:1C", "G:1C", "E:1C", "E:1C", "E:1C", "G:1C"]
    refs = {"G:1C": "G02", "E:1C": "E13", "C:2I": "C01"}  # a group without rows
    rng = np.random.default_rng(5)
    obs_r, obs_b = rng.normal(0, 1e3, 7), rng.normal(0, 1e3, 7)
    obs_r[3] = np.nan  # E11 absent at the rover
    var_r, var_b = rng.uniform(1, 2, 7), rng.uniform(1, 2, 7)
    plain = form_dd(ids, groups, obs_r, obs_b, var_r, var_b, refs)
    rows = dd_rows(ids, groups, np.isfinite(obs_r) & np.isfinite(obs_b), refs)
    assert rows.tx == plain.tx == ("G01", "G03", "E12", "G04")
    assert rows.ref == ("G02", "G02", "E13", "G02")
    reused = form_dd(ids, groups, obs_r, obs_b, var_r, var_b, refs, rows)
    assert reused.D is rows.D
    for name in ("labels", "tx", "ref", "group"):
        assert getattr(reused, name) == getattr(plain, name)
    for name in ("i_tx", "i_ref", "D", "z", "R"):
        np.testing.assert_array_equal(getattr(reused, name), getattr(plain, name))
    # rows chosen for another mask are not used: the reference G02 is missing here
    obs_r2 = obs_r.copy()
    obs_r2[1] = np.nan
    other = form_dd(ids, groups, obs_r2, obs_b, var_r, var_b, refs, rows)
    assert other.D is not rows.D
    assert other.tx == ("E12",)
    # nor rows chosen for other references
    refs2 = {"G:1C": "G01", "E:1C": "E13"}
    moved = form_dd(ids, groups, obs_r, obs_b, var_r, var_b, refs2, rows)
    assert moved.D is not rows.D and moved.ref == ("G01", "G01", "E13", "G01")


def test_elevation_variance_from_its_divisor_is_the_same():
    el = np.deg2rad(np.array([90.0, 45.0, 10.0, 3.0, np.nan, -2.0]))
    direct = variance(0.3, "elevation", elev_rad=el)
    np.testing.assert_array_equal(variance(0.3, "elevation", elev_sin2=elevation_sin2(el)), direct)
    np.testing.assert_allclose(direct[:3], 0.09 / np.sin(el[:3]) ** 2)
    assert direct[4] == 0.09  # NaN: the zenith
    assert direct[3] == direct[5] == 0.09 / np.sin(np.deg2rad(5.0)) ** 2  # clipped at 5°


@settings(max_examples=80, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(0, 14))
def test_dd_rows_are_those_of_the_row_by_row_rule(seed, n):
    rng = np.random.default_rng(seed)
    names = ["G01", "G02", "G03", "E05", "E06", "C10"]
    ids = [names[i] for i in rng.integers(0, len(names), n)]  # repeated names too
    groups = [f"{t[0]}:{'1C' if rng.random() < 0.7 else '2W'}" for t in ids]
    ok = rng.random(n) < 0.8
    refs = {g: names[int(rng.integers(0, len(names)))] for g in set(groups) if rng.random() < 0.9}
    refs["X:1C"] = "X99"  # a group without rows, a reference without a row
    rows = dd_rows(ids, groups, ok, refs)
    first = {}
    for i, t in enumerate(ids):
        first.setdefault(t, i)
    want = [
        (i, first[refs[g]])
        for i, g in enumerate(groups)
        if ok[i] and g in refs and refs[g] in first and ids[i] != refs[g] and ok[first[refs[g]]]
    ]
    assert list(zip(rows.i_tx.tolist(), rows.i_ref.tolist(), strict=True)) == want
    assert rows.tx == tuple(ids[i] for i, _ in want) and rows.group == tuple(groups[i] for i, _ in want)
    assert rows.labels == tuple(f"{ids[i]}-{ids[j]}" for i, j in want)
    np.testing.assert_array_equal(rows.D.sum(axis=1), np.zeros(len(want)))
    assert rows.matches(ids, groups, ok, refs)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), sagnac=st.booleans(), delays=st.booleans())
def test_position_model_is_the_same_rows_on_the_position_alone(seed, sagnac, delays):
    """``on_position``: ``h`` and the position columns of the Jacobian of a code model, bit
    for bit, from the position alone; a model with ambiguity rows has no such form."""
    rng = np.random.default_rng(seed)
    tx = rng.uniform(-2e7, 2e7, (6, 3))
    base_r = rng.uniform(2e7, 2.6e7, 6)
    i_tx = np.array([0, 1, 2, 4, 5])
    i_ref = np.array([3, 3, 3, 3, 3])
    corr = rng.uniform(2.0, 20.0, 6) if delays else None
    pos = slice(3, 6)  # the position need not come first in the state
    model = DDRangeModel(
        tx, base_r, i_tx, i_ref, pos, np.full(5, -1), np.zeros(5), np.zeros(5), np.eye(5), tuple("abcde"),
        sagnac=sagnac, tx_corr_m=corr,
    )  # fmt: skip
    x = np.r_[rng.normal(0, 1.0, 3), rng.uniform(-6.4e6, 6.4e6, 3), rng.normal(0, 1e3, 4)]
    pm = model.on_position()
    assert pm.h(x[pos]).tobytes() == model.h(x).tobytes()
    assert (
        np.ascontiguousarray(pm.jacobian(x[pos])).tobytes()
        == np.ascontiguousarray(model.jacobian(x)[:, pos]).tobytes()
    )
    assert pm.z is model.z and pm.R is model.R and pm.labels == model.labels
    assert pm.row_constants is model.row_constants  # the rows' constants are shared
    with_amb = DDRangeModel(
        tx, base_r, i_tx, i_ref, pos, np.array([6, -1, -1, -1, -1]), np.full(5, 0.19), np.zeros(5), np.eye(5),
        tuple("abcde"),
    )  # fmt: skip
    with pytest.raises(ValueError, match="ambiguity"):
        with_amb.on_position()


def test_stacked_model_is_the_block_diagonal_of_its_parts_built_once():
    """``z``, ``R`` and ``labels`` of a stack: the parts' in order, ``R`` block-diagonal,
    each built on first use and the same object on later uses (an update reads them
    several times)."""
    rng = np.random.default_rng(3)
    tx = rng.uniform(-2e7, 2e7, (6, 3))
    base_r = rng.uniform(2e7, 2.6e7, 6)
    i_tx, i_ref = np.array([0, 1, 2, 4, 5]), np.array([3, 3, 3, 3, 3])
    R1 = np.diag(rng.uniform(1.0, 2.0, 5)) + 0.5
    R2 = np.diag(rng.uniform(1.0, 2.0, 3)) + 0.25
    a = DDRangeModel(
        tx,
        base_r,
        i_tx,
        i_ref,
        slice(0, 3),
        np.full(5, -1),
        np.zeros(5),
        rng.normal(size=5),
        R1,
        tuple("abcde"),
    )
    b = DDRangeModel(
        tx, base_r, i_tx[:3], i_ref[:3], slice(0, 3), np.full(3, -1), np.zeros(3), rng.normal(size=3), R2,
        tuple("fgh"),
    )  # fmt: skip
    st = StackedModel((a, b))
    assert st.labels == tuple("abcdefgh")
    np.testing.assert_array_equal(st.z, np.r_[a.z, b.z])
    expect = np.zeros((8, 8))
    expect[:5, :5], expect[5:, 5:] = R1, R2
    np.testing.assert_array_equal(st.R, expect)
    assert st.R is st.R and st.z is st.z and st.labels is st.labels


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), sagnac=st.booleans(), delays=st.booleans())
def test_models_sharing_a_range_memo_give_the_same_numbers(seed, sagnac, delays):
    """A phase and a code model of one epoch sharing a :class:`RangeMemo` (stacked, on the
    position alone, at repeated and new states) give ``h`` and Jacobians bit for bit equal
    to the same models without it; an entry never serves other transmitter arrays, even
    with equal values at the same position."""
    rng = np.random.default_rng(seed)
    tx = rng.uniform(-2e7, 2e7, (6, 3))
    base_r = rng.uniform(2e7, 2.6e7, 6)
    corr = rng.uniform(2.0, 20.0, 6) if delays else None
    i_tx, i_ref = np.array([0, 1, 2, 4, 5]), np.array([3, 3, 3, 3, 3])
    phase = DDRangeModel(
        tx, base_r, i_tx, i_ref, slice(0, 3), np.array([6, 7, 8, 9, 10]), rng.uniform(0.18, 0.26, 5),
        np.zeros(5), np.eye(5), tuple("abcde"), sagnac=sagnac, tx_corr_m=corr,
    )  # fmt: skip
    code = DDRangeModel(
        tx, base_r, i_tx, i_ref, slice(0, 3), np.full(5, -1), np.zeros(5), np.zeros(5), np.eye(5),
        tuple("fghij"), sagnac=sagnac, tx_corr_m=corr,
    )  # fmt: skip
    memo = RangeMemo()
    phase_m, code_m = replace(phase, memo=memo), replace(code, memo=memo)
    plain, shared = StackedModel((phase, code)), StackedModel((phase_m, code_m))
    x0 = np.r_[rng.uniform(-6.4e6, 6.4e6, 3), rng.normal(0, 1e3, 3), rng.normal(0, 1e3, 5)]
    for x in (x0, x0, x0 + rng.normal(0, 1.0, 11), x0):
        assert shared.h(x).tobytes() == plain.h(x).tobytes()
        assert shared.jacobian(x).tobytes() == plain.jacobian(x).tobytes()
        assert code_m.on_position().h(x[:3]).tobytes() == code.on_position().h(x[:3]).tobytes()
        assert code_m.on_position().jacobian(x[:3]).tobytes() == code.jacobian(x)[:, :3].tobytes()
    # the memo's entries are read-only: a model's output is a new array
    out = code_m.h(x0)
    out[0] += 1.0
    assert code_m.h(x0).tobytes() == code.h(x0).tobytes()
    # other transmitter arrays (a copy, moved satellites) at the same position: computed anew
    moved = tx + 1000.0
    other = replace(code, tx_pos_m=moved, memo=memo)
    assert other.h(x0).tobytes() == replace(code, tx_pos_m=moved).h(x0).tobytes()
    assert other.h(x0).tobytes() != code.h(x0).tobytes()
    assert replace(code, tx_pos_m=tx.copy(), memo=memo).jacobian(x0).tobytes() == code.jacobian(x0).tobytes()
