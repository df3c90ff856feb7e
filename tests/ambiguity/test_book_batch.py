"""The ambiguity book's batched queries against the per-key methods they stand for, and
the layout's ``amb_indices`` against ``amb_index`` of each key (hypothesis)."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk.ambiguity.book import AmbiguityBook, AmbKey
from robustrtk.estimation.state import StateLayout

TXS = [f"G{i:02d}" for i in range(1, 9)]
GROUPS = ["G:L1", "G:L2"]

keys_st = st.lists(st.tuples(st.sampled_from(TXS), st.sampled_from(GROUPS)), max_size=12)


def _book(entries: list[tuple[tuple[str, str], str, int, int | None]]) -> AmbiguityBook:
    book = AmbiguityBook()
    for (tx, g), ref, lock, suspect in entries:
        key = book.key(tx, g)
        book.add(key, ref)
        e = book.entry(key)
        assert e is not None
        e.lock = lock
        e.suspect = suspect
    return book


entries_st = st.lists(
    st.tuples(
        st.tuples(st.sampled_from(TXS), st.sampled_from(GROUPS)),
        st.sampled_from(TXS),
        st.integers(1, 6),
        st.none() | st.integers(0, 5),
    ),
    max_size=10,
)


@settings(max_examples=200, deadline=None)
@given(entries_st, keys_st, st.data())
def test_confirmed_slips_is_the_per_key_loop(entries, pairs, data) -> None:
    flagged = data.draw(st.lists(st.booleans(), min_size=len(pairs), max_size=len(pairs)))
    a, b = _book(entries), _book(entries)
    keys = a.keys([p[0] for p in pairs], [p[1] for p in pairs])
    assert keys == [b.key(tx, g) for tx, g in pairs]
    expected = []
    for i, (key, flag) in enumerate(zip(keys, flagged, strict=True)):
        if flag:
            b.suspect(key)
        n = b.rejections(key)
        if n is not None and n >= 3:
            expected.append(i)
    assert a.confirmed_slips(keys, flagged, 3) == expected
    assert {k: a.rejections(k) for k in a} == {k: b.rejections(k) for k in b}


@settings(max_examples=200, deadline=None)
@given(entries_st, keys_st, keys_st, st.integers(0, 7))
def test_locked_and_stale_are_the_per_key_expressions(entries, pairs, present_pairs, n) -> None:
    book = _book(entries)
    keys = [book.key(tx, g) for tx, g in pairs]
    present = {book.key(tx, g) for tx, g in present_pairs}
    ref_of = {"G:L1": "G01"}
    assert book.locked(keys, n) == [book.lock(k) >= n for k in keys]
    expected = [k for k in keys if k not in present or book.ref(k) != ref_of.get(k.signal)]
    assert book.stale(keys, present, ref_of) == expected


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.sampled_from(TXS), max_size=8),
    st.lists(st.sampled_from(TXS), max_size=8),
    st.sampled_from([(("pos", 3),), (("pos", 3), ("vel", 3))]),
)
def test_amb_indices_is_amb_index_of_each_key(amb, ask, blocks) -> None:
    layout = StateLayout(blocks=blocks, amb_keys=tuple(AmbKey(t, "G:L1") for t in amb))
    for keys in (None, [AmbKey(t, "G:L1") for t in ask]):
        want_keys = layout.amb_keys if keys is None else keys
        try:
            want = [layout.amb_index(k) for k in want_keys]
        except ValueError as err:
            with pytest.raises(ValueError) as got_err:
                layout.amb_indices(keys)
            assert str(got_err.value) == str(err)  # the first absent key named
            continue
        got = layout.amb_indices(keys)
        assert got.dtype == int and got.tolist() == want
