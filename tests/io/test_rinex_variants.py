"""RINEX variants met in public readers' test data: each defect class on a small file written
by the test from the tiny RINEX 2.11/3.04 files. What is tolerated is read and named in
``meta["read_notes"]`` (printed by ``info``, warned by ``solve``); what is broken is refused."""

from __future__ import annotations

import gzip
from pathlib import Path

import ncompress
import numpy as np
import pytest
from click.testing import CliRunner

from robustrtk.cli.gnss_messages import warn_read
from robustrtk.cli.main import main
from robustrtk.core import InputError
from robustrtk.io import rinex_file
from robustrtk.io.readers import detect_format, read_observations
from robustrtk.io.rinex_nav import read_rinex_nav
from robustrtk.io.rinex_obs import read_rinex_obs

_DATA = Path(__file__).parent / "data"
V2 = _DATA / "tiny_v211.o"
V3 = _DATA / "tiny_v304.rnx"

_NAV_RECORD = (
    " 6 21  4 29 17 59 44.0 0.112163834274D-04 0.329691829393D-11 0.000000000000D+00\n"
    "    0.340000000000D+02-0.122843750000D+03 0.377408577725D-08 0.291016870089D+00\n"
    "   -0.645034015179D-05 0.225092296023D-02 0.979937613010D-05 0.515375577545D+04\n"
    "    0.410384000000D+06 0.186264514923D-08-0.294573169812D+01-0.186264514923D-08\n"
    "    0.983894919813D+00 0.204593750000D+03-0.983002402270D+00-0.770496379981D-08\n"
    "   -0.197865384745D-09 0.100000000000D+01 0.215500000000D+04 0.000000000000D+00\n"
    "    0.200000000000D+01 0.000000000000D+00 0.419095158577D-08 0.340000000000D+02\n"
    "    0.409092000000D+06 0.400000000000D+01 0.000000000000D+00 0.000000000000D+00\n"
)
_END = f"{'':60}END OF HEADER\n"


def _write(tmp_path: Path, lines: list[str], name: str) -> Path:
    p = tmp_path / name
    p.write_text("\n".join(lines) + "\n")
    return p


def _with(lines: list[str], label: str, new: str) -> list[str]:
    out = [new if ln[60:].strip() == label else ln for ln in lines]
    assert out != lines
    return out


def _notes(path: Path) -> list[str]:
    return list(read_rinex_obs(path).meta["read_notes"])


def test_tiny_files_have_no_notes() -> None:
    assert _notes(V2) == [] and _notes(V3) == []


def test_approx_position_outside_its_columns(tmp_path: Path) -> None:
    """Three numbers shifted out of the F14.4 columns (a converter's layout) are read as
    blank-separated numbers, with a note; a field that is no number is still refused."""
    lines = V2.read_text().splitlines()
    shifted = f"{'   1000000.0000    2000000.0000   3000000.0000':<60}APPROX POSITION XYZ"
    p = _write(tmp_path, _with(lines, "APPROX POSITION XYZ", shifted), "shift.24o")
    b = read_rinex_obs(p)
    np.testing.assert_array_equal(b.approx_pos_m, [1e6, 2e6, 3e6])
    np.testing.assert_array_equal(b.code_m, read_rinex_obs(V2).code_m)
    (note,) = b.meta["read_notes"]
    assert note.startswith("line 6: APPROX POSITION XYZ not in the columns")
    bad = f"{'   1000000.0000    20000x0.0000   3000000.0000':<60}APPROX POSITION XYZ"
    with pytest.raises(InputError, match=r"bad.24o:6: APPROX POSITION XYZ: expected a number"):
        read_rinex_obs(_write(tmp_path, _with(lines, "APPROX POSITION XYZ", bad), "bad.24o"))


def test_seconds_with_a_stray_blank(tmp_path: Path) -> None:
    """'5 .0000000' in TIME OF FIRST OBS and in an epoch tag is 5 s (the blank dropped, noted);
    two blanks inside the digits are refused."""
    lines = V2.read_text().splitlines()
    lines = _with(
        lines,
        "TIME OF FIRST OBS",
        f"{'  2024     1     2     3     4   5 .0000000     GPS':<60}TIME OF FIRST OBS",
    )
    k = next(i for i, ln in enumerate(lines) if ln.startswith(" 24  1  2  3  4  5.0000000"))
    lines[k] = lines[k][:15] + " 5 .0000000" + lines[k][26:]
    b = read_rinex_obs(_write(tmp_path, lines, "blank.24o"))
    ref = read_rinex_obs(V2)
    np.testing.assert_array_equal(b.t_s, ref.t_s)
    np.testing.assert_array_equal(b.meta["t_ns"], ref.meta["t_ns"])
    np.testing.assert_array_equal(b.code_m, ref.code_m)
    first, body = b.meta["read_notes"]
    assert "TIME OF FIRST OBS seconds '5 .0000000'" in first and "read as 5.0000000" in first
    assert body.startswith("1 epoch tag(s) with a stray blank") and f"line {k + 1}" in body
    lines[k] = lines[k][:15] + " 5 .00 0000" + lines[k][26:]
    with pytest.raises(InputError, match=rf"two.24o:{k + 1}: bad epoch time"):
        read_rinex_obs(_write(tmp_path, lines, "two.24o"))


