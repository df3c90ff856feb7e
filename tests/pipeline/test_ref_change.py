"""A reference change re-expresses DD ambiguities instead of resetting them."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk.estimation.state import GaussianState, StateLayout
from robustrtk.pipeline.config import Config
from robustrtk.pipeline.engine import DDEngine


class _NoSource:
    def positions(self, t_s, ids, code=None):  # type: ignore[no-untyped-def]
        raise AssertionError("not used")


def _engine() -> DDEngine:
    cfg = Config.of(mode="rtk")
    return DDEngine(cfg, _NoSource(), np.zeros(3), np.zeros(3))  # type: ignore[arg-type]


@settings(max_examples=50, deadline=None)
@given(st.lists(st.integers(-50, 50), min_size=4, max_size=4), st.floats(0.01, 2.0))
def test_ref_change_maps_integers_to_integers_and_keeps_information(n_sd: list[int], s: float) -> None:
    # single-difference ambiguities of A (old ref), B (new ref), C, D in group g; DD = SD_i - SD_ref
    sd = dict(zip("ABCD", n_sd, strict=True))
    g = "G:L1"
    keys = [("B", g), ("C", g), ("D", g), ("X", "E:L1")]
    x_amb = np.array([sd["B"] - sd["A"], sd["C"] - sd["A"], sd["D"] - sd["A"], 7.0])
    rng = np.random.default_rng(abs(hash((tuple(n_sd), s))) % 2**32)
    A = rng.normal(size=(7, 7))
    P = A @ A.T * s + np.eye(7) * 1e-3
    state = GaussianState(
        np.concatenate([[1.0, 2.0, 3.0], x_amb]), P, 0.0, StateLayout((("pos", 3),), tuple(keys))
    )
    eng = _engine()
    eng.refs = {g: "A", "E:L1": "X0"}
    for k in keys:
        eng._amb_ref[k] = "A" if k[1] == g else "X0"
    new = eng._ref_change({g: "B", "E:L1": "X0"}, state)
    amb = dict(zip(new.layout.amb_keys, new.x[3:], strict=True))
    # DDs against the new reference B, and the old reference A now an ordinary row
    assert amb[("A", g)] == sd["A"] - sd["B"]
    assert amb[("C", g)] == sd["C"] - sd["B"]
    assert amb[("D", g)] == sd["D"] - sd["B"]
    assert amb[("X", "E:L1")] == 7.0  # other groups untouched
    assert np.allclose(new.x[:3], state.x[:3])
    # a unimodular map: no information lost or invented (equal determinants)
    assert np.isclose(np.linalg.det(new.P), np.linalg.det(state.P), rtol=1e-8)
    assert all(eng._amb_ref[k] == "B" for k in new.layout.amb_keys if k[1] == g)


def test_ref_change_without_state_for_new_reference_leaves_state() -> None:
    g = "G:L1"
    state = GaussianState(np.zeros(4), np.eye(4), 0.0, StateLayout((("pos", 3),), (("C", g),)))
    eng = _engine()
    eng.refs = {g: "A"}
    out = eng._ref_change({g: "B"}, state)
    assert out is state  # the usual drop-and-re-add handles it
