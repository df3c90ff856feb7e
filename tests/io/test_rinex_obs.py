"""RINEX observation reader: synthetic fixtures, malformed input, real files checked against
an independent slicing oracle, compression round trips."""

from __future__ import annotations

import gzip
import math
from pathlib import Path

import hatanaka
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk.core import InputError, ObsBatch
from robustrtk.gnss import wavelength_m
from robustrtk.io.rinex_obs import read_rinex_obs
from robustrtk.timeutil import gpst_from_calendar

DATA = Path(__file__).parent / "data"
V2 = DATA / "tiny_v211.o"
V3 = DATA / "tiny_v304.rnx"

GEONET = "geonet_0759_3040_static_3km/07590920.05o"
MOSAIC = "mosaicx5_static_1m/rover.obs"
KAMAKURA = "kamakura_kinematic_5km/SEPT265G.21O"
KAMAKURA_BASE = "kamakura_kinematic_5km/3034265G.21O"
PIXEL5 = "gsdc2021_mtv1_pixel5_phone/Pixel5/supplemental/Pixel5_GnssLog.21o"

FIELDS = {"C": "code_m", "L": "phase_cyc", "D": "doppler_hz", "S": "cn0_dbhz"}


def cell(b: ObsBatch, fld: str, t: int, tx: str, sig: str) -> float:
    return float(getattr(b, fld)[t, b.tx_ids.index(tx), b.signals.index(sig)])


# ------------------------------------------------------------------------------------------
# synthetic fixtures


def test_v2_fixture_values_and_layout() -> None:
    b = read_rinex_obs(V2)
    # flag 4 event and flag 6 slip records are skipped: 3 epochs remain
    assert len(b) == 3
    assert b.tx_ids == tuple(f"G{k:02d}" for k in range(1, 11)) + ("R11", "E12", "S20")
    assert b.system == ("G",) * 10 + ("R", "E", "S")
    assert b.signals == ("1C", "1P", "1W", "1X", "2P", "2W")
    t0 = gpst_from_calendar(2024, 1, 2, 3, 4, 5.0)
    np.testing.assert_array_equal(b.t_s, [t0, t0 + 30.002, t0 + 60.0])
    assert b.meta["t_ns"][1] == int(t0) * 10**9 + 30_002_000_000
    # satellite 2 has a blank system letter -> GPS, on the continuation line S20 is #13
    assert cell(b, "code_m", 0, "G02", "1C") == 20002000.246
    assert cell(b, "code_m", 0, "G02", "1W") == 20002000.912  # P1 kept beside C1
    assert math.isnan(cell(b, "code_m", 0, "G01", "1W"))  # P1 blank
    assert cell(b, "code_m", 0, "G02", "2W") == 20002001.578  # P2
    assert cell(b, "phase_cyc", 0, "G03", "1C") == 300000.125  # L1 -> 1C
    assert cell(b, "phase_cyc", 0, "G03", "2W") == 239999.5  # L2 -> 2W
    assert cell(b, "doppler_hz", 0, "G04", "1C") == -1230.567  # second record line
    assert cell(b, "cn0_dbhz", 0, "S20", "1C") == 43.25
    assert cell(b, "phase_cyc", 0, "R11", "2P") == 879999.5  # GLONASS L2 -> 2P
    assert cell(b, "code_m", 0, "E12", "1X") == 20012001.476  # Galileo C1 -> 1X
    assert cell(b, "code_m", 2, "E12", "1X") == 21000000.0
    # LLI of the phase; SSI kept in meta
    assert b.lli[0, 2, 0] == 1 and b.lli[0, 0, 0] == 0
    assert b.lli[1, 0, 0] == 5
    assert b.meta["ssi"][0, 0, 0] == 7 and b.meta["ssi"][1, 0, 0] == 8
    # epoch 1 (flag 1) keeps only G01 and G03; blank second record lines -> NaN
    assert np.isfinite(b.code_m[1]).sum() == 3  # G01 C1, P2; G03 C1
    assert cell(b, "phase_cyc", 1, "G03", "1C") == -5.5
    assert b.meta["power_failure_epochs"] == [1]
    assert b.meta["events"] == [{"line": 39, "flag": 4}]
    assert b.meta["n_slip_records_skipped"] == 1
    assert b.meta["rcv_clock_offset_s"][0] == 0.000123456
    np.testing.assert_array_equal(b.approx_pos_m, [1e6, 2e6, 3e6])
    assert b.receiver == "TINY2" and b.meta["receiver_type"] == "TESTREC"
    assert b.meta["interval_s"] == 30.0
    # RINEX 2 has no GLONASS channel: NaN on the FDMA bands
    assert np.isnan(b.wavelength_m[b.tx_ids.index("R11")]).all()
    assert b.wavelength_m[0, 0] == wavelength_m("G", "1C")


