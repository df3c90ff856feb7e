"""RTCM 3 messages the galway stream does not carry (ephemerides 1019/1020/1042/1044/1045/1046,
legacy 1004/1012, MSM4 of Galileo, BeiDou and QZSS), built here from known values, decoded by
us and by RTKLIB's convbin (``../shared/tools/rtklib-demo5/convbin``, run into a temporary
folder; skipped without it or the shared data).

The messages are encoded from the field tables of :mod:`robustrtk.io.rtcm3_eph`; convbin
decodes them with its own reading of RTCM 10403.3, so a field out of place shows up as a
difference.
"""

from __future__ import annotations

import math
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from robustrtk.geometry.navdata import NavData
from robustrtk.geometry.orbits import glonass_states, kepler_position
from robustrtk.io.bits import crc24q
from robustrtk.io.rinex_nav import read_rinex_nav
from robustrtk.io.rinex_obs import read_rinex_obs
from robustrtk.io.rtcm3 import read_rtcm3
from robustrtk.io.rtcm3_eph import EPHEMERIS_TABLES
from robustrtk.io.ubx import read_ubx
from robustrtk.timeutil import WEEK_S

CONVBIN = Path(__file__).resolve().parents[2].parent / "shared" / "tools" / "rtklib-demo5" / "convbin"
T_REF = "2018/10/04 12:00:00"


