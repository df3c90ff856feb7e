"""Galileo I/NAV pages in UBX RXM-SFRBX, built here from known values, decoded by us and by
RTKLIB's convbin (``../shared/tools/rtklib-demo5/convbin``, run into a temporary folder;
skipped without it). The galway logs hold no Galileo, so the pages are synthetic: word
layouts from the Galileo OS SIS ICD tables, CRC-24Q over each page, u-blox word packing."""

from __future__ import annotations

import struct
import subprocess
from pathlib import Path

import numpy as np
import pytest

from robustrtk.geometry.orbits import kepler_position
from robustrtk.io.bits import crc24q, fletcher8
from robustrtk.io.nav_inav import inav_page_word
from robustrtk.io.rinex_nav import read_rinex_nav
from robustrtk.io.ubx import read_ubx

CONVBIN = Path(__file__).resolve().parents[2].parent / "shared" / "tools" / "rtklib-demo5" / "convbin"
PI = 3.1415926535898
WEEK = 2021  # GPS week; GST week 997
TOW = 391_000


def _word(fields: list[tuple[int, int]]) -> int:
    v, n = 0, 0
    for value, bits in fields:
        v = (v << bits) | (value & ((1 << bits) - 1))
        n += bits
    return v << (128 - n)


def _words(svid: int, iod: int) -> dict[int, int]:
    sc = 2.0**-31 * PI
    r = 2.0**-43 * PI
    c29, c5 = 2.0**-29, 2.0**-5
    toe = 396_000
    return {
        0: _word([(0, 6), (2, 2), (0, 88), (WEEK - 1024, 12), (TOW, 20)]),
        1: _word([(1, 6), (iod, 10), (toe // 60, 14), (round(0.661 / sc), 32), (round(1.79e-3 * 2**33), 32),
                  (round(5440.6 * 2**19), 32)]),
        2: _word([(2, 6), (iod, 10), (round((2.32 + 0.1 * svid) / sc), 32), (round(0.9617 / sc), 32),
                  (round(-1.15 / sc), 32), (round(7.85e-11 / r), 14)]),
        3: _word([(3, 6), (iod, 10), (round(-7.9e-9 / r), 24), (round(4.39e-9 / r), 16),
                  (round(-2.75e-6 / c29), 16), (round(1.15e-5 / c29), 16), (round(157.6 / c5), 16),
                  (round(-52.97 / c5), 16), (107, 8)]),
        4: _word([(4, 6), (iod, 10), (svid, 6), (round(-5.0e-8 / c29), 16), (round(2.05e-8 / c29), 16),
                  (toe // 60, 14), (round(1.447e-4 * 2**34), 31), (round(4.77e-12 * 2**46), 21),
                  (0, 6), (0, 2)]),
        5: _word([(5, 6), (40, 11), (5, 11), (-3, 14), (0, 5), (7, 10), (-9, 10), (0, 2), (0, 2), (0, 1),
                  (0, 1), (WEEK - 1024, 12), (TOW + 2, 20), (0, 23)]),
        6: _word([(6, 6), (-12, 32), (3, 24), (18, 8), (147, 8), (WEEK - 1024 & 255, 8), (137, 8), (7, 3),
                  (18, 8), (TOW + 4, 20)]),
    }  # fmt: skip


def _page(word: int) -> bytes:
    """Even part (bits 0-119, padded to 128) and odd part (bits 128-255) of a nominal page."""
    even = (0 << 127) | (0 << 126) | ((word >> 16) << 14)  # even/odd 0, page type 0, 112 bits
    odd = (1 << 127) | ((word & 0xFFFF) << 110)  # even/odd 1, page type 0, 16 bits, reserved 0
    crc_in = ((even >> 14) << 82) | (odd >> 46)  # even bits 0-113, odd bits 0-81
    odd |= crc24q(crc_in.to_bytes(25, "big")) << 22  # odd bits 82-105
    return even.to_bytes(16, "big") + odd.to_bytes(16, "big")


def _ubx(cls: int, mid: int, payload: bytes) -> bytes:
    body = bytes([cls, mid]) + struct.pack("<H", len(payload)) + payload
    return b"\xb5\x62" + body + bytes(fletcher8(body))


def _sfrbx(svid: int, page: bytes) -> bytes:
    dwords = struct.unpack(">8I", page)
    return _ubx(0x02, 0x13, bytes([2, svid, 0, 0, 8, 0, 2, 0]) + struct.pack("<8I", *dwords))


def _rawx(tow: float) -> bytes:
    head = struct.pack("<dHbBBB2x", tow, WEEK, 18, 1, 1, 1)
    meas = struct.pack("<ddfBBBBHBBBBBx", 2.3e7, 1.2e8, 100.0, 2, 5, 0, 0, 5000, 40, 5, 1, 3, 0x07)
    return _ubx(0x02, 0x15, head + meas)


def test_page_crc_round_trip() -> None:
    w = _words(5, 77)[3]
    wtype, word = inav_page_word(_page(w))  # type: ignore[misc]
    assert wtype == 3 and int.from_bytes(word, "big") == w
    bad = bytearray(_page(w))
    bad[9] ^= 0x10
    assert inav_page_word(bytes(bad)) is None


def test_inav_ephemerides_decoded_like_convbin(tmp_path: Path) -> None:
    if not CONVBIN.is_file():
        pytest.skip("convbin absent")
    data = _rawx(float(TOW - 10))
    for svid, iod in ((5, 77), (24, 78)):
        for t in (0, 1, 2, 3, 4, 6, 5):  # word 5 last: it completes the set
            data += _sfrbx(svid, _page(_words(svid, iod)[t]))
    data += _rawx(float(TOW + 5))
    src = tmp_path / "gal.ubx"
    src.write_bytes(data)
    nav = tmp_path / "cb.nav"
    cmd = [str(CONVBIN), "-r", "ubx", "-v", "3.04", "-o", str(tmp_path / "cb.obs"), "-n", str(nav), str(src)]
    subprocess.run(cmd, check=True, capture_output=True, timeout=60)
    ref = read_rinex_nav(nav).kepler["E"]
    ours = read_ubx(src)[1].kepler["E"]
    assert sorted(map(str, ours.sat_id)) == sorted(map(str, ref.sat_id)) == ["E05", "E24"]
    io = np.argsort(ours.sat_id)
    ir = np.argsort(ref.sat_id)
    a, b = ours.take(io), ref.take(ir)
    np.testing.assert_allclose(a.toe_s, b.toe_s)
    np.testing.assert_allclose(a.toc_s, b.toc_s)
    pa = np.asarray(kepler_position(a, a.toe_s + 3600.0, "E")[0])
    pb = np.asarray(kepler_position(b, b.toe_s + 3600.0, "E")[0])
    assert np.max(np.linalg.norm(pa - pb, axis=-1)) < 1e-3
    for f in ("af0_s", "af1_s_s", "iode", "tgd1_s", "tgd2_s", "accuracy_m", "week", "health"):
        np.testing.assert_allclose(getattr(a, f), getattr(b, f), rtol=1e-11, atol=1e-19, err_msg=f)