def test_v3_fixture_values_and_layout() -> None:
    b = read_rinex_obs(V3)
    assert len(b) == 2  # flag 3 event skipped
    assert b.tx_ids == ("G05", "G13", "R01", "R02", "E11", "C07")  # "C 7" -> C07
    assert b.signals == ("1C", "2I", "2L", "2P", "2W", "5Q", "7I", "7Q")
    t0 = gpst_from_calendar(2024, 6, 24, 8, 20, 0.0)
    np.testing.assert_array_equal(b.t_s, [t0, t0 + 1.0005])
    assert cell(b, "code_m", 0, "G05", "1C") == 22000000.125
    assert cell(b, "phase_cyc", 0, "G05", "1C") == 115000000.5
    assert cell(b, "doppler_hz", 0, "G05", "1C") == -1500.25
    assert cell(b, "cn0_dbhz", 0, "G05", "2W") == 30.25
    assert math.isnan(cell(b, "doppler_hz", 0, "G05", "2W"))
    assert cell(b, "phase_cyc", 0, "G05", "5Q") == 85900000.0  # after the continuation types
    assert cell(b, "phase_cyc", 0, "E11", "7Q") == -96000000.0
    assert cell(b, "code_m", 0, "C07", "2I") == 37000000.0
    assert np.isnan(b.code_m[0, b.tx_ids.index("G13")]).all()  # record with no fields
    assert cell(b, "code_m", 1, "R01", "1C") == 20000000.0
    assert b.lli[0, 0, 0] == 1 and b.lli[0, 0, 4] == 2 and b.lli[0, 3, 3] == 3
    assert b.meta["ssi"][0, 0, 0] == 7
    assert b.meta["ignored_obs_types"] == {"E": ["X1"]}
    assert b.meta["glonass_channels"] == {"R01": 1, "R02": -4, "R03": 5}
    # GLONASS FDMA wavelength from the channel; signals a system lacks are NaN
    r2 = b.tx_ids.index("R02")
    assert b.wavelength_m[r2, 0] == pytest.approx(299792458.0 / (1602e6 - 4 * 0.5625e6))
    assert b.wavelength_m[r2, 3] == pytest.approx(299792458.0 / (1246e6 - 4 * 0.4375e6))
    assert np.isnan(b.wavelength_m[r2, 4])
    assert b.wavelength_m[0, 4] == wavelength_m("G", "2W")
    assert b.meta["rcv_clock_offset_s"][0] == -1.23e-7


def test_filters_by_system_and_time() -> None:
    full = read_rinex_obs(V3)
    g = read_rinex_obs(V3, systems="GC")
    assert g.tx_ids == ("G05", "G13", "C07")
    assert g.signals == ("1C", "2I", "2L", "2W", "5Q", "7I")
    k = [full.signals.index(s) for s in g.signals]
    n = [full.tx_ids.index(t) for t in g.tx_ids]
    np.testing.assert_array_equal(g.code_m, full.code_m[:, n][:, :, k])
    late = read_rinex_obs(V3, t_start_s=full.t_s[0] + 0.5)
    assert len(late) == 1 and late.t_s[0] == full.t_s[1]
    assert late.tx_ids == ("G13", "R01")  # union over the epochs kept
    n = [full.tx_ids.index(t) for t in late.tx_ids]
    np.testing.assert_array_equal(late.code_m[0], full.code_m[1, n])
    early = read_rinex_obs(V2, t_end_s=read_rinex_obs(V2).t_s[1])
    assert len(early) == 2
    # a mask over every epoch's time tag: it sees them all, and only its epochs are kept
    seen: list[np.ndarray] = []

    def second_only(t: np.ndarray) -> np.ndarray:
        seen.append(t.copy())
        return np.arange(t.size) == 1

    masked = read_rinex_obs(V3, epoch_mask=second_only)
    np.testing.assert_array_equal(seen[0], full.t_s)
    assert len(masked) == 1 and masked.tx_ids == late.tx_ids
    np.testing.assert_array_equal(masked.code_m, late.code_m)

    def refuse(t: np.ndarray) -> np.ndarray:
        raise InputError("time_start: no rover epoch selected")

    with pytest.raises(InputError, match="no rover epoch selected"):
        read_rinex_obs(V3, epoch_mask=refuse)
    with pytest.raises(InputError, match="unknown system"):
        read_rinex_obs(V3, systems="GX")


