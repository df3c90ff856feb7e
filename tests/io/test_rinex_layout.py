"""Public RINEX observation layout: header parsing, epoch scan, field columns."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from robustrtk.core import InputError
from robustrtk.io.rinex_decode import digit_field, f14_to_float
from robustrtk.io.rinex_file import read_rinex_bytes
from robustrtk.io.rinex_layout import (
    LLI_OFFSET,
    OBS_FIELD_WIDTH,
    OBS_VALUE_WIDTH,
    SSI_OFFSET,
    V2_OBS_PER_LINE,
    V3_SAT_ID_WIDTH,
    field_position,
    parse_obs_header,
    rinex3_signal,
    v2_lines_per_record,
)
from robustrtk.io.rinex_obs import read_rinex_obs
from robustrtk.io.rinex_text import (
    scan_obs_text,
    split_lines,
)

DATA = Path(__file__).parent / "data"


def test_header_of_tiny_v304() -> None:
    lines = (DATA / "tiny_v304.rnx").read_text().splitlines()
    h = parse_obs_header(lines, "tiny")
    assert h.version == pytest.approx(3.04) and h.file_system == "M"
    assert h.marker == "TINY3" and h.receiver_type == "REC3" and h.antenna_type == "ANT3"
    np.testing.assert_allclose(h.approx_pos_m, [-3817680.9841, 3562840.0688, 3650158.4543])
    assert len(h.obs_types["G"]) == 16 and h.obs_types["G"][-3:] == ["L5Q", "D5Q", "S5Q"]
    assert h.obs_types["E"] == ["C1C", "L1C", "C7Q", "L7Q", "X1"]
    assert h.interval_s == 1.0 and h.time_system == "GPS" and h.leap_s == 18
    assert h.glo_channel == {"R01": 1, "R02": -4, "R03": 5}
    assert lines[h.n_lines - 1][60:].strip() == "END OF HEADER"


def test_header_errors_name_the_line() -> None:
    with pytest.raises(InputError, match="RINEX VERSION / TYPE") as exc:
        parse_obs_header(["garbage"], "f.obs")
    assert exc.value.line == 1
    nav = "     3.04           N: GNSS NAV DATA    M                   RINEX VERSION / TYPE"
    with pytest.raises(InputError, match="not an observation file"):
        parse_obs_header([nav], "f.nav")
    first = (DATA / "tiny_v304.rnx").read_text().splitlines()[:3]
    with pytest.raises(InputError, match="missing END OF HEADER"):
        parse_obs_header(first, "f.obs")


@pytest.mark.parametrize("name", ["tiny_v211.o", "tiny_v304.rnx"])
def test_scan_matches_reader(name: str) -> None:
    data, _ = read_rinex_bytes(DATA / name)
    txt = scan_obs_text(data, name)
    b = read_rinex_obs(DATA / name)
    assert len(txt.epochs.t_s) == len(b)
    np.testing.assert_allclose(np.asarray(txt.epochs.t_s) + b.meta["time_offset_s"], b.t_s)
    for ln in txt.epochs.line:
        t = txt.text(ln)
        assert t.startswith(">") if txt.v3 else t[28] in "01"
    assert txt.per_sat == (1 if txt.v3 else v2_lines_per_record(len(txt.header.obs_types2)))


def test_field_positions_point_at_values() -> None:
    data, _ = read_rinex_bytes(DATA / "tiny_v304.rnx")
    txt = scan_obs_text(data, "tiny")
    rec = txt.epochs.first_rec[0]  # G05 record of the first epoch
    li, col = field_position(True, rec, 1)  # L1C
    line = txt.text(li)
    assert line[:V3_SAT_ID_WIDTH] == "G05"
    assert float(line[col : col + OBS_VALUE_WIDTH]) == 115000000.500
    assert line[col + LLI_OFFSET] == "1" and line[col + SSI_OFFSET] == "7"
    assert field_position(False, 10, 7) == (11, OBS_FIELD_WIDTH * 2)
    assert field_position(False, 10, V2_OBS_PER_LINE) == (11, 0)


def test_split_lines_and_records_per_sat() -> None:
    starts, ends, n = split_lines(b"ab\ncd\n")
    assert n == 2 and starts.tolist()[:2] == [0, 3] and ends.tolist()[:2] == [2, 5]
    assert split_lines(b"ab\ncd")[2] == 2
    assert [v2_lines_per_record(k) for k in (0, 1, 5, 6, 10, 11)] == [1, 1, 1, 2, 2, 3]


def test_rinex3_signal_beidou_rename() -> None:
    assert rinex3_signal("C", "L1I", 3.02) == "2I"
    assert rinex3_signal("C", "L1I", 3.04) == "1I"
    assert rinex3_signal("G", "C1C", 3.02) == "1C"


@given(st.integers(min_value=-999_999_999_999, max_value=9_999_999_999_999))
def test_f14_round_trip(milli: int) -> None:
    value = milli / 1000.0
    text = f"{value:14.3f}"
    arr = np.frombuffer(text.encode(), np.uint8).reshape(1, 14)
    got, odd = f14_to_float(arr)
    assert not odd[0]
    assert got[0] == float(text)


@given(st.text(alphabet="0123456789 x", min_size=1, max_size=30))
def test_digit_field(chars: str) -> None:
    arr = np.frombuffer(chars.encode(), np.uint8)
    want = [int(c) if c.isdigit() else 0 for c in chars]
    assert digit_field(arr).tolist() == want
    assert not math.isnan(float(len(want)))
