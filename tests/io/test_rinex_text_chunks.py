"""The streamed reader's text pieces (header + at most n epochs) are those of cutting the
whole body at every n-th epoch start, whatever the read size: epochs straddling reads,
``\\r\\n`` split between reads, text before the first epoch, a last line without newline."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import robustrtk.io.rinex_chunks as rc

_HEADER = (
    b"     3.04           OBSERVATION DATA    M                   RINEX VERSION / TYPE\r\n"
    b"                                                            END OF HEADER\r\n"
)


def _whole_text_pieces(data: bytes, n: int) -> list[tuple[bytes, tuple[int, int]]]:
    """The pieces cut from the whole text at once (the reference)."""
    head_end = data.index(b"END OF HEADER")
    head_end = data.index(b"\n", head_end) + 1
    header = data[:head_end].replace(b"\r", b"")
    n_head = header.count(b"\n")
    body = data[head_end:].replace(b"\r", b"")
    starts = [m.start() + 1 for m in re.finditer(rb"\n>", body)]
    if body.startswith(b">"):
        starts.insert(0, 0)
    out = []
    before = n_head
    cut_at = 0
    for k in range(n, len(starts), n):
        piece = body[cut_at : starts[k]]
        out.append((header + piece, (n_head, before)))
        before += piece.count(b"\n")
        cut_at = starts[k]
    if body[cut_at:].strip():
        out.append((header + body[cut_at:], (n_head, before)))
    return out


_LINE = st.sampled_from(
    [b"> 2021 04 28 22 19 22.4299102  0  1", b"G01  20000000.000", b"", b"  junk >", b">", b"x"]
)


@settings(max_examples=200, derandomize=True, deadline=None)
@given(
    st.lists(_LINE, min_size=0, max_size=30),
    st.sampled_from([b"\n", b"\r\n"]),
    st.booleans(),
    st.integers(1, 5),
    st.integers(1, 40),
)
def test_pieces_equal_cutting_the_whole_text(
    tmp_path_factory: pytest.TempPathFactory,
    lines: list[bytes],
    eol: bytes,
    final_eol: bool,
    n: int,
    read_bytes: int,
) -> None:
    body = eol.join(lines) + (eol if final_eol else b"")
    data = _HEADER + body
    path = Path(tmp_path_factory.mktemp("chunks")) / "f.obs"
    path.write_bytes(data)
    saved = rc._READ_BYTES
    rc._READ_BYTES = read_bytes
    try:
        got = list(rc._text_chunks(str(path), n))
    finally:
        rc._READ_BYTES = saved
    assert got == _whole_text_pieces(data, n)
