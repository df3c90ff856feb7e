"""Foreign inputs named by what they are; RINEX that RTKLIB reads is read; Compact RINEX capped."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from robustrtk.core import InputError
from robustrtk.io.crx import crx_decompress
from robustrtk.io.readers import detect_format, read_observations

_HEADER = """\
     2.11           OBSERVATION DATA    G (GPS)             RINEX VERSION / TYPE
TEST                                                        MARKER NAME
 -3976219.5082  3382372.5671  3652512.9849                  APPROX POSITION XYZ
     4    L1    C1    L2    P2                              # / TYPES OF OBSERV
  2005     4     2     0     0    0.0000000     GPS         TIME OF FIRST OBS
                                                            END OF HEADER
"""
_EPOCH = """\
 05  4  2  0{minute:3d}{sec:11.7f}  0  2G 3G 7
  55923622.160    24767686.375    43647388.2424   24767684.8224
   -691177.898    24361933.475     -537007.1404   24361930.5994
"""


def _epoch(t_s: float) -> str:
    return _EPOCH.format(minute=int(t_s // 60), sec=t_s % 60)


def _rinex(
    path: Path, header: str = _HEADER, epochs: tuple[float, ...] = (0.0, 30.0, 60.0), extra: str = ""
) -> Path:
    path.write_text(header + "".join(_epoch(s) for s in epochs) + extra)
    return path


def test_plain_file_reads(tmp_path: Path) -> None:
    b = read_observations(_rinex(tmp_path / "a.obs"))
    assert len(b.t_s) == 3 and np.allclose(np.diff(b.t_s), 30.0)


def test_time_of_first_obs_zero_or_two_letter_system(tmp_path: Path) -> None:
    """TIME OF FIRST OBS all zeros: the first epoch gives the time; 'GP' is GPS time."""
    ref = read_observations(_rinex(tmp_path / "a.obs")).t_s
    zero = _HEADER.replace(
        "  2005     4     2     0     0    0.0000000", "     0     0     0     0     0    0.0000000"
    )
    assert np.array_equal(read_observations(_rinex(tmp_path / "z.obs", zero)).t_s, ref)
    gp = _HEADER.replace("     GPS         TIME OF FIRST OBS", "     GP          TIME OF FIRST OBS")
    assert np.array_equal(read_observations(_rinex(tmp_path / "gp.obs", gp)).t_s, ref)
    bad = _HEADER.replace("  2005     4     2", "  2005    14     2")
    with pytest.raises(InputError, match="TIME OF FIRST OBS"):
        read_observations(_rinex(tmp_path / "bad.obs", bad))


def test_crlf_line_ends(tmp_path: Path) -> None:
    p = _rinex(tmp_path / "a.obs")
    ref = read_observations(p)
    crlf = tmp_path / "crlf.obs"
    crlf.write_bytes(p.read_bytes().replace(b"\n", b"\r\n"))
    b = read_observations(crlf)
    assert np.array_equal(b.t_s, ref.t_s) and np.array_equal(b.code_m, ref.code_m, equal_nan=True)


def test_last_epoch_written_twice_is_dropped_and_counted(tmp_path: Path) -> None:
    b = read_observations(_rinex(tmp_path / "dup.obs", epochs=(0.0, 30.0, 60.0, 60.0)))
    assert len(b.t_s) == 3 and b.meta["duplicate_epochs_dropped"] == 1
    # the same time with other content is not a duplicate: refused with its line
    other = _epoch(60.0).replace("24767686.375", "24767686.999")
    with pytest.raises(InputError, match=r"dup2.obs:16: epoch time does not increase"):
        read_observations(_rinex(tmp_path / "dup2.obs", extra=other))
    with pytest.raises(InputError, match="epoch time does not increase"):
        read_observations(_rinex(tmp_path / "back.obs", epochs=(0.0, 60.0, 30.0)))


def test_empty_satellite_rows(tmp_path: Path) -> None:
    """A satellite listed with blank observation lines: read as missing values."""
    text = _HEADER + _epoch(0.0).replace(
        "   -691177.898    24361933.475     -537007.1404   24361930.5994", ""
    )
    p = tmp_path / "e.obs"
    p.write_text(text + _epoch(30.0))
    b = read_observations(p)
    assert len(b.t_s) == 2
    g07 = b.tx_ids.index("G07")
    assert np.all(np.isnan(b.code_m[0, g07])) and np.isfinite(b.code_m[1, g07]).any()


def test_type_count_disagreeing_with_its_list(tmp_path: Path) -> None:
    """Declared 5, listed 4 (records of one line either way): the listed types are read."""
    ref = read_observations(_rinex(tmp_path / "a.obs"))
    five = _HEADER.replace("     4    L1    C1    L2    P2      ", "     5    L1    C1    L2    P2      ")
    b = read_observations(_rinex(tmp_path / "c.obs", five))
    assert np.array_equal(b.code_m, ref.code_m, equal_nan=True)
    # declared 7 (two lines per record) for 4 listed: the records cannot be laid out
    seven = _HEADER.replace("     4    L1    C1    L2    P2      ", "     7    L1    C1    L2    P2      ")
    with pytest.raises(InputError, match="declares 7 observation types but lists 4"):
        read_observations(_rinex(tmp_path / "c7.obs", seven))


@pytest.mark.parametrize(
    ("content", "named"),
    [
        (b"$@\x8b\x1c\xa7\x0f\x60\x00" + bytes(90) + b"$@\x11\x22\x33\x44" + bytes(60), "Septentrio SBF"),
        (
            b"% program   : RTKLIB ver.2.5\n%  GPST          latitude(deg) longitude(deg)  height(m)   Q\n"
            b"2021/09/22 06:30:00.000   35.342058024  139.521986462    47.5626   1  16\n",
            "RTKLIB .pos solution",
        ),
        (b"$GPGGA,063000.00,3520.5234,N,13931.3191,E,4,16,0.7,47.5,M,0.0,M,1.0,0000*5A\r\n" * 3, "NMEA"),
        (b"time,x,y,z,sx,sy,sz,status\n1,2,3,4,0,0,0,single\n", "robustrtk CSV solution"),
        (
            b"MessageType,Provider,LatitudeDegrees,LongitudeDegrees,AltitudeMeters\nFix,GT,37.4,-122.0,5\n",
            "ground-truth CSV",
        ),
        (
            b"     3.04           METEOROLOGICAL DATA                     RINEX VERSION / TYPE\n",
            "meteorological",
        ),
    ],
)
def test_foreign_inputs_named(tmp_path: Path, content: bytes, named: str) -> None:
    p = tmp_path / "input.dat"
    p.write_bytes(content)
    with pytest.raises(InputError, match=named) as info:
        detect_format(p)
    assert "unrecognised content" not in str(info.value)


def test_compact_rinex_capped(tmp_path: Path) -> None:
    from robustrtk.io import crx, rinex_file

    assert crx.MAX_PLAIN_BYTES == rinex_file.MAX_PLAIN_BYTES
    hatanaka = pytest.importorskip("hatanaka")
    plain = _rinex(tmp_path / "a.obs", epochs=tuple(float(s) for s in range(0, 3000, 30))).read_bytes()
    crx = hatanaka.rnx2crx(plain)
    assert crx_decompress(crx, "a.crx") == plain
    assert crx_decompress(crx, "a.crx", head=500) == plain[:500]
    with pytest.raises(InputError, match="decompression bomb"):
        crx_decompress(crx, "a.crx", max_bytes=len(plain) // 2)
    with pytest.raises(InputError, match="bad Hatanaka"):
        crx_decompress(
            b"1.0                 COMPACT RINEX FORMAT                    CRINEX VERS   / TYPE\nx\n", "b.crx"
        )
    p = tmp_path / "a.crx"
    p.write_bytes(crx)
    assert np.array_equal(read_observations(p).t_s, read_observations(tmp_path / "a.obs").t_s)