def _rinex3_text(values: list[float], lli: list[int]) -> str:
    head = [
        f"{'     3.04           OBSERVATION DATA    G':<60}RINEX VERSION / TYPE",
        f"{'G    2 C1C L1C':<60}SYS / # / OBS TYPES",
        f"{'':<60}END OF HEADER",
    ]
    body = [f"> 2020 01 01 00 00  0.0000000  0{len(values):3d}"]
    for k, (v, f) in enumerate(zip(values, lli, strict=True)):
        body.append(f"G{k + 1:02d}{v:14.3f}  {v:14.3f}{f or ' '}")
    return "\n".join(head + body) + "\n"


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.floats(min_value=-9.9e8, max_value=9.9e9, allow_nan=False), min_size=1, max_size=30),
    st.randoms(use_true_random=False),
)
def test_field_conversion_matches_float_of_text(values: list[float], rnd) -> None:  # type: ignore[no-untyped-def]
    """Every F14.3 field equals Python's float() of the same text, bit for bit."""
    import tempfile

    lli = [rnd.choice([0, 1, 2, 3]) for _ in values]
    text = _rinex3_text(values, lli)
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "x.rnx"
        path.write_text(text)
        b = read_rinex_obs(path)
    expect = np.array([float(f"{v:14.3f}") for v in values])
    order = [b.tx_ids.index(f"G{k + 1:02d}") for k in range(len(values))]
    # pseudoranges outside (0, 1e9) m are masked as missing (io.obs_checks), phases kept
    code = np.where((expect > 0.0) & (expect < 1e9), expect, np.nan)
    np.testing.assert_array_equal(b.code_m[0, order, 0], code)
    np.testing.assert_array_equal(b.phase_cyc[0, order, 0], expect)
    np.testing.assert_array_equal(b.lli[0, order, 0], lli)
    masked = int(np.isnan(code).sum())
    assert b.meta.get("masked_values", {}).get("code_m", 0) == masked


# ------------------------------------------------------------------------------------------
# malformed input


def _write(tmp_path: Path, text: str, name: str = "bad.rnx") -> Path:
    p = tmp_path / name
    p.write_text(text + "\n")
    return p


def _v3_lines() -> list[str]:
    return V3.read_text().splitlines()


def test_bad_version_header(tmp_path: Path) -> None:
    lines = _v3_lines()
    lines[0] = lines[0][:60] + "RINEX VERSION"
    with pytest.raises(InputError, match="bad version header") as e:
        read_rinex_obs(_write(tmp_path, "\n".join(lines)))
    assert e.value.line == 1 and str(e.value).startswith(str(tmp_path / "bad.rnx") + ":1:")
    lines = _v3_lines()
    lines[0] = "   x.04" + lines[0][7:]
    with pytest.raises(InputError, match="version") as e:
        read_rinex_obs(_write(tmp_path, "\n".join(lines)))
    assert e.value.line == 1
    lines = _v3_lines()
    lines[0] = lines[0][:20] + "N" + lines[0][21:]
    with pytest.raises(InputError, match="not an observation file"):
        read_rinex_obs(_write(tmp_path, "\n".join(lines)))