def test_junk_line_starting_like_an_epoch(tmp_path: Path) -> None:
    """A RINEX 3 line starting with '>' without a date and without records (seen in a
    converter's output) is skipped with a note; one followed by records is refused."""
    lines = V3.read_text().splitlines()
    k = [i for i, ln in enumerate(lines) if ln.startswith(">")][-1]
    junk = lines[:k] + ["> 23 29"] + lines[k:]
    b = read_rinex_obs(_write(tmp_path, junk, "junk.rnx"))
    ref = read_rinex_obs(V3)
    np.testing.assert_array_equal(b.t_s, ref.t_s)
    np.testing.assert_array_equal(b.code_m, ref.code_m)
    (note,) = b.meta["read_notes"]
    assert note.startswith("1 line(s) starting with '>'") and f"line {k + 1}" in note
    with_records = lines + ["> 23 29", lines[k + 1]]
    with pytest.raises(InputError, match=rf"recs.rnx:{len(lines) + 1}: bad epoch line"):
        read_rinex_obs(_write(tmp_path, with_records, "recs.rnx"))


@pytest.mark.parametrize(
    ("letter", "tsys", "offset_s"), [("C", "BDT", 14.0), ("E", "GAL", 0.0), ("J", "QZS", 0.0)]
)
def test_default_time_system_of_a_single_system_file(
    tmp_path: Path, letter: str, tsys: str, offset_s: float
) -> None:
    """Without a time system in TIME OF FIRST OBS, a single-system file's tags are in its
    system's time (RINEX 3: BDT for BeiDou, GAL, QZS), noted; the other systems' satellites
    the header does not declare are read as in a mixed file, noted."""
    lines = V3.read_text().splitlines()
    lines[0] = lines[0][:40] + letter + lines[0][41:]
    no_sys = f"{'  2024     6    24     8    20    0.0000000':<60}TIME OF FIRST OBS"
    b = read_rinex_obs(_write(tmp_path, _with(lines, "TIME OF FIRST OBS", no_sys), "one.rnx"))
    ref = read_rinex_obs(V3)
    assert b.meta["time_system"] == tsys and b.meta["time_offset_s"] == offset_s
    np.testing.assert_array_equal(b.t_s, ref.t_s + offset_s)
    assert b.tx_ids == ref.tx_ids
    default, foreign = b.meta["read_notes"]
    assert f"{tsys} assumed" in default and f"system {letter!r}" in default
    assert f"declares system(s) {letter!r} only" in foreign
    # a time system written in the header is used without a note
    gps = read_rinex_obs(_write(tmp_path, lines, "gps.rnx"))
    assert gps.meta["time_system"] == "GPS" and not any("assumed" in n for n in gps.meta["read_notes"])


def test_gps_file_without_time_system_has_no_default_note(tmp_path: Path) -> None:
    lines = V2.read_text().splitlines()
    lines[0] = lines[0][:40] + "G" + lines[0][41:]
    no_sys = f"{'  2024     1     2     3     4    5.0000000':<60}TIME OF FIRST OBS"
    b = read_rinex_obs(_write(tmp_path, _with(lines, "TIME OF FIRST OBS", no_sys), "g.24o"))
    assert b.meta["time_system"] == "GPS"
    assert not any("assumed" in n for n in b.meta["read_notes"])


