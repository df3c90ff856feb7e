"""Inputs that once cost minutes, gigabytes or a wrong acceptance: decompression bombs,
FIFOs and devices, short CSV rows, infinite and impossible observation values."""

from __future__ import annotations

import os
import zlib
from pathlib import Path

import numpy as np
import pytest

from robustrtk.core import InputError
from robustrtk.io import rinex_file
from robustrtk.io.obs_checks import mask_impossible, masked_text
from robustrtk.io.obstable import read_obs_table
from robustrtk.io.readers import read_observations
from robustrtk.io.rinex_obs import read_rinex_obs

DATA = Path(__file__).resolve().parent / "data"


def _gzip_bomb(path: Path, head: bytes, n_mib: int) -> None:
    co = zlib.compressobj(9, zlib.DEFLATED, 31)
    with path.open("wb") as fh:
        fh.write(co.compress(head))
        block = b" " * (1 << 20)
        for _ in range(n_mib):
            fh.write(co.compress(block))
        fh.write(co.flush())


def test_a_gzip_bomb_is_refused_before_it_is_expanded(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """RINEX header, then 200 MiB of blanks in a ~0.2 MB file: refused once the output
    passes MAX_EXPANSION times the input (here lowered so that the test stays small)."""
    monkeypatch.setattr(rinex_file, "MAX_PLAIN_BYTES", 8 << 20)
    bomb = tmp_path / "bomb.o.gz"
    _gzip_bomb(bomb, (DATA / "tiny_v211.o").read_bytes()[:800], 200)
    with pytest.raises(InputError, match="decompression bomb"):
        read_rinex_obs(bomb)


def test_gzip_content_that_is_not_rinex_is_refused_at_the_first_chunk(tmp_path: Path) -> None:
    bomb = tmp_path / "zeros.gz"
    _gzip_bomb(bomb, b"\0" * 100, 64)
    with pytest.raises(InputError, match="not RINEX"):
        read_rinex_obs(bomb)


def test_gzip_of_several_members_still_reads(tmp_path: Path) -> None:
    text = (DATA / "tiny_v304.rnx").read_bytes()
    cut = len(text) // 2
    p = tmp_path / "two.rnx.gz"
    p.write_bytes(_gz(text[:cut]) + _gz(text[cut:]))
    a, b = read_rinex_obs(p), read_rinex_obs(DATA / "tiny_v304.rnx")
    np.testing.assert_array_equal(a.code_m, b.code_m)


def _gz(data: bytes) -> bytes:
    co = zlib.compressobj(6, zlib.DEFLATED, 31)
    return co.compress(data) + co.flush()


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs on this system")
@pytest.mark.parametrize("reader", [read_rinex_obs, read_observations])
def test_a_fifo_is_refused_at_once(tmp_path: Path, reader: object) -> None:
    fifo = tmp_path / "stream.o"
    os.mkfifo(fifo)
    with pytest.raises(InputError, match="FIFO"):
        reader(fifo)  # type: ignore[operator]  # would block forever if it were opened


def test_a_device_is_refused() -> None:
    if not os.path.exists("/dev/zero"):
        pytest.skip("no /dev/zero")
    with pytest.raises(InputError, match="device"):
        read_observations("/dev/zero")


def test_a_csv_row_with_missing_fields_is_refused(tmp_path: Path) -> None:
    p = tmp_path / "obs.csv"
    p.write_text(
        "time,receiver,transmitter,code_m,phase_cyc,snr_dbhz,lli\n"
        "0.0,base,PL1,17251.34,414763.48,42.35,0\n0.0,rover,PL1\n"
    )
    with pytest.raises(InputError, match=r"obs.csv:3: expected 7 fields as in the header, got 3"):
        read_obs_table(p, fmt="csv")


def test_an_infinite_table_value_is_refused(tmp_path: Path) -> None:
    p = tmp_path / "obs.csv"
    p.write_text(
        "time,receiver,transmitter,code_m,phase_cyc,snr_dbhz,lli\n0.0,base,PL1,inf,414763.48,42.35,0\n"
    )
    with pytest.raises(InputError, match=r"obs.csv:2: column code_m: expected a finite number"):
        read_obs_table(p, fmt="csv")


def test_impossible_rinex_values_are_masked_and_counted(tmp_path: Path) -> None:
    text = (DATA / "tiny_v304.rnx").read_text()
    ref = read_rinex_obs(DATA / "tiny_v304.rnx")
    k = ref.signals.index("1C")
    i = next(i for i in range(len(ref.tx_ids)) if np.isfinite(ref.code_m[0, i, k]))
    value = f"{ref.code_m[0, i, k]:14.3f}"
    assert text.count(value) == 1
    bad = tmp_path / "bad.rnx"
    bad.write_text(text.replace(value, f"{-2.0e7:14.3f}"))
    b = read_rinex_obs(bad)
    assert np.isnan(b.code_m[0, i, k]) and b.meta["masked_values"] == {"code_m": 1}
    assert masked_text(b) == "1 code_m"
    same = np.isfinite(ref.code_m)
    same[0, i, k] = False
    np.testing.assert_array_equal(b.code_m[same], ref.code_m[same])


def test_mask_impossible_leaves_a_clean_batch_alone() -> None:
    ref = read_rinex_obs(DATA / "tiny_v304.rnx")
    assert mask_impossible(ref) is ref
    arr = ref.code_m.copy()
    arr[0, 0, 0] = np.inf
    from dataclasses import replace

    out = mask_impossible(replace(ref, code_m=arr))
    assert np.isnan(out.code_m[0, 0, 0]) and out.meta["masked_values"]["code_m"] == 1