def test_missing_end_of_header(tmp_path: Path) -> None:
    lines = [ln for ln in _v3_lines() if "END OF HEADER" not in ln]
    with pytest.raises(InputError, match="missing END OF HEADER") as e:
        read_rinex_obs(_write(tmp_path, "\n".join(lines)))
    assert e.value.path == str(tmp_path / "bad.rnx")


def test_bad_epoch_line(tmp_path: Path) -> None:
    lines = _v3_lines()
    i = next(k for k, ln in enumerate(lines) if ln.startswith(">"))
    lines[i] = lines[i][:31] + "x" + lines[i][32:]
    with pytest.raises(InputError, match="bad epoch line") as e:
        read_rinex_obs(_write(tmp_path, "\n".join(lines)))
    assert e.value.line == i + 1
    lines = _v3_lines()
    lines[i] = lines[i][:7] + "13" + lines[i][9:]  # month 13
    with pytest.raises(InputError, match="bad epoch time") as e:
        read_rinex_obs(_write(tmp_path, "\n".join(lines)))
    assert e.value.line == i + 1
    lines = V2.read_text().splitlines()
    lines[10] = lines[10].replace(" 24  1  2", " 24 ab  2")
    with pytest.raises(InputError, match="bad epoch line") as e:
        read_rinex_obs(_write(tmp_path, "\n".join(lines), "bad.24o"))
    assert e.value.line == 11


def test_satellite_count_mismatch(tmp_path: Path) -> None:
    lines = _v3_lines()
    i = next(k for k, ln in enumerate(lines) if ln.startswith(">"))
    lines[i] = lines[i][:32] + "  6" + lines[i][35:]  # 6 announced, 5 records follow
    with pytest.raises(InputError, match="satellite count does not match") as e:
        read_rinex_obs(_write(tmp_path, "\n".join(lines)))
    assert e.value.line == i + 1
    lines = V2.read_text().splitlines()
    lines[10] = lines[10][:29] + " 12" + lines[10][32:]  # 12 announced, 13 listed
    with pytest.raises(InputError, match="satellite count does not match") as e:
        read_rinex_obs(_write(tmp_path, "\n".join(lines), "bad.24o"))
    assert e.value.line == 11
    # records missing at the end of the file (a file cut short): the last epoch dropped, noted
    lines = V2.read_text().splitlines()[:-2]
    b = read_rinex_obs(_write(tmp_path, "\n".join(lines), "cut.24o"))
    ref = read_rinex_obs(V2)
    np.testing.assert_array_equal(b.t_s, ref.t_s[:-1])
    assert any("ends inside its last epoch" in n for n in b.meta["read_notes"])


def test_non_numeric_field(tmp_path: Path) -> None:
    lines = _v3_lines()
    i = next(k for k, ln in enumerate(lines) if ln.startswith("R02"))
    lines[i] = lines[i][:3] + "  19000x00.000" + lines[i][17:]
    with pytest.raises(InputError, match="C1C.*expected a number") as e:
        read_rinex_obs(_write(tmp_path, "\n".join(lines)))
    assert e.value.line == i + 1
    lines = V2.read_text().splitlines()
    j = 13  # second record line of G01: D1 field
    lines[j] = "     -12 3.567" + lines[j][14:]
    with pytest.raises(InputError, match="D1.*expected a number") as e:
        read_rinex_obs(_write(tmp_path, "\n".join(lines), "bad.24o"))
    assert e.value.line == j + 1


def test_nonstandard_but_numeric_field_is_read(tmp_path: Path) -> None:
    lines = _v3_lines()
    i = next(k for k, ln in enumerate(lines) if ln.startswith("R02"))
    lines[i] = lines[i][:3] + "   19000000.12" + lines[i][17:]  # 2 decimals, point moved
    b = read_rinex_obs(_write(tmp_path, "\n".join(lines)))
    assert cell(b, "code_m", 0, "R02", "1C") == 19000000.12


def test_missing_file_and_bad_gzip(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="file not found"):
        read_rinex_obs(tmp_path / "nope.rnx")
    p = tmp_path / "x.rnx.gz"
    p.write_bytes(b"\x1f\x8b" + b"garbage" * 10)
    with pytest.raises(InputError, match="decompress"):
        read_rinex_obs(p)


