"""``gather_lines`` in chunks gives the rows a one-shot gather gives (any chunk size)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

import robustrtk.io.rinex_decode as dec


def _one_shot(bufp: np.ndarray, starts: np.ndarray, lens: np.ndarray, width: int) -> np.ndarray:
    rows = []
    for s, n in zip(starts.tolist(), lens.tolist(), strict=True):
        line = bytes(bufp[s : s + min(n, width)])
        rows.append(list(line.ljust(width, b" ")))
    return np.array(rows, np.uint8).reshape(len(rows), width)


@settings(max_examples=60, derandomize=True, deadline=None)
@given(
    st.lists(
        st.binary(min_size=0, max_size=40).map(lambda b: b.replace(b"\n", b"x")), min_size=0, max_size=30
    ),
    st.integers(1, 50),
    st.integers(1, 200),
)
def test_chunked_gather_equals_line_by_line(lines: list[bytes], width: int, chunk: int) -> None:
    text = b"\n".join(lines) + b"\n"
    bufp = np.frombuffer(text, np.uint8)
    lens = np.array([len(x) for x in lines], np.int64)
    starts = (
        np.concatenate([[0], np.cumsum(lens + 1)[:-1]]).astype(np.int64) if lines else np.zeros(0, np.int64)
    )
    saved = dec.GATHER_CHUNK_CELLS
    dec.GATHER_CHUNK_CELLS = chunk
    try:
        got = dec.gather_lines(bufp, starts, lens, width)
    finally:
        dec.GATHER_CHUNK_CELLS = saved
    assert got.shape == (len(lines), width) and got.dtype == np.uint8
    np.testing.assert_array_equal(got, _one_shot(bufp, starts, lens, width))
