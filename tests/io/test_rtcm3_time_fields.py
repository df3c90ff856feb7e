"""RTCM 3 time fields out of range, BeiDou time-of-week quirks, station changes, lock-time
indicators and SBAS in legacy messages, on hand-built frames."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from robustrtk.io.bits import crc24q
from robustrtk.io.rtcm3 import Rtcm3Decoder, read_rtcm3

WEEK_S = 604_800.0
T_REF = 2021 * WEEK_S + 604_000.0  # Saturday evening of GPS week 2021


class Bits:
    """MSB-first bit writer."""

    def __init__(self) -> None:
        self.v = 0
        self.n = 0

    def put(self, value: int, bits: int) -> Bits:
        self.v = (self.v << bits) | (int(value) & ((1 << bits) - 1))
        self.n += bits
        return self

    def frame(self) -> bytes:
        pad = (-self.n) % 8
        payload = (self.v << pad).to_bytes((self.n + pad) // 8, "big")
        head = bytes([0xD3, len(payload) >> 8, len(payload) & 0xFF]) + payload
        return head + crc24q(head).to_bytes(3, "big")


def msm4(
    number: int,
    epoch: int,
    sats: list[int],
    *,
    station: int = 7,
    lock: int = 5,
    half: int = 0,
    multiple: int = 0,
    phase: int = -2000,
) -> bytes:
    """MSM4, signal id 2 (L1 C/A, E1C, B1I...) for each satellite, one lock indicator for all."""
    w = Bits().put(number, 12).put(station, 12).put(epoch, 30).put(multiple, 1).put(0, 18)
    w.put(sum(1 << (64 - s) for s in sats), 64).put(1 << 30, 32).put((1 << len(sats)) - 1, len(sats))
    for _ in sats:
        w.put(72, 8)
    for k, _ in enumerate(sats):
        w.put(100 + k, 10)
    for _ in sats:
        w.put(1000, 15)
    for _ in sats:
        w.put(phase, 22)
    for _ in sats:
        w.put(lock, 4)
    for _ in sats:
        w.put(half, 1)
    for _ in sats:
        w.put(40, 6)
    return w.frame()


def decode(data: bytes, **kw: object) -> Rtcm3Decoder:
    dec = Rtcm3Decoder(t_ref_s=T_REF, **kw)  # type: ignore[arg-type]
    dec.feed(data)
    dec.close()
    return dec


def test_time_of_week_beyond_a_week_is_skipped_and_counted() -> None:
    data = msm4(1074, 604_790_000, [3]) + msm4(1074, 700_000_000, [3]) + msm4(1074, 604_791_000, [3])
    dec = decode(data)
    b = dec.batch()
    np.testing.assert_array_equal(b.t_s, 2022 * WEEK_S - np.array([10.0, 9.0]))
    assert dec.counts["bad time (time of week >= 1 week)"] == 1


def test_glonass_time_of_day_beyond_a_day_is_skipped_and_counted() -> None:
    tod = (604_790_000 - 6 * 86_400_000 - 18_000 + 10_800_000) % 86_400_000
    data = msm4(1084, tod, [4]) + msm4(1084, 90_000_000, [4]) + msm4(1084, tod + 1000, [4])
    dec = decode(data)
    assert len(dec.batch()) == 2
    assert dec.counts["bad time (GLONASS time of day >= 1 day)"] == 1
    # a day-of-week of 7 (unknown, DF416) in front of the time of day is not an error
    dec = decode(msm4(1084, (7 << 27) | tod, [4]))
    assert len(dec.batch()) == 1


def test_beidou_negative_time_of_week_at_gps_week_start() -> None:
    # GPS epochs 0..2 s of week 2022; BeiDou written as GPST - 14 s without the week wrap:
    # -14 s .. -12 s as 30-bit two's complement, i.e. the end of the previous BDT week
    data = b""
    for e in range(3):
        data += msm4(1074, 1000 * e, [3], multiple=1)
        data += msm4(1124, (1000 * e - 14_000) % (1 << 30), [8])
    dec = decode(data)
    b = dec.batch()
    np.testing.assert_array_equal(b.t_s, 2022 * WEEK_S + np.arange(3.0))
    assert b.tx_ids == ("G03", "C08")
    assert np.isfinite(b.code_m).any(axis=-1).all()
    assert not any(k.startswith("bad") for k in dec.counts)
    # beyond -14 s it is no BDT of this kind: skipped and counted, not a far-away epoch
    dec = decode(msm4(1124, (1 << 30) - 100_000, [8]))
    assert len(dec.batch()) == 0
    assert dec.counts["bad time (BeiDou time of week >= 1 week)"] == 1


def test_beidou_tagged_in_gps_time_detected_and_read_with_the_option() -> None:
    data = b""
    for e in range(3):
        tow = 604_700_000 + 1000 * e
        data += msm4(1074, tow, [3], multiple=1) + msm4(1124, tow, [8])  # BeiDou field = GPST
    dec = decode(data)
    assert dec.counts["BeiDou epochs 14 s off"] == 3
    dec = decode(data, beidou_gpst=True)
    b = dec.batch()
    assert "BeiDou epochs 14 s off" not in dec.counts
    np.testing.assert_array_equal(b.t_s, 2021 * WEEK_S + 604_700.0 + np.arange(3.0))
    assert np.isfinite(b.code_m).any(axis=-1).all()


def lli_of(data: bytes) -> np.ndarray:
    b = decode(data).batch()
    return b.lli[:, 0, 0].astype(int)


def test_lock_time_indicator_gives_loss_of_lock() -> None:
    t0 = 604_700_000
    # DF402 = 5: 512-1024 ms of lock; growing, restarted (0), 1 s later 512-1024 ms again
    # (continuous), then decreasing
    seq = [(0, 5), (1000, 6), (2000, 0), (3000, 5), (4000, 3)]
    data = b"".join(msm4(1074, t0 + dt, [3], lock=k) for dt, k in seq)
    np.testing.assert_array_equal(lli_of(data), [0, 0, 1, 0, 1])
    # a gap longer than the lock time the indicator stands for: the lock restarted
    data = msm4(1074, t0, [3], lock=5) + msm4(1074, t0 + 5000, [3], lock=5)  # 5 s, < 1024 ms
    np.testing.assert_array_equal(lli_of(data), [0, 1])
    data = msm4(1074, t0, [3], lock=13) + msm4(1074, t0 + 5000, [3], lock=13)  # 131-262 s
    np.testing.assert_array_equal(lli_of(data), [0, 0])
    # 0.256-0.512 s of lock 3 s after the previous epoch's 0 ms: restarted in between (more
    # than the 1-s margin for late indicators); 0.5-1 s of lock 1 s after: continuous
    data = msm4(1074, t0, [3], lock=0) + msm4(1074, t0 + 3000, [3], lock=4)
    np.testing.assert_array_equal(lli_of(data), [1, 1])
    data = msm4(1074, t0, [3], lock=0) + msm4(1074, t0 + 1000, [3], lock=5)
    np.testing.assert_array_equal(lli_of(data), [1, 0])
    # half-cycle ambiguity: bit 1, with bit 0 from the lock indicator as without it
    data = msm4(1074, t0, [3], lock=5, half=1) + msm4(1074, t0 + 1000, [3], lock=0, half=1)
    np.testing.assert_array_equal(lli_of(data), [2, 3])


def test_station_change_restarts_lock_tracking() -> None:
    t0 = 604_700_000
    same = msm4(1074, t0, [3], lock=12) + msm4(1074, t0 + 1000, [3], lock=6)
    other = msm4(1074, t0, [3], lock=12) + msm4(1074, t0 + 1000, [3], lock=6, station=8)
    np.testing.assert_array_equal(lli_of(same), [0, 1])
    np.testing.assert_array_equal(lli_of(other), [0, 0])
    assert decode(other).counts["station changes"] == 1


def legacy_1002(tow_ms: int, prns: list[int]) -> bytes:
    w = Bits().put(1002, 12).put(7, 12).put(tow_ms, 30).put(0, 1).put(len(prns), 5).put(0, 4)
    for prn in prns:
        w.put(prn, 6).put(0, 1).put(1_000_000, 24).put(100, 20).put(50, 7).put(70, 8).put(160, 8)
    return w.frame()


def test_sbas_satellites_in_legacy_gps_messages() -> None:
    dec = decode(legacy_1002(604_700_000, [5, 40, 58, 33]))
    b = dec.batch()
    assert b.tx_ids == ("G05", "S20", "S38")  # DF009 40 and 58: PRN 120 and 138
    np.testing.assert_allclose(b.code_m[0, :, 0], 70 * 299_792.458 + 20_000.0)
    assert dec.counts["cells skipped in 1002"] == 1  # 33: neither GPS nor SBAS


def test_glonass_first_message_placed_by_the_first_time_of_week(tmp_path: Path) -> None:
    """A stream opening with GLONASS messages and a reference time 20 h off: the GLONASS time
    of day alone would land a day early; the file reader anchors on the first GPS epoch."""
    tow0 = 4 * 86_400_000 + 70_000_000  # Thursday 19:26:40 GPST
    data = b""
    for e in range(3):
        tow = tow0 + 1000 * e
        tod = (tow - 4 * 86_400_000 - 18_000 + 10_800_000) % 86_400_000
        data += msm4(1084, tod, [4], multiple=1, lock=9) + msm4(1074, tow, [3], lock=9)
    p = tmp_path / "glo_first.rtcm3"
    p.write_bytes(data)
    t_ref = 2021 * WEEK_S + tow0 / 1000.0 - 20 * 3600.0
    b, _, counts = read_rtcm3(p, t_ref_s=t_ref)
    np.testing.assert_array_equal(b.t_s, 2021 * WEEK_S + tow0 / 1000.0 + np.arange(3.0))
    assert b.tx_ids == ("G03", "R04")
    assert not b.lli.any()  # no false loss of lock from a first epoch a day away


def test_loss_of_lock_without_phase_is_reported_on_the_next_phase() -> None:
    t0 = 604_700_000
    data = msm4(1074, t0, [3], lock=9) + msm4(1074, t0 + 1000, [3], lock=0, phase=-(1 << 21))
    data += msm4(1074, t0 + 2000, [3], lock=5) + msm4(1074, t0 + 3000, [3], lock=6)
    b = decode(data).batch()
    assert np.isnan(b.phase_cyc[1, 0, 0]) and np.isfinite(b.phase_cyc[[0, 2, 3], 0, 0]).all()
    np.testing.assert_array_equal(b.lli[[0, 2, 3], 0, 0], [0, 1, 0])


def test_convert_beidou_time_option(tmp_path: Path) -> None:
    from click.testing import CliRunner

    from robustrtk.cli.main import main
    from robustrtk.io.rinex_obs import read_rinex_obs

    data = b""
    for e in range(3):
        tow = 604_700_000 + 1000 * e
        data += msm4(1074, tow, [3], multiple=1) + msm4(1124, tow, [8])  # BeiDou field = GPST
    src = tmp_path / "bds_gpst.rtcm3"
    src.write_bytes(data)
    args = ["convert", str(src), "--time-ref", "2018/10/06 12:00:00"]
    r = CliRunner().invoke(main, [*args, "--out", str(tmp_path / "a.obs")])
    assert r.exit_code == 0 and "3 BeiDou MSM epochs 14 s off" in r.output
    r = CliRunner().invoke(main, [*args, "--out", str(tmp_path / "b.obs"), "--beidou-time", "gpst"])
    assert r.exit_code == 0 and "14 s off" not in r.output
    a, b = read_rinex_obs(tmp_path / "a.obs"), read_rinex_obs(tmp_path / "b.obs")
    # read as BDT the BeiDou epochs fall 14 s late, and the GPS epochs whose last message
    # (the BeiDou one) never came are dropped and counted; read as GPST both are whole
    assert a.tx_ids == ("C08",)
    assert b.tx_ids == ("G03", "C08") and len(b) == 3
    assert np.isfinite(b.code_m).any(axis=-1).all()
    np.testing.assert_array_equal(a.t_s, b.t_s + 14.0)
    r = CliRunner().invoke(
        main, ["convert", str(tmp_path / "b.obs"), "--out", str(tmp_path / "c.obs"), "--beidou-time", "gpst"]
    )
    assert r.exit_code == 2 and "--beidou-time applies to RTCM 3" in r.output


def test_stream_decoder_and_run_read_beidou_in_gps_time_with_the_option() -> None:
    """The option of ``convert`` in the stream decoder (and ``run --beidou-time``): the
    epochs a stream gives equal the file reader's with the same option."""
    from click.testing import CliRunner

    from robustrtk.cli.main import main
    from robustrtk.core import ObsEpoch
    from robustrtk.io.epoch_source import StreamDecoder

    data = b""
    for e in range(3):
        tow = 604_700_000 + 1000 * e
        data += msm4(1074, tow, [3], multiple=1) + msm4(1124, tow, [8])  # BeiDou field = GPST
    t_ref = 2021 * WEEK_S + 604_000.0
    want = decode(data, beidou_gpst=True).batch()
    for gpst in (False, True):
        dec = StreamDecoder(t_ref_s=t_ref, beidou_gpst=gpst)
        events = [*dec.feed(data[:50]), *dec.feed(data[50:]), *dec.close()]
        got = [e for e in events if isinstance(e, ObsEpoch)]
        if gpst:
            np.testing.assert_array_equal([e.t_s for e in got], want.t_s)
            assert all(set(e.tx_ids) == {"G03", "C08"} for e in got)
        else:  # read as BDT: 14 s late, detected and counted
            assert dec.counts.get("BeiDou epochs 14 s off") == 3
    r = CliRunner().invoke(main, ["run", "--help"])
    assert r.exit_code == 0 and "--beidou-time" in r.output