# ------------------------------------------------------------------------------------------
# compression round trips


def _assert_same(a: ObsBatch, b: ObsBatch) -> None:
    assert a.tx_ids == b.tx_ids and a.signals == b.signals
    np.testing.assert_array_equal(a.t_s, b.t_s)
    for f in ("code_m", "phase_cyc", "doppler_hz", "cn0_dbhz", "lli", "wavelength_m"):
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f))


def _head_of(path: Path, n_epochs: int) -> bytes:
    out = []
    seen = 0
    for ln in path.read_bytes().splitlines(keepends=True):
        if ln.startswith(b">"):
            seen += 1
            if seen > n_epochs:
                break
        out.append(ln)
    return b"".join(out)


@pytest.mark.parametrize("source", ["fixture", "mosaic"])
def test_hatanaka_and_gzip_round_trip(tmp_path: Path, request, source: str) -> None:  # type: ignore[no-untyped-def]
    if source == "fixture":
        plain = V3.read_bytes()
    else:
        shared = request.getfixturevalue("shared_data")
        plain = _head_of(shared / MOSAIC, 5)
    (tmp_path / "a.rnx").write_bytes(plain)
    ref = read_rinex_obs(tmp_path / "a.rnx")
    crx = hatanaka.compress(plain, compression="none")
    assert crx != plain and b"CRINEX" in crx[:100]
    (tmp_path / "a.crx").write_bytes(crx)
    (tmp_path / "a.crx.gz").write_bytes(hatanaka.compress(plain, compression="gz"))
    (tmp_path / "a.rnx.gz").write_bytes(gzip.compress(plain))
    (tmp_path / "noext").write_bytes(crx)  # detection by content, not by name
    for name, kind in [
        ("a.crx", "hatanaka"),
        ("a.crx.gz", "hatanaka+gzip"),
        ("a.rnx.gz", "gzip"),
        ("noext", "hatanaka"),
    ]:
        b = read_rinex_obs(tmp_path / name)
        assert b.meta["compression"] == kind
        _assert_same(ref, b)
    # CRLF line ends read the same
    (tmp_path / "crlf.rnx").write_bytes(plain.replace(b"\n", b"\r\n"))
    _assert_same(ref, read_rinex_obs(tmp_path / "crlf.rnx"))


# ------------------------------------------------------------------------------------------
# real files against an independent oracle (plain string slicing)


def _oracle_v3(path: Path, epochs: set[int]) -> dict[tuple[int, str, str], float]:
    """{(epoch, sat, obs code): value} for the chosen epochs, by token-split header and
    slicing of the 16-character fields."""
    types: dict[str, list[str]] = {}
    lines = path.read_text(errors="replace").splitlines()
    k = 0
    cur = ""
    while "END OF HEADER" not in lines[k]:
        if "SYS / # / OBS TYPES" in lines[k]:
            tok = lines[k][:60].split()
            if not lines[k][0].isspace():
                cur = tok[0]
                types[cur] = tok[2:]
            else:
                types[cur] += tok
        k += 1
    out: dict[tuple[int, str, str], float] = {}
    e = -1
    for ln in lines[k + 1 :]:
        if ln.startswith(">"):
            e += 1
            continue
        if e in epochs:
            sat = ln[:3]
            for j, code in enumerate(types[sat[0]]):
                s = ln[3 + 16 * j : 3 + 16 * j + 14]
                out[(e, sat, code)] = float(s) if s.strip() else math.nan
    return out


def _check_against_oracle(b: ObsBatch, oracle: dict[tuple[int, str, str], float]) -> int:
    n = 0
    for (e, sat, code), v in oracle.items():
        if code[0] not in FIELDS:
            continue
        got = cell(b, FIELDS[code[0]], e, sat, code[1:])
        if math.isnan(v):
            assert math.isnan(got), (e, sat, code)
        else:
            assert got == v, (e, sat, code, got, v)
            n += 1
    return n


