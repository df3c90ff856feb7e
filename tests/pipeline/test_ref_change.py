"""A reference change re-expresses DD ambiguities instead of resetting them."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk.ambiguity.book import AmbiguityBook, AmbKey
from robustrtk.estimation.filters import EKF
from robustrtk.estimation.robust import NoRobust
from robustrtk.estimation.state import GaussianState, StateLayout
from robustrtk.pipeline.config import Config
from robustrtk.pipeline.rtk import RtkStage


def _stage(book: AmbiguityBook) -> RtkStage:
    return RtkStage(Config.of(mode="rtk"), book, EKF(), NoRobust(), sagnac=False, signal=0)


@settings(max_examples=50, deadline=None)
@given(st.lists(st.integers(-50, 50), min_size=4, max_size=4), st.floats(0.01, 2.0))
def test_ref_change_maps_integers_to_integers_and_keeps_information(n_sd: list[int], s: float) -> None:
    # single-difference ambiguities of A (old ref), B (new ref), C, D in group g; DD = SD_i - SD_ref
    sd = dict(zip("ABCD", n_sd, strict=True))
    g = "G:L1"
    book = AmbiguityBook()
    keys = [book.key("B", g), book.key("C", g), book.key("D", g), book.key("X", "E:L1")]
    x_amb = np.array([sd["B"] - sd["A"], sd["C"] - sd["A"], sd["D"] - sd["A"], 7.0])
    rng = np.random.default_rng(abs(hash((tuple(n_sd), s))) % 2**32)
    A = rng.normal(size=(7, 7))
    P = A @ A.T * s + np.eye(7) * 1e-3
    state = GaussianState(
        np.concatenate([[1.0, 2.0, 3.0], x_amb]), P, 0.0, StateLayout((("pos", 3),), tuple(keys))
    )
    for k in keys:
        book.add(k, "A" if k.signal == g else "X0")
    book.set_fixed(keys, x_amb)
    new = _stage(book).ref_change({g: "A", "E:L1": "X0"}, {g: "B", "E:L1": "X0"}, state)
    amb = dict(zip(new.layout.amb_keys, new.x[3:], strict=True))
    # DDs against the new reference B, and the old reference A now an ordinary row
    assert amb[book.key("A", g)] == sd["A"] - sd["B"]
    assert amb[book.key("C", g)] == sd["C"] - sd["B"]
    assert amb[book.key("D", g)] == sd["D"] - sd["B"]
    assert amb[book.key("X", "E:L1")] == 7.0  # other groups untouched
    assert np.allclose(new.x[:3], state.x[:3])
    # a unimodular map: no information lost or invented (equal determinants)
    assert np.isclose(np.linalg.det(new.P), np.linalg.det(state.P), rtol=1e-8)
    # the book follows: references and the recorded integers re-expressed the same way
    assert all(book.ref(k) == "B" for k in new.layout.amb_keys if k.signal == g)
    for k in new.layout.amb_keys:
        entry = book.entry(k)
        assert entry is not None and entry.fixed == amb[k]


def test_ref_change_without_state_for_new_reference_leaves_state() -> None:
    g = "G:L1"
    book = AmbiguityBook()
    state = GaussianState(np.zeros(4), np.eye(4), 0.0, StateLayout((("pos", 3),), (book.key("C", g),)))
    book.add(book.key("C", g), "A")
    out = _stage(book).ref_change({g: "A"}, {g: "B"}, state)
    assert out is state  # the usual drop-and-re-add handles it
    assert book.ref(book.key("C", g)) == "A"


def test_book_suspect_clears_on_acceptance_and_counts_rejections() -> None:
    book = AmbiguityBook(("rov", "ref"))
    k = book.key("G05:L1", "G:L1")
    assert k == AmbKey("G05:L1", "G:L1", ("rov", "ref"))
    book.add(k, "G10:L1")
    book.suspect(k)
    book.judge(k, 3)
    book.judge(k, 3)
    assert book.rejections(k) == 2
    book.suspect(k)  # already suspect: the count goes on
    assert book.rejections(k) == 2
    book.judge(k, 1)
    assert book.rejections(k) is None
    book.tick([k, book.key("G07:L1", "G:L1")])
    assert book.lock(k) == 2 and book.lock(book.key("G07:L1", "G:L1")) == 0


def test_judging_all_rows_at_once_is_judging_each() -> None:
    keys = [AmbKey(f"G{i:02d}:L1", "G:L1") for i in range(1, 7)]
    situations = [3, 1, 3, 2, 3, 1]
    books = [AmbiguityBook(), AmbiguityBook()]
    for book in books:
        for k in keys[:5]:  # the last is not tracked
            book.add(k, "G10:L1")
        for k in keys[:3] + keys[4:5]:  # one tracked key is not suspect
            book.suspect(k)
    for k, s in zip(keys, situations, strict=True):
        books[0].judge(k, s)
    books[1].judge_all(keys, situations)
    got = [books[1].rejections(k) for k in keys]
    assert got == [books[0].rejections(k) for k in keys] == [1, None, 1, None, 1, None]