class Bits:
    def __init__(self) -> None:
        self.v = 0
        self.n = 0

    def put(self, value: int, bits: int) -> Bits:
        self.v = (self.v << bits) | (int(value) & ((1 << bits) - 1))
        self.n += bits
        return self

    def sm(self, value: int, bits: int) -> Bits:  # sign-magnitude
        return self.put((1 << (bits - 1)) | -value if value < 0 else value, bits)

    def frame(self) -> bytes:
        pad = (-self.n) % 8
        payload = (self.v << pad).to_bytes((self.n + pad) // 8, "big")
        head = bytes([0xD3, len(payload) >> 8, len(payload) & 0xFF]) + payload
        return head + crc24q(head).to_bytes(3, "big")


def _kepler_msg(number: int, f: dict[str, float]) -> bytes:
    w = Bits().put(number, 12)
    for name, bits, _kind, scale in EPHEMERIS_TABLES[number]:
        w.put(round(f.get(name, 0.0) / scale), bits)
    return w.frame()


@pytest.fixture(scope="module")
def source_nav(shared_data: Path) -> NavData:
    d = shared_data / "galway_m8p_l1_lowcost" / "s1_static"
    if not d.is_dir() or not CONVBIN.is_file():
        pytest.skip("galway data or convbin absent")
    return read_ubx(d / "rover-20181004-1237.ubx.gz")[1]


def _kepler_fields(nav: NavData, i: int) -> dict[str, float]:
    k = nav.kepler["G"]
    f = {name: float(getattr(k, name)[i]) for name in k.__dataclass_fields__ if name != "sat_id"}
    f["prn"] = int(str(k.sat_id[i])[1:])
    f["toc_sow"] = f["toc_s"] % WEEK_S
    f["ura"] = 0
    f["sisa"] = 100
    f["aodc"] = 1
    f["tgd2_s"] = -f["tgd1_s"]
    return f


def _glonass_msg(nav: NavData, i: int, leap: float) -> bytes:
    g = nav.glonass
    tod_tk = (float(g.tk_s[i]) + 10800.0) % 86400.0
    tb = round(((float(g.toe_s[i]) - leap) + 10800.0) % 86400.0 / 900.0)
    w = Bits().put(1020, 12).put(int(str(g.sat_id[i])[1:]), 6).put(int(g.freq_channel[i]) + 7, 5)
    w.put(0, 1).put(1, 1).put(0, 2)
    w.put(int(tod_tk // 3600), 5).put(int(tod_tk % 3600 // 60), 6).put(int(tod_tk % 60 // 30), 1)
    w.put(0, 1).put(0, 1).put(tb, 7)
    for k in range(3):
        w.sm(round(g.vel_m_s[i, k] / 1e3 / 2.0**-20), 24)
        w.sm(round(g.pos_m[i, k] / 1e3 / 2.0**-11), 27)
        w.sm(round(g.acc_m_s2[i, k] / 1e3 / 2.0**-30), 5)
    w.put(0, 1).sm(round(float(g.gamma_n[i]) / 2.0**-40), 11).put(0, 2).put(0, 1)
    w.sm(round(-float(g.minus_tau_n_s[i]) / 2.0**-30), 22).sm(0, 5).put(int(g.age_d[i]), 5)
    w.put(0, 1).put(0, 4).put(0, 11).put(1, 2).put(0, 1).put(0, 11).sm(0, 32).put(0, 5).sm(0, 22)
    w.put(0, 1).put(0, 7)
    return w.frame()


def _convbin(tmp: Path, data: bytes) -> tuple[Path, Path, Path]:
    src = tmp / "synthetic.rtcm3"
    src.write_bytes(data)
    obs, nav = tmp / "cb.obs", tmp / "cb.nav"
    cmd = [
        str(CONVBIN),
        "-r",
        "rtcm3",
        "-tr",
        *T_REF.split(),
        "-v",
        "3.04",
        "-od",
        "-os",
        "-o",
        str(obs),
        "-n",
        str(nav),
        str(src),
    ]
    subprocess.run(cmd, check=True, capture_output=True, timeout=60)
    return src, obs, nav


def _by_key(k: object, keys: list[tuple[str, int]]) -> np.ndarray:
    ids = [(str(s), round(float(t))) for s, t in zip(k.sat_id, k.toe_s, strict=True)]  # type: ignore[attr-defined]
    return np.array([ids.index(key) for key in keys])


def test_ephemeris_messages_decoded_like_convbin(source_nav: NavData, tmp_path: Path) -> None:
    nav = source_nav
    data = b""
    k = nav.kepler["G"]
    gweek = int(k.week[0])
    for i in range(len(k)):
        f = _kepler_fields(nav, i)
        data += _kepler_msg(1019, {**f, "week": gweek % 1024})
        if i < 3:  # the same orbits relabelled: QZSS, Galileo I/NAV and F/NAV, BeiDou
            data += _kepler_msg(1044, {**f, "prn": i + 1, "week": gweek % 1024})
            data += _kepler_msg(1046, {**f, "prn": i + 1, "week": gweek - 1024, "iode": i + 40})
            data += _kepler_msg(1045, {**f, "prn": i + 11, "week": gweek - 1024, "iode": i + 40})
            data += _kepler_msg(1042, {**f, "prn": i + 11, "week": gweek - 1356, "iode": 1})
    for i in range(len(nav.glonass)):
        data += _glonass_msg(nav, i, 18.0)
    src, _, cb_nav = _convbin(tmp_path, data)
    _, ours, counts = read_rtcm3(src, t_ref_s=float(k.toe_s[0]))
    ref = read_rinex_nav(cb_nav)
    assert counts.get("bad 1019", 0) == 0 and counts["1019"] == len(k)
    for s, n in (("G", len(k)), ("J", 3), ("E", 6), ("C", 3)):
        a, b = ours.kepler[s], ref.kepler[s]
        keys = sorted({(str(x), round(float(t))) for x, t in zip(a.sat_id, a.toe_s, strict=True)})
        keys_ref = sorted({(str(x), round(float(t))) for x, t in zip(b.sat_id, b.toe_s, strict=True)})
        assert keys == keys_ref and len(keys) == n, s
        ea, eb = a.take(_by_key(a, keys)), b.take(_by_key(b, keys))
        pa = np.asarray(kepler_position(ea, ea.toe_s + 1800.0, s)[0])
        pb = np.asarray(kepler_position(eb, eb.toe_s + 1800.0, s)[0])
        assert np.max(np.linalg.norm(pa - pb, axis=-1)) < 1e-3, s
        # BeiDou: convbin writes toe / 720 mod 240 as the AODE; ours is the broadcast one
        for fld in ("af0_s", "af1_s_s", "tgd1_s", "toc_s", "week", "health") + (
            ("iode",) if s != "C" else ()
        ):
            va, vb = getattr(ea, fld), getattr(eb, fld)
            np.testing.assert_allclose(va, vb, rtol=1e-11, atol=1e-19, err_msg=f"{s} {fld}")
    ga, gb = ours.glonass, ref.glonass
    keys = sorted((str(x), round(float(t))) for x, t in zip(ga.sat_id, ga.toe_s, strict=True))
    keys_ref = sorted((str(x), round(float(t))) for x, t in zip(gb.sat_id, gb.toe_s, strict=True))
    assert keys == keys_ref and len(keys) == len(nav.glonass)
    ea, eb = ga.take(_by_key(ga, keys)), gb.take(_by_key(gb, keys))
    pa = glonass_states(ea, ea.toe_s + 600.0)[0]
    pb = glonass_states(eb, eb.toe_s + 600.0)[0]
    assert np.max(np.linalg.norm(pa - pb, axis=-1)) < 1e-3
    np.testing.assert_array_equal(ea.freq_channel, eb.freq_channel)
    np.testing.assert_allclose(ea.tk_s, eb.tk_s)


def _legacy_1004(tow_ms: int, sync: int) -> bytes:
    w = Bits().put(1004, 12).put(0, 12).put(tow_ms, 30).put(sync, 1).put(2, 5).put(0, 1).put(0, 3)
    for prn, amb, pr, ppr in ((5, 70, 1234567, 12345), (12, 72, 7654321, -23456)):
        w.put(prn, 6).put(0, 1).put(pr, 24).put(ppr, 20).put(100, 7).put(amb, 8).put(180, 8)
        w.put(3, 2).put(-50, 14).put(ppr - 2000, 20).put(100, 7).put(160, 8)
    return w.frame()


def _legacy_1012(tod_ms: int) -> bytes:
    w = Bits().put(1012, 12).put(0, 12).put(tod_ms, 27).put(1, 1).put(1, 5).put(0, 1).put(0, 3)
    w.put(7, 6).put(0, 1).put(12, 5).put(9876543, 25).put(4321, 20).put(90, 7).put(35, 7).put(170, 8)
    w.put(1, 2).put(25, 14).put(4000, 20).put(90, 7).put(150, 8)
    return w.frame()


def _msm4(number: int, epoch: int, sats: list[int], sig: int, multiple: int) -> bytes:
    w = Bits().put(number, 12).put(0, 12).put(epoch, 30).put(multiple, 1).put(0, 3 + 7 + 2 + 2 + 1 + 3)
    mask = sum(1 << (64 - s) for s in sats)
    w.put(mask, 64).put(1 << (32 - sig), 32).put((1 << len(sats)) - 1, len(sats))
    for k, _ in enumerate(sats):
        w.put(70 + k, 8)
    for k, _ in enumerate(sats):
        w.put(100 * k + 7, 10)
    for k, _ in enumerate(sats):
        w.put(-1000 + 300 * k, 15)
    for k, _ in enumerate(sats):
        w.put(5000 - 77 * k, 22)
    for _ in sats:
        w.put(9, 4)
    for _ in sats:
        w.put(0, 1)
    for k, _ in enumerate(sats):
        w.put(40 + k, 6)
    return w.frame()


def test_observation_messages_decoded_like_convbin(source_nav: NavData, tmp_path: Path) -> None:
    tow0 = 389_000_000  # 2018-10-04 12:03:20 GPST (Thursday)
    data = b""
    for e in range(3):
        tow = tow0 + 1000 * e
        tod_glo = (tow - 4 * 86_400_000 - 18_000 + 10_800_000) % 86_400_000
        data += _legacy_1004(tow, 1) + _legacy_1012(tod_glo)
        data += _msm4(1094, tow, [2, 11, 30], 2, 1)  # Galileo E1C
        data += _msm4(1114, tow, [1, 3], 2, 1)  # QZSS L1C
        data += _msm4(1124, tow - 14_000, [6, 19, 30], 2, 0)  # BeiDou B1I, BDT
    src, cb_obs, _ = _convbin(tmp_path, data)
    ours, _, counts = read_rtcm3(src, t_ref_s=2021 * WEEK_S + 389_000.0)
    ref = read_rinex_obs(cb_obs)
    assert counts["1004"] == counts["1012"] == 3 and counts["1124"] == 3
    np.testing.assert_array_equal(np.round(ours.t_s, 6), np.round(ref.t_s, 6))
    assert set(ours.tx_ids) == set(ref.tx_ids)
    n_cmp = 0
    for n_r, tx in enumerate(ref.tx_ids):
        n_o = ours.tx_ids.index(tx)
        for k_r, sig in enumerate(ref.signals):
            if not np.isfinite(ref.code_m[:, n_r, k_r]).any():
                continue
            k_o = ours.signals.index(sig)
            for f in ("code_m", "phase_cyc", "cn0_dbhz"):
                a = getattr(ours, f)[:, n_o, k_o]
                b = getattr(ref, f)[:, n_r, k_r]
                ok = np.isfinite(b)
                assert np.array_equal(np.isfinite(a), ok), (tx, sig, f)
                assert np.max(np.abs(np.round(a[ok], 3) - b[ok])) <= 1.1e-3, (tx, sig, f)
            n_cmp += 1
    assert n_cmp == 2 * 2 + 2 + 3 + 2 + 3  # G L1+L2, R L1+L2, E, J, C cells
    assert math.isclose(ours.meta["glonass_channels"]["R07"], 5)
    assert shutil.which(str(CONVBIN)) is not None or CONVBIN.is_file()


def _lock_indicator(t_ms: int) -> int:
    """DF407 of a lock time (RTCM 10403.3 table 3.5-75): ``t`` below 64 ms, else
    ``(t - 2^(c+5)) / 2^c + 64 + 32 (c - 1)`` with ``2^(c+5) <= t < 2^(c+6)``."""
    if t_ms < 64:
        return t_ms
    c = t_ms.bit_length() - 6
    return (t_ms - 2 ** (c + 5)) // 2**c + 64 + 32 * (c - 1)


def _msm7(number: int, epoch: int, sats: list[int], sigs: list[int], e: int, multiple: int) -> bytes:
    """MSM7 with every cell present; values vary with satellite, signal and epoch ``e``."""
    w = Bits().put(number, 12).put(0, 12).put(epoch, 30).put(multiple, 1).put(0, 3 + 7 + 2 + 2 + 1 + 3)
    w.put(sum(1 << (64 - s) for s in sats), 64).put(sum(1 << (32 - g) for g in sigs), 32)
    nc = len(sats) * len(sigs)
    w.put((1 << nc) - 1, nc)
    for k, _ in enumerate(sats):
        w.put(68 + k, 8)
    for k, _ in enumerate(sats):
        w.put(8 + k, 4)  # extended info: GLONASS channel + 7
    for k, _ in enumerate(sats):
        w.put(100 * k + 3 * e, 10)
    for k, _ in enumerate(sats):
        w.put(-700 + 450 * k + e, 14)  # rough rate, m/s
    cells = [(a, b) for a in range(len(sats)) for b in range(len(sigs))]
    for a, b in cells:
        w.put(-5000 + 1000 * a + 77 * b + 11 * e, 20)
    for a, b in cells:
        w.put(20000 - 3000 * a + 123 * b + 97 * e, 24)
    for a, b in cells:
        # lock time: 852 s and growing; one signal restarts (0.5 s of lock) at e = 4
        lock_ms = 500 + 1000 * (e - 4) if (a == 1 and b == 0 and e >= 4) else 852_000 + 1000 * e
        w.put(_lock_indicator(lock_ms), 10)
    for a, b in cells:
        w.put(1 if (a == 0 and b == 1) else 0, 1)  # half-cycle ambiguity on one cell
    for a, b in cells:
        w.put(600 + 16 * a + b, 10)
    for a, b in cells:
        w.put(-1200 + 35 * a + 5 * b + e, 15)
    return w.frame()


def test_msm7_week_rollover_like_convbin(tmp_path: Path) -> None:
    if not CONVBIN.is_file():
        pytest.skip("convbin absent")
    # GPST 2018-10-06 23:59:55 .. 2018-10-07 00:00:04: the end of GPS week 2021
    data = b""
    for e in range(10):
        tow = (604_795_000 + 1000 * e) % 604_800_000
        glo_tod = (tow - 6 * 86_400_000 - 18_000 + 10_800_000) % 86_400_000
        bdt = (tow - 14_000) % 604_800_000
        data += _msm7(1077, tow, [3, 17], [2, 16], e, 1)  # GPS L1C, L2L
        data += _msm7(1087, glo_tod, [4, 9], [2, 8], e, 1)  # GLONASS L1C, L2C
        data += _msm7(1117, tow, [1, 2], [2, 16], e, 1)  # QZSS L1C, L2L
        data += _msm7(1097, tow, [5, 24], [2, 22], e, 1)  # Galileo E1C, E5aI
        data += _msm7(1127, bdt, [8, 27], [2, 14], e, 0)  # BeiDou B1I, B2I
    src = tmp_path / "rollover.rtcm3"
    src.write_bytes(data)
    obs = tmp_path / "cb.obs"
    cmd = [str(CONVBIN), "-r", "rtcm3", "-tr", "2018/10/06", "23:00:00", "-v", "3.04", "-od", "-os"]
    subprocess.run([*cmd, "-o", str(obs), str(src)], check=True, capture_output=True, timeout=60)
    ref = read_rinex_obs(obs)
    ours, _, counts = read_rtcm3(src, t_ref_s=2021 * WEEK_S + 6 * 86400.0 + 82800.0)
    t0 = 2022 * WEEK_S - 5.0
    np.testing.assert_allclose(ours.t_s, t0 + np.arange(10), rtol=0, atol=1e-9)
    np.testing.assert_allclose(ref.t_s, ours.t_s, rtol=0, atol=1e-6)
    assert set(ours.tx_ids) == set(ref.tx_ids) and len(ours.tx_ids) == 10
    assert set(ours.signals) == set(ref.signals)
    n_cells = 0
    for n_r, tx in enumerate(ref.tx_ids):
        n_o = ours.tx_ids.index(tx)
        for k_r, sig in enumerate(ref.signals):
            if not np.isfinite(ref.code_m[:, n_r, k_r]).any():
                continue
            k_o = ours.signals.index(sig)
            for f in ("code_m", "phase_cyc", "doppler_hz", "cn0_dbhz"):
                a = getattr(ours, f)[:, n_o, k_o]
                b = getattr(ref, f)[:, n_r, k_r]
                assert np.array_equal(np.isfinite(a), np.isfinite(b)), (tx, sig, f)
                ok = np.isfinite(b)
                assert np.max(np.abs(np.round(a[ok], 3) - b[ok])) <= 1.1e-3, (tx, sig, f)
            np.testing.assert_array_equal(ours.lli[:, n_o, k_o], ref.lli[:, n_r, k_r], err_msg=f"{tx} {sig}")
            n_cells += 1
    assert n_cells == 20
    assert (ours.lli & 1).sum() == 5 and (ours.lli & 2).sum() == 2 * 5 * 10  # restarts, half cycles