def test_mosaicx5_rinex304(shared_data: Path) -> None:
    path = shared_data / MOSAIC
    b = read_rinex_obs(path)
    assert len(b) == 301
    assert b.meta["rinex_version"] == 3.04 and b.meta["interval_s"] == 1.0
    assert set(b.system) == {"G", "R", "E", "C", "J"}
    np.testing.assert_array_equal(np.diff(b.t_s), 1.0)
    assert b.t_s[0] == gpst_from_calendar(2024, 6, 24, 8, 20, 0.0)
    assert b.receiver == "SEPT" and b.meta["receiver_type"] == "SEPT MOSAIC-X5"
    np.testing.assert_allclose(b.approx_pos_m, [-3817680.9841, 3562840.0688, 3650158.4543])
    n = _check_against_oracle(b, _oracle_v3(path, {0, 1, 150, 300}))
    assert n > 1500
    # C23 has no B2b (7I) in the first epoch: blank fields -> NaN
    assert math.isnan(cell(b, "code_m", 0, "C23", "7I"))
    assert cell(b, "code_m", 0, "C23", "2I") == 24656801.108
    # the SSI digit of C01 L2I and the GLONASS channel wavelengths
    assert b.meta["ssi"][0, b.tx_ids.index("C01"), b.signals.index("2I")] == 7
    r = b.tx_ids.index("R03")
    assert b.wavelength_m[r, b.signals.index("1C")] == wavelength_m("R", "1C", 5)


def test_kamakura_rinex304(shared_data: Path) -> None:
    rover = read_rinex_obs(shared_data / KAMAKURA)
    assert len(rover) == 360 and set(rover.system) == {"G", "E", "J"}
    assert rover.signals == ("1C", "1W", "2L", "2W", "5Q", "7Q", "8Q")
    np.testing.assert_array_equal(np.diff(rover.t_s), 1.0)
    assert _check_against_oracle(rover, _oracle_v3(shared_data / KAMAKURA, {0, 359})) > 300
    base = read_rinex_obs(shared_data / KAMAKURA_BASE)
    assert len(base) == 360 and base.meta["receiver_type"] == "TRIMBLE NetR9"
    assert _check_against_oracle(base, _oracle_v3(shared_data / KAMAKURA_BASE, {0, 200})) > 200
    np.testing.assert_array_equal(base.t_s, rover.t_s)


def test_pixel5_rinex303(shared_data: Path) -> None:
    path = shared_data / PIXEL5
    b = read_rinex_obs(path)
    assert len(b) == 1985 and set(b.system) == {"G", "R", "E"}
    assert b.signals == ("1C", "5X")
    assert b.approx_pos_m is None  # header position is all zero
    # sub-second time tags are kept exactly
    assert b.meta["t_ns"][0] % 10**9 == 429_910_200
    assert b.t_s[0] == gpst_from_calendar(2021, 4, 28, 22, 19, 22.4299102)
    assert _check_against_oracle(b, _oracle_v3(path, {0, 1000, 1984})) > 100
    # LLI 2 (half-cycle ambiguity) on G05 L1C in the first epoch, and its SSI 5
    g05 = b.tx_ids.index("G05")
    assert b.lli[0, g05, 0] == 2 and b.meta["ssi"][0, g05, 0] == 5
    assert b.cn0_dbhz[0, g05, 0] == 33.4
    assert b.meta["glonass_channels"]["R09"] == -2 and b.meta["glonass_channels"]["R05"] == 1


