"""The array scan of plain RINEX 3 epoch lines gives what the line-by-line scan gives: the
same epochs, times to the bit, events and skipped records, and the same refusals (the line
by line scan then reading what the array scan declines)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import robustrtk.io.rinex_epochs as rep
from robustrtk.core import InputError
from robustrtk.io.rinex_text import split_lines

_REC = "G01  20000000.000 7 105000000.000 7"


def _epoch_line(y: int, mo: int, d: int, h: int, mi: int, sec: str, flag: int, n: int, clk: str) -> str:
    head = f"> {y:04d} {mo:02d} {d:02d} {h:02d} {mi:02d}{sec} {flag:2d}{n:3d}"
    return head + (f"      {clk}" if clk else "")


def _scan(body: list[str], array_scan: bool) -> rep.RinexEpochs | str:
    data = ("\n".join(body) + "\n").encode("latin-1")
    starts, ends, n_lines = split_lines(data)
    bufp = np.concatenate([np.frombuffer(data, np.uint8), np.full(4, 32, np.uint8)])
    saved = rep._plain_epochs_v3
    if not array_scan:
        rep._plain_epochs_v3 = lambda *a: False  # type: ignore[assignment]
    try:
        return rep.scan_epochs_v3(data, bufp, starts, ends, 0, n_lines, "f.obs")
    except InputError as exc:
        return f"{exc.message} @ {exc.line}"
    finally:
        rep._plain_epochs_v3 = saved


def _mostly(usual: list, odd: list) -> st.SearchStrategy:
    """Each field odd about once in twenty (so that many files are all plain)."""
    return st.sampled_from(usual * (20 * len(odd) // len(usual)) + odd)


_ODD_SECONDS = [
    " 60.0000000", " 61.0000000", " 62.5000000", " 0 .0000000", "  5.00000  ", " 5.5e0     ",
    "          .", " -1.0000000", "59.99999999", " 99.9999999",
]  # fmt: skip
_SEC = st.one_of(
    st.builds(lambda s, f: f" {s:2d}.{f:07d}", st.integers(0, 59), st.integers(0, 9_999_999)),
    st.builds(lambda s, f: f" {s:02d}.{f:07d}", st.integers(0, 59), st.integers(0, 9_999_999)),
    st.builds(lambda s, f: f" {s:2d}.{f:07d}", st.integers(0, 59), st.integers(0, 9_999_999)),
    st.sampled_from(_ODD_SECONDS),
)

_EPOCH = st.tuples(
    _mostly([2021], [1975, 1979, 1980, 2100, 2101]),
    _mostly([2, 3], [0, 1, 12, 13]),
    _mostly([28, 29], [0, 1, 31, 32]),
    _mostly([23], [0, 24, 25]),
    _mostly([59, 0], [58, 60, 61]),
    _SEC,
    _mostly([0], [1, 2, 3, 4, 5, 6, 7, 9]),
    _mostly([1, 2], [0, 3, 10]),
    _mostly([""], ["   0.000123456", "  -1.2345D-04", "  bad", "   1 5"]),
    _mostly([0], [-1, 1]),  # records written: announced count + this
    _mostly([""], ["junk", "nonascii", "short"]),
)


@settings(max_examples=400, derandomize=True, deadline=None)
@given(st.lists(_EPOCH, min_size=1, max_size=4))
def test_array_scan_equals_line_by_line(epochs: list[tuple]) -> None:
    body: list[str] = []
    for y, mo, d, h, mi, sec, flag, n, clk, extra, odd in epochs:
        line = _epoch_line(y, mo, d, h, mi, sec, flag, n, clk)
        if odd == "junk":
            line = ">" + line[1:20] + "x" + line[21:]
        elif odd == "nonascii":
            line = line[:40] + "\u00e9" + line[41:]
        elif odd == "short":
            line = line[:33]
        body.append(line)
        recs = max(0, n + extra)
        if flag in (2, 3, 4, 5) and recs:
            body += ["  COMMENT TEXT" + " " * 46 + "COMMENT"] * recs
        else:
            body += [_REC] * recs
    got = _scan(body, True)
    want = _scan(body, False)
    assert got == want


def test_plain_file_takes_the_array_scan_and_matches() -> None:
    body = []
    for k in range(50):
        body.append(_epoch_line(2021, 4, 28, 22, 19 + k // 60, f" {k % 60:2d}.4299102", 0, 2, ""))
        body += [_REC, _REC]
        if k == 10:
            body += [_epoch_line(2021, 4, 28, 22, 19, " 10.5000000", 5, 0, "")]
    calls: list[bool] = []
    saved = rep._plain_epochs_v3

    def spy(*a: object) -> bool:
        calls.append(saved(*a))  # type: ignore[arg-type]
        return calls[-1]

    rep._plain_epochs_v3 = spy  # type: ignore[assignment]
    try:
        got = _scan(body, True)
    finally:
        rep._plain_epochs_v3 = saved
    assert calls == [True]
    want = _scan(body, False)
    assert isinstance(got, rep.RinexEpochs) and got == want
    assert len(got.t_s) == 50 and got.events == [{"line": 34, "flag": 5}]


@pytest.mark.parametrize("sec", [" 22.4299102", " 59.9999999", "  0.0000001", " 60.0000000"])
def test_array_scan_times_are_float_of_the_text(sec: str) -> None:
    body = [_epoch_line(2024, 2, 29, 23, 59, sec, 0, 1, ""), _REC]
    got = _scan(body, True)
    want = _scan(body, False)
    assert isinstance(got, rep.RinexEpochs) and got == want
    assert got.t_s[0] == want.t_s[0] and got.t_ns[0] == want.t_ns[0]


_ODD_LINES = [
    _epoch_line(2021, 4, 28, 22, 60, " 10.0000000", 0, 1, ""),
    _epoch_line(2021, 4, 28, 25, 0, " 10.0000000", 0, 1, ""),
    _epoch_line(2021, 4, 32, 22, 0, " 10.0000000", 0, 1, ""),
    _epoch_line(2021, 13, 28, 22, 0, " 10.0000000", 0, 1, ""),
    _epoch_line(1979, 12, 31, 23, 59, " 10.0000000", 0, 1, ""),
    _epoch_line(2021, 4, 28, 22, 0, " 61.0000000", 0, 1, ""),
    _epoch_line(2021, 4, 28, 22, 0, " 60.9999999", 0, 1, ""),
    _epoch_line(2021, 4, 28, 22, 0, " 10.0000000", 7, 1, ""),
    _epoch_line(2021, 4, 28, 22, 0, " 10.0000000", 0, 1, "  bad"),
    _epoch_line(2021, 4, 28, 22, 0, " 10.0000000", 0, 1, "  -1.5D-04"),
    _epoch_line(2021, 4, 28, 22, 0, " 10,0000000", 0, 1, ""),
    _epoch_line(2021, 4, 28, 22, 0, " 1 .0000000", 0, 1, ""),
    _epoch_line(2021, 4, 28, 22, 0, " 10.0000000", 0, 1, "")[:33],
    _epoch_line(2021, 4, 28, 22, 0, " 10.0000000", 0, 1, "").replace("> 2021", ">x2021"),
    _epoch_line(2021, 4, 28, 22, 0, " 10.0000000", 0, 1, "").replace(" 22 ", " 2x "),
    _epoch_line(2021, 4, 28, 22, 0, " 10.0000000", 0, 1, "")[:32] + "1 ",
    _epoch_line(2021, 4, 28, 22, 0, " 10.0000000", 0, 1, "") + " \u00e9",
]


@pytest.mark.parametrize("odd", _ODD_LINES)
def test_one_odd_epoch_line_among_plain_ones(odd: str) -> None:
    plain = _epoch_line(2021, 4, 28, 22, 0, "  9.0000000", 0, 1, "")
    body = [plain, _REC, odd, _REC, plain.replace("  9.", " 11."), _REC]
    assert _scan(body, True) == _scan(body, False)
