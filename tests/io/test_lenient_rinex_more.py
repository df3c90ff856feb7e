"""More RINEX that RTKLIB reads: blank first line, a zero with a stray blank, RINEX 2.12
Galileo navigation, bzip2 and zip containers (capped like gzip); what is broken still refused."""

from __future__ import annotations

import bz2
import io
import zipfile
from pathlib import Path

import numpy as np
import pytest

from robustrtk.core import InputError
from robustrtk.io import rinex_file
from robustrtk.io.readers import detect_format, read_observations
from robustrtk.io.rinex_nav import read_rinex_nav

_DATA = Path(__file__).parent / "data"
_NAV_HEADER = (
    "     2              NAVIGATION DATA                         RINEX VERSION / TYPE\n"
    "                                                            END OF HEADER       \n"
)
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


def _zip(members: dict[str, bytes]) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, data in members.items():
            zf.writestr(name, data)
    return buf.getvalue()


@pytest.mark.parametrize("name", ["tiny_v211.o", "tiny_v304.rnx"])
def test_blank_first_line_observations(tmp_path: Path, name: str) -> None:
    raw = (_DATA / name).read_bytes()
    ref = read_observations(_DATA / name)
    p = tmp_path / name
    p.write_bytes(b"\n  \n" + raw)
    assert detect_format(p) == "rinex_obs"
    b = read_observations(p)
    assert np.array_equal(b.t_s, ref.t_s) and np.array_equal(b.code_m, ref.code_m, equal_nan=True)
    # a non-blank line of something else before the header is still refused
    p.write_bytes(b"garbage\n" + raw)
    with pytest.raises(InputError):
        read_observations(p)


def test_blank_first_line_navigation(tmp_path: Path) -> None:
    p = tmp_path / "x.21n"
    p.write_text("\n" + _NAV_HEADER + _NAV_RECORD)
    assert read_rinex_nav(p).n_records("G") == 1


def test_zero_with_a_stray_blank(tmp_path: Path) -> None:
    """``. 000000000000D+00`` is 0.0 (as RTKLIB reads it); ``0.2 25...`` stays refused."""
    good = read_rinex_nav(_write(tmp_path, "a.21n", _NAV_HEADER + _NAV_RECORD))
    assert good.kepler["G"].e[0] != 0.0
    stray = _NAV_RECORD.replace("0.225092296023D-02", ". 000000000000D+00")
    nav = read_rinex_nav(_write(tmp_path, "b.21n", _NAV_HEADER + stray))
    assert nav.kepler["G"].e[0] == 0.0
    assert nav.kepler["G"].m0_rad[0] == good.kepler["G"].m0_rad[0]
    split = _NAV_RECORD.replace("0.225092296023D-02", "0.2 25092296023D-02")
    with pytest.raises(InputError, match="expected a finite number"):
        read_rinex_nav(_write(tmp_path, "c.21n", _NAV_HEADER + split))


def _write(tmp_path: Path, name: str, text: str) -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def _galileo_v3_records(src: Path) -> tuple[str, list[str]]:
    lines = src.read_text().splitlines(keepends=True)
    end = next(k for k, line in enumerate(lines) if "END OF HEADER" in line)
    body = lines[end + 1 :]
    recs: list[str] = []
    k = 0
    while k < len(body):
        if body[k][:1] == "E":
            recs.append("".join(body[k : k + 8]))
            k += 8
        else:
            k += 1
    return "".join(lines[1 : end + 1]), recs


def test_rinex_212_galileo_navigation(shared_data: Path, tmp_path: Path) -> None:
    """A RINEX 2.12 Galileo (and mixed) navigation file: RINEX 3 records under a 2.12 header."""
    src = shared_data / "mosaicx5_static_1m/base.nav"
    header_rest, recs = _galileo_v3_records(src)
    ref = read_rinex_nav(src)
    assert len(recs) == ref.n_records("E") > 0
    first = "     2.12           N: GNSS NAV DATA    E: GALILEO          RINEX VERSION / TYPE\n"
    nav = read_rinex_nav(_write(tmp_path, "gal.10n", first + header_rest + "".join(recs)))
    assert nav.n_records("E") == ref.n_records("E") and nav.n_records("G") == 0
    np.testing.assert_array_equal(nav.kepler["E"].m0_rad, ref.kepler["E"].m0_rad)
    mixed = first.replace("E: GALILEO", "M: MIXED  ")
    whole = src.read_text().split("END OF HEADER", 1)[1].split("\n", 1)[1]
    both = read_rinex_nav(_write(tmp_path, "mix.10n", mixed + header_rest + whole))
    for s in "GRE":
        assert both.n_records(s) == ref.n_records(s)
    # a GPS RINEX 2 file with RINEX 3 records is still refused
    gps = first.replace("E: GALILEO", "G: GPS    ")
    with pytest.raises(InputError):
        read_rinex_nav(_write(tmp_path, "gps.10n", gps + header_rest + "".join(recs)))


@pytest.mark.parametrize("kind", ["bzip2", "zip"])
def test_bzip2_and_zip_containers(tmp_path: Path, kind: str) -> None:
    obs = (_DATA / "tiny_v211.o").read_bytes()
    nav = (_NAV_HEADER + _NAV_RECORD).encode()

    def pack(data: bytes, member: str) -> bytes:
        return bz2.compress(data) if kind == "bzip2" else _zip({member: data})

    po, pn = tmp_path / "a.o.pack", tmp_path / "a.n.pack"
    po.write_bytes(pack(obs, "a.o"))
    pn.write_bytes(pack(nav, "a.n"))
    ref = read_observations(_DATA / "tiny_v211.o")
    b = read_observations(po)
    assert np.array_equal(b.code_m, ref.code_m, equal_nan=True) and b.meta.get("compression", kind) == kind
    assert detect_format(pn) == "rinex_nav"
    assert read_rinex_nav(pn).n_records("G") == 1


def test_zip_refusals_and_cap(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    obs = (_DATA / "tiny_v211.o").read_bytes()
    two = tmp_path / "two.zip"
    two.write_bytes(_zip({"a.o": obs, "b.o": obs}))
    with pytest.raises(InputError, match="holds 2 files"):
        read_observations(two)
    # a zip "bomb": zeros expanding far beyond the cap are refused, not decoded
    monkeypatch.setattr(rinex_file, "MAX_PLAIN_BYTES", 1 << 20)
    bomb = tmp_path / "bomb.zip"
    bomb.write_bytes(_zip({"a.o": obs[:400] + bytes(8 << 20)}))
    with pytest.raises(InputError, match="decompression bomb"):
        rinex_file.read_rinex_bytes(bomb)
    bzb = tmp_path / "bomb.bz2"
    bzb.write_bytes(bz2.compress(obs[:400] + bytes(8 << 20)))
    with pytest.raises(InputError, match="decompression bomb"):
        rinex_file.read_rinex_bytes(bzb)