def test_geonet_rinex210(shared_data: Path) -> None:
    path = shared_data / GEONET
    b = read_rinex_obs(path)
    assert len(b) == 120 and b.meta["rinex_version"] == 2.10
    assert set(b.system) == {"G"} and b.signals == ("1C", "2W")
    assert b.meta["interval_s"] == 30.0
    np.testing.assert_allclose(b.approx_pos_m, [-3976219.5082, 3382372.5671, 3652512.9849])
    # oracle: epoch lines and records by slicing (4 types: L1 C1 L2 P2, one line per sat)
    lines = path.read_text().splitlines()
    k = next(i for i, ln in enumerate(lines) if "END OF HEADER" in ln) + 1
    e = 0
    checked = 0
    events = 0
    while k < len(lines):
        head = lines[k]
        n = int(head[29:32])
        if head[28] in "2345":  # event: n header records follow
            events += 1
            k += 1 + n
            continue
        sats = [head[32 + 3 * j : 35 + 3 * j].replace(" ", "0") for j in range(n)]
        sec = float(head[15:26])
        t = (
            gpst_from_calendar(
                2000 + int(head[1:3]), int(head[4:6]), int(head[7:9]), int(head[10:12]), int(head[13:15]), 0.0
            )
            + sec
        )
        assert b.t_s[e] == t
        for j, sat in enumerate(sats):
            rec = lines[k + 1 + j].ljust(64)
            for c, (fld, sig) in enumerate(
                [("phase_cyc", "1C"), ("code_m", "1C"), ("phase_cyc", "2W"), ("code_m", "2W")]
            ):
                s = rec[16 * c : 16 * c + 14]
                v = float(s) if s.strip() else math.nan
                got = cell(b, fld, e, sat, sig)
                assert got == v or (math.isnan(v) and math.isnan(got))
                checked += 1
            lli2 = rec[16 * 2 + 14]
            assert b.lli[e, b.tx_ids.index(sat), 1] == (int(lli2) if lli2.strip() else 0)
        k += 1 + n
        e += 1
    assert e == 120 and checked > 3000
    assert events == len(b.meta["events"]) == 3  # teqc splice comments (flag 4)
    # time tags a few ms off the second are kept: the last epoch is 00:59:30.005
    assert b.meta["t_ns"][-1] % 30_000_000_000 == 5_000_000
    # teqc writes LLI 4 (anti-spoofing) on L2
    assert (b.lli[..., 1][np.isfinite(b.phase_cyc[..., 1])] & 4).all()


def test_f14_layout_detection() -> None:
    """Standard fields convert in place; anything else is flagged for the slow path."""
    from robustrtk.io.rinex_decode import f14_to_float

    cases = {
        "    -12345.678": (-12345.678, False),
        "        -0.001": (-0.001, False),
        "9999999999.999": (9999999999.999, False),
        "-999999999.999": (-999999999.999, False),
        "         0.000": (0.0, False),
        "              ": (math.nan, False),
        "     12 34.567": (None, True),  # space inside the number
        "    1-2345.678": (None, True),  # minus after a digit
        "   --12345.678": (None, True),
        "   19000000.12": (None, True),  # point in the wrong column
        "   1.00000E+01": (None, True),
        "    12345.6x8 ": (None, True),
    }
    arr = np.frombuffer("".join(cases).encode(), np.uint8).reshape(-1, 14)
    val, odd = f14_to_float(arr)
    for (text, (v, is_odd)), got, o in zip(cases.items(), val, odd, strict=True):
        assert bool(o) == is_odd, text
        if v is not None:
            assert got == v or (math.isnan(v) and math.isnan(got)), text
            if not math.isnan(v):
                assert got == float(text)


def _replace_line(lines: list[str], label: str, new: str) -> list[str]:
    return [new if ln[60:].strip() == label else ln for ln in lines]


def test_time_systems(tmp_path: Path) -> None:
    ref = read_rinex_obs(V3)
    lines = _v3_lines()
    first = "  2024     6    24     8    20    0.0000000     {}         TIME OF FIRST OBS"
    bdt = read_rinex_obs(
        _write(tmp_path, "\n".join(_replace_line(lines, "TIME OF FIRST OBS", first.format("BDT"))))
    )
    assert bdt.meta["time_offset_s"] == 14.0
    np.testing.assert_array_equal(bdt.t_s, ref.t_s + 14.0)
    glo = read_rinex_obs(
        _write(tmp_path, "\n".join(_replace_line(lines, "TIME OF FIRST OBS", first.format("GLO"))))
    )
    assert glo.meta["time_offset_s"] == 18.0  # header LEAP SECONDS
    np.testing.assert_array_equal(glo.t_s, ref.t_s + 18.0)
    # RINEX 2 GLONASS-only file without a time system: UTC, leap seconds from the table
    v2 = V2.read_text().splitlines()
    v2[0] = v2[0][:40] + "R" + v2[0][41:]
    # a GLONASS-only file holds GLONASS satellites only (the others are refused)
    import re

    v2 = [
        ln[:32] + re.sub(r"[GES](?=\d\d)", "R", ln[32:68]) + ln[68:]
        if ln.startswith(" 24  1") or (ln[:32].isspace() and ln[32:33].isalpha())
        else ln
        for ln in v2
    ]
    v2 = _replace_line(
        v2,
        "TIME OF FIRST OBS",
        "  2024     1     2     3     4    5.0000000                 TIME OF FIRST OBS",
    )
    b = read_rinex_obs(_write(tmp_path, "\n".join(v2), "glo.24o"))
    assert b.meta["time_system"] == "GLO" and b.meta["time_offset_s"] == 18.0
    np.testing.assert_array_equal(b.t_s, read_rinex_obs(V2).t_s + 18.0)