def test_rinex212_galileo_navigation_with_rinex2_records(tmp_path: Path) -> None:
    """A RINEX 2.12 file of type 'E' whose records are RINEX 2 style (bare satellite number,
    3-column continuation) is navigation data: the same numbers as under a GPS header."""
    gal = tmp_path / "gal.18e"
    gal.write_text(
        f"{'     2.12           E: Galileo NAV DATA':<60}RINEX VERSION / TYPE\n" + _END + _NAV_RECORD
    )
    gps = tmp_path / "gps.18n"
    gps.write_text(f"{'     2.11           N: GPS NAV DATA':<60}RINEX VERSION / TYPE\n" + _END + _NAV_RECORD)
    assert detect_format(gal) == "rinex_nav"
    nav, ref = read_rinex_nav(gal), read_rinex_nav(gps)
    assert nav.n_records("E") == 1 and nav.n_records("G") == 0
    assert list(nav.kepler["E"].sat_id) == ["E06"]
    np.testing.assert_array_equal(nav.kepler["E"].m0_rad, ref.kepler["G"].m0_rad)
    np.testing.assert_array_equal(nav.kepler["E"].toc_s, ref.kepler["G"].toc_s)
    with pytest.raises(InputError, match="holds no observations"):
        read_observations(gal)


def test_unix_compress_read_and_capped(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """.Z (LZW) files, as RINEX archives ship them, are read like the plain file; a stream
    that expands past the cap is refused as a likely bomb; a corrupt one in one line."""
    z = tmp_path / "tiny.24o.Z"
    z.write_bytes(ncompress.compress(V2.read_bytes()))
    b = read_rinex_obs(z)
    ref = read_rinex_obs(V2)
    assert b.meta["compression"] == "compress" and detect_format(z) == "rinex_obs"
    np.testing.assert_array_equal(b.code_m, ref.code_m)
    np.testing.assert_array_equal(b.phase_cyc, ref.phase_cyc)
    bomb = tmp_path / "bomb.24o.Z"
    bomb.write_bytes(ncompress.compress(V2.read_bytes() + b" " * (3 << 20)))
    monkeypatch.setattr(rinex_file, "MAX_PLAIN_BYTES", 1 << 20)
    with pytest.raises(InputError, match="compress data expands beyond 1 MiB.*decompression bomb"):
        read_rinex_obs(bomb)
    with pytest.raises(InputError, match="decompression bomb"):
        detect_format(bomb)
    bad = tmp_path / "bad.24o.Z"
    bad.write_bytes(b"\x1f\x9d\x98" + b"\xff" * 64)
    with pytest.raises(InputError, match=r"bad.24o.Z: cannot decompress compress"):
        read_rinex_obs(bad)


@pytest.mark.parametrize("packed", [False, True])
def test_sp3_orbit_file_is_named(tmp_path: Path, packed: bool) -> None:
    """An SP3 precise-orbit file (plain or gzip) is refused as what it is, not as unknown bytes."""
    text = (
        b"#cP2017  2 14  0  0  0.00000000       2 ORBIT IGS14 HLM  IGS\n"
        b"## 1936 172800.00000000   900.00000000 57798 0.0000000000000\n"
        b"+    2   G01G02  0  0  0  0  0  0  0  0  0  0  0  0  0  0  0\n"
    )
    p = tmp_path / "orbit.sp3"
    p.write_bytes(gzip.compress(text) if packed else text)
    with pytest.raises(InputError, match=r"orbit.sp3: an SP3-c precise orbit file"):
        read_observations(p)


def test_notes_printed_by_info_and_warned_by_solve(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    lines = V2.read_text().splitlines()
    shifted = f"{'   1000000.0000    2000000.0000   3000000.0000':<60}APPROX POSITION XYZ"
    p = _write(tmp_path, _with(lines, "APPROX POSITION XYZ", shifted), "shift.24o")
    r = CliRunner().invoke(main, ["info", str(p)])
    assert r.exit_code == 0, r.output
    noted = [ln for ln in r.output.splitlines() if ln.strip().startswith("note:")]
    assert noted == ["  note: " + read_rinex_obs(p).meta["read_notes"][0]]
    warn_read(str(p), "", 0, notes=["first", "second"])
    err = capsys.readouterr().err.splitlines()
    assert err == [f"warning: {p}: first", f"warning: {p}: second"]


def test_fortran_three_digit_exponent_without_letter(tmp_path: Path) -> None:
    """Fortran drops the ``D`` of an exponent that needs three digits (``0.499063314480-269``,
    seen in the spare fields of IGS broadcast files): the number is read as written."""
    rec = _NAV_RECORD.splitlines(keepends=True)
    rec[-1] = rec[-1][:41] + " 0.499063314480-269 0.664593648549-315\n"
    head = f"{'     2.11           N: GPS NAV DATA':<60}RINEX VERSION / TYPE\n" + _END
    p = tmp_path / "exp3.21n"
    p.write_text(head + "".join(rec))
    ref_p = tmp_path / "ref.21n"
    ref_p.write_text(head + _NAV_RECORD)
    nav, ref = read_rinex_nav(p), read_rinex_nav(ref_p)
    np.testing.assert_array_equal(nav.kepler["G"].m0_rad, ref.kepler["G"].m0_rad)
    np.testing.assert_array_equal(nav.kepler["G"].toe_s, ref.kepler["G"].toe_s)
    rec[-1] = rec[-1][:41] + " 0.499063314480-2x9 0.664593648549-315\n"
    p.write_text(head + "".join(rec))
    with pytest.raises(InputError, match=r"exp3.21n:10: expected a finite number"):
        read_rinex_nav(p)


def test_rinex212_qzss_navigation_with_rinex3_records(tmp_path: Path) -> None:
    """A RINEX 2.12 navigation file with 'J' (QZSS) in column 41 and lettered records reads
    them as RINEX 3 records, as for Galileo."""
    rec = _NAV_RECORD.splitlines(keepends=True)
    v3 = ["J01 2021 04 29 17 59 44" + rec[0][22:]] + [" " + ln for ln in rec[1:]]
    qzs = tmp_path / "qzs.21q"
    qzs.write_text(
        f"{'     2.12           N                   J':<60}RINEX VERSION / TYPE\n" + _END + "".join(v3)
    )
    gps = tmp_path / "gps.21n"
    gps.write_text(f"{'     2.11           N: GPS NAV DATA':<60}RINEX VERSION / TYPE\n" + _END + _NAV_RECORD)
    nav, ref = read_rinex_nav(qzs), read_rinex_nav(gps)
    assert nav.n_records("J") == 1 and list(nav.kepler["J"].sat_id) == ["J01"]
    np.testing.assert_array_equal(nav.kepler["J"].m0_rad, ref.kepler["G"].m0_rad)
    np.testing.assert_array_equal(nav.kepler["J"].toc_s, ref.kepler["G"].toc_s)


def test_streamed_blocks_name_the_file_lines_in_their_notes(tmp_path: Path) -> None:
    """A plain RINEX 3 file read block by block gives the notes of the whole-file read, with
    the file's line numbers."""
    from robustrtk.io.rinex_chunks import iter_rinex_obs

    lines = V3.read_text().splitlines()
    k = [i for i, ln in enumerate(lines) if ln.startswith(">")][-1]
    p = _write(tmp_path, lines[:k] + ["> 23 29"] + lines[k:], "junk.rnx")
    whole = read_rinex_obs(p).meta["read_notes"]
    blocks = list(iter_rinex_obs(p, epochs_per_chunk=1))
    assert len(blocks) > 1
    streamed = [n for b in blocks for n in b.meta["read_notes"]]
    assert streamed == whole and f"line {k + 1}" in whole[0]


def test_rinex2_type_list_longer_than_its_count(tmp_path: Path) -> None:
    """'# / TYPES OF OBSERV' declaring 6 types but listing 7 (records of two lines either
    way): when the records hold values in the 7th field, the list is what they carry and all
    7 are read; when no record does, the declared 6. A note says which."""
    import re

    lines = V2.read_text().splitlines()
    k = next(i for i, ln in enumerate(lines) if ln[60:].strip() == "# / TYPES OF OBSERV")
    lines[k] = "     6" + lines[k][6:]
    ref = read_rinex_obs(V2)
    b = read_rinex_obs(_write(tmp_path, lines, "six.24o"))
    np.testing.assert_array_equal(b.cn0_dbhz, ref.cn0_dbhz)
    assert np.isfinite(ref.cn0_dbhz).any()
    (note,) = b.meta["read_notes"]
    assert "declares 6 observation types but lists 7" in note and "all 7" in note

    # the 7th field (S1, second line of each record) left blank in every record
    def is_second(ln: str) -> bool:
        return len(ln) <= 32 and bool(
            re.fullmatch(r"\s*(-?\d+\.\d{3})?\s*", ln[:16]) and re.fullmatch(r"\s*\d+\.\d{3}", ln[16:])
        )

    blanked = [ln[:16] if is_second(ln) else ln for ln in lines]
    assert blanked != lines
    c = read_rinex_obs(_write(tmp_path, blanked, "blank7.24o"))
    assert not np.isfinite(c.cn0_dbhz).any()
    np.testing.assert_array_equal(c.code_m, ref.code_m)
    np.testing.assert_array_equal(c.doppler_hz, ref.doppler_hz)
    (note,) = c.meta["read_notes"]
    assert "the first 6 read" in note


@pytest.mark.parametrize("kind", ["zero", "absent"])
def test_time_of_first_obs_zero_or_absent_is_noted(tmp_path: Path, kind: str) -> None:
    """TIME OF FIRST OBS all zeros or missing: the epochs give the start (as RTKLIB) and GPS
    time is assumed for the mixed file; both said in notes, the data as with the record."""
    lines = V2.read_text().splitlines()
    if kind == "zero":
        zero = f"{'     0     0     0     0     0    0.0000000':<60}TIME OF FIRST OBS"
        lines = _with(lines, "TIME OF FIRST OBS", zero)
    else:
        lines = [ln for ln in lines if ln[60:].strip() != "TIME OF FIRST OBS"]
    b = read_rinex_obs(_write(tmp_path, lines, "t0.24o"))
    ref = read_rinex_obs(V2)
    np.testing.assert_array_equal(b.t_s, ref.t_s)
    np.testing.assert_array_equal(b.code_m, ref.code_m)
    start, tsys = b.meta["read_notes"]
    assert ("all zeros" if kind == "zero" else "no TIME OF FIRST OBS record") in start
    assert "GPS assumed, which a mixed file must name" in tsys


@pytest.mark.parametrize("version", [2, 3])
def test_file_cut_short_inside_its_last_epoch(tmp_path: Path, version: int) -> None:
    """A file that ends inside its last epoch (a logger stopped, a transfer cut) gives the
    complete epochs, the last one dropped and noted; the same shortfall before another
    epoch is a count error and refused."""
    src = V2 if version == 2 else V3
    lines = src.read_text().splitlines()
    ref = read_rinex_obs(src)
    cut = lines[:-1]
    b = read_rinex_obs(_write(tmp_path, cut, "cut.obs"))
    np.testing.assert_array_equal(b.t_s, ref.t_s[:-1])
    assert len(b) == len(ref) - 1
    (note,) = [n for n in b.meta["read_notes"] if "ends inside its last epoch" in n]
    epoch_lines = [
        i for i, ln in enumerate(lines) if (ln.startswith(">") if version == 3 else ln.startswith(" 24"))
    ]
    assert f"line {epoch_lines[-1] + 1}" in note
    if version == 3:
        k = epoch_lines[0]
        bad = lines[: k + 1] + lines[k + 2 :]  # a record missing before the next epoch
        with pytest.raises(InputError, match=rf"bad.obs:{k + 1}: satellite count does not match"):
            read_rinex_obs(_write(tmp_path, bad, "bad.obs"))


def test_rinex_clock_304_header_is_named(tmp_path: Path) -> None:
    """RINEX clock 3.04 puts its labels in column 66: still named as a clock file."""
    p = tmp_path / "a.clk"
    p.write_text(f"{'3.04                 C                    G':<65}RINEX VERSION / TYPE\n")
    with pytest.raises(InputError, match=r"a.clk: a RINEX clock file; expected RINEX observation data"):
        read_observations(p)


def test_rinex4_system_wide_record_without_satellite_number(tmp_path: Path) -> None:
    """'> STO E   IFNV' (a Galileo-GPS offset that names its system only, as an IGS merged
    RINEX 4 file writes it) is read with the system letter as its id; an ephemeris record
    without a satellite number is still refused."""
    head = f"{'     4.00           N: GNSS NAV DATA    M: MIXED':<60}RINEX VERSION / TYPE\n" + _END
    sto = (
        "> STO E   IFNV\n"
        "    2023 03 13 00 00 00 GAGP\n"
        "     4.510000000000e+04 1.073931343853e-08 1.865174681370e-14 0.000000000000e+00\n"
    )
    p = tmp_path / "sto.rnx"
    p.write_text(head + sto)
    (off,) = read_rinex_nav(p).time_offsets
    assert off.sat_id == "E" and off.code == "GAGP" and off.message == "IFNV"
    assert off.a0_s == 1.073931343853e-08 and off.t_tot_s == 4.51e4
    p.write_text(head + sto.replace("> STO E   IFNV", "> EPH E   INAV"))
    with pytest.raises(InputError, match=r"sto.rnx:3: bad record header '> EPH E   INAV'"):
        read_rinex_nav(p)


@pytest.mark.parametrize("magic", [b"\x89HDF\r\n\x1a\n", b"CDF\x01"])
def test_netcdf_and_hdf5_files_are_named(tmp_path: Path, magic: bytes) -> None:
    p = tmp_path / "obs.nc"
    p.write_bytes(magic + bytes(200))
    with pytest.raises(InputError, match=r"obs.nc: a netCDF/HDF5 data file"):
        read_observations(p)
