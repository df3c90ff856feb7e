"""Situation counting (Table 1) and per-situation errors (Fig. 6) on hand-made tables."""

from __future__ import annotations

import numpy as np

from robustrtk.eval.situations import (
    ALL_LABEL,
    classify_dv,
    epoch_situations,
    situation_counts,
    situation_mean_abs_errors,
)
from robustrtk.io.solution import DiagTable


def diag(rows: list[tuple[float, str, float, int]]) -> DiagTable:
    R = len(rows)
    nan = np.full(R, np.nan)
    return DiagTable(
        t_s=np.array([r[0] for r in rows]),
        dd=np.array([r[1] for r in rows]),
        innovation=nan,
        residual=nan,
        std_residual=nan,
        dv=np.array([r[2] for r in rows]),
        factor=nan,
        situation=np.array([r[3] for r in rows], dtype=np.int64),
    )


ROWS = [
    # epoch 0: all normal -> 1
    (0.0, "A", 0.5, 1), (0.0, "B", -1.9, 1),
    # epoch 1: one down-weighted -> 2
    (1.0, "A", 2.5, 2), (1.0, "B", 1.0, 1),
    # epoch 2: one rejected, one down-weighted -> 3
    (2.0, "A", -9.0, 3), (2.0, "B", 3.0, 2),
    # epoch 3: only B present, normal -> 1
    (3.0, "B", 0.1, 1),
    # epoch 4: A rejected -> 3
    (4.0, "A", 12.0, 3), (4.0, "B", 0.0, 1),
]  # fmt: skip


def test_classify_dv_boundaries() -> None:
    np.testing.assert_array_equal(
        classify_dv([0.0, 2.0, -2.0001, 8.0, 8.0001, -50.0, np.nan], 2.0, 8.0),
        [1, 1, 2, 2, 3, 3, 0],
    )


def test_counts_per_dd_and_all() -> None:
    d = diag(ROWS)
    c = situation_counts(d)
    assert list(c) == ["A", "B", ALL_LABEL]
    assert c["A"] == (1, 1, 2)
    assert c["B"] == (4, 1, 0)
    assert c[ALL_LABEL] == (2, 1, 2)
    # Recomputing from dv with the paper's k0 = 2, k1 = 8 gives the same table here.
    assert situation_counts(d, from_dv=True) == c
    # A stricter k1 = 2.7 turns B's dv = 3.0 at epoch 2 into #3 (A's 2.5 stays #2).
    c2 = situation_counts(d, from_dv=True, k0=2.0, k1=2.7)
    assert c2["A"] == (1, 1, 2) and c2["B"] == (4, 0, 1)
    assert c2[ALL_LABEL] == (2, 1, 2)
    t, s = epoch_situations(d)
    np.testing.assert_array_equal(t, [0, 1, 2, 3, 4])
    np.testing.assert_array_equal(s, [1, 2, 3, 1, 3])


def test_situation_mean_abs_errors() -> None:
    t, s = epoch_situations(diag(ROWS))
    tt = np.arange(5.0)
    sukf = np.array([[0.1, 0, 0], [1, -1, 0], [-4, 2, 2], [0.1, 0, 0], [6, 0, -2]])
    rukf = sukf * 0.25
    out = situation_mean_abs_errors(t, s, {"SUKF": (tt, sukf), "RUKF": (tt + 1e-4, rukf)})
    np.testing.assert_allclose(out["SUKF"][3], [5.0, 1.0, 2.0])
    np.testing.assert_allclose(out["SUKF"][2], [1.0, 1.0, 0.0])
    np.testing.assert_allclose(out["SUKF"][1], [0.1, 0.0, 0.0])
    np.testing.assert_allclose(out["RUKF"][3], [1.25, 0.25, 0.5])
    # Solution epochs not matching any diagnostic epoch are ignored.
    far = situation_mean_abs_errors(t, s, {"X": (tt + 0.5, sukf)}, situations=(2,))
    assert np.isnan(far["X"][2]).all()


def test_engine_event_rows_are_not_dds() -> None:
    """An integrity or adaptive-factor row (no situation, no Δv̄) is neither a Table 1 row nor
    part of its epoch's situation."""
    with_events = ROWS + [(1.0, "integrity:inflate", np.nan, 0), (2.0, "adaptive", np.nan, 0)]
    a = situation_counts(diag(ROWS))
    b = situation_counts(diag(with_events))
    assert b == a and "integrity:inflate" not in b
    np.testing.assert_array_equal(epoch_situations(diag(with_events))[1], epoch_situations(diag(ROWS))[1])
    b_dv = situation_counts(diag(with_events), from_dv=True)
    assert b_dv == situation_counts(diag(ROWS), from_dv=True)