def test_a_satellite_outside_the_file_type_is_read_and_noted(tmp_path: Path) -> None:
    """Satellites of systems a single-system RINEX 2 file (type G) does not declare are read
    as in a mixed file (as RTKLIB does), and the disagreement is a read note."""
    v2 = V2.read_text().splitlines()
    v2[0] = v2[0][:40] + "G" + v2[0][41:]
    b = read_rinex_obs(_write(tmp_path, "\n".join(v2), "gps.24o"))
    ref = read_rinex_obs(V2)
    assert b.tx_ids == ref.tx_ids and "R11" in b.tx_ids
    np.testing.assert_array_equal(b.code_m, ref.code_m)
    notes = [n for n in b.meta["read_notes"] if "declares system(s) 'GS' only" in n]
    assert len(notes) == 1 and "'RE'" in notes[0]
    assert not ref.meta["read_notes"]


def test_rinex302_beidou_b1_and_scale_factor(tmp_path: Path) -> None:
    ref = read_rinex_obs(V3)
    lines = _v3_lines()
    lines[0] = "     3.02" + lines[0][9:]
    lines = [ln.replace("C    4 C2I L2I C7I L7I", "C    4 C1I L1I C7I L7I") for ln in lines]
    end = next(k for k, ln in enumerate(lines) if "END OF HEADER" in ln)
    lines.insert(end, f"{'G   10  2 L1C L2W':<60}SYS / SCALE FACTOR")
    b = read_rinex_obs(_write(tmp_path, "\n".join(lines)))
    assert b.signals == ref.signals  # B1I renamed 1I -> 2I
    c07 = b.tx_ids.index("C07")
    np.testing.assert_array_equal(b.code_m[:, c07], ref.code_m[:, c07])
    assert b.wavelength_m[c07, b.signals.index("2I")] == wavelength_m("C", "2I")
    g = [b.tx_ids.index("G05"), b.tx_ids.index("G13")]
    np.testing.assert_array_equal(b.phase_cyc[:, g, 0], ref.phase_cyc[:, g, 0] / 10)
    k2w = b.signals.index("2W")
    np.testing.assert_array_equal(b.phase_cyc[:, g, k2w], ref.phase_cyc[:, g, k2w] / 10)
    np.testing.assert_array_equal(b.code_m[:, g], ref.code_m[:, g])  # codes not scaled


def test_rinex4_observation_header_records(tmp_path: Path) -> None:
    """RINEX 4.00 observation files: the 3.05 body with new header records (DOI, LICENSE OF
    USE, STATION INFORMATION), which are ignored."""
    lines = V3.read_text().splitlines(keepends=True)
    lines[0] = lines[0].replace("     3.04", "     4.00")
    extra = [
        f"{'10.1234/example.doi':<60}DOI\n",
        f"{'CC BY 4.0':<60}LICENSE OF USE\n",
        f"{'https://example.org/station/TINY3':<60}STATION INFORMATION\n",
    ]
    p = tmp_path / "tiny_v400.rnx"
    p.write_text("".join([lines[0], lines[1], *extra, *lines[2:]]))
    a = read_rinex_obs(V3)
    b = read_rinex_obs(p)
    assert b.meta["rinex_version"] == 4.0
    assert a.tx_ids == b.tx_ids and a.signals == b.signals
    np.testing.assert_array_equal(a.code_m, b.code_m)
    np.testing.assert_array_equal(a.phase_cyc, b.phase_cyc)
