"""Byte streams decoded incrementally give the epochs of the whole-file decode."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from robustrtk.core import ObsEpoch
from robustrtk.geometry.navdata import NavData
from robustrtk.io.epoch_source import BatchSource, StreamDecoder, detect_format, stream_events
from robustrtk.io.raw_file import read_binary_log
from robustrtk.io.rtcm3 import read_rtcm3, reference_time_s
from robustrtk.io.ubx import read_ubx

FIELDS = ("code_m", "phase_cyc", "doppler_hz", "cn0_dbhz", "lli")


@pytest.fixture(scope="module")
def s1(shared_data: Path) -> Path:
    d = shared_data / "galway_m8p_l1_lowcost" / "s1_static"
    if not d.is_dir():
        pytest.skip(f"{d} absent")
    return d


def chunks(data: bytes, seed: int) -> list[bytes]:
    """``data`` cut at random places (1 byte to 4 KiB pieces)."""
    rng = np.random.default_rng(seed)
    cuts = np.cumsum(rng.integers(1, 4096, size=len(data) // 100 + 2))
    cuts = cuts[cuts < len(data)]
    return [data[a:b] for a, b in zip(np.r_[0, cuts], np.r_[cuts, len(data)], strict=True)]


def assert_epochs_equal_batch(epochs: list[ObsEpoch], batch_path: Path, t_ref: float | None) -> None:
    if t_ref is None:
        batch = read_ubx(batch_path)[0]
    else:
        batch = read_rtcm3(batch_path, t_ref_s=t_ref)[0]
    assert [e.t_s for e in epochs] == [float(t) for t in batch.t_s]
    for e in epochs[:: max(1, len(epochs) // 200)]:
        i = int(np.searchsorted(batch.t_s, e.t_s))
        rows = [batch.tx_ids.index(t) for t in e.tx_ids]
        cols = [batch.signals.index(s) for s in e.signals]
        ref = batch.epoch(i)
        for f in FIELDS:
            a = np.asarray(getattr(ref, f))[np.ix_(rows, cols)]
            np.testing.assert_array_equal(getattr(e, f), a, err_msg=f)
        # rows and signals the stream epoch leaves out are empty in the batch
        others = [k for k in range(len(batch.tx_ids)) if k not in rows]
        assert not np.isfinite(batch.code_m[i, others]).any()


def test_ubx_stream_equals_file(s1: Path) -> None:
    path = s1 / "rover-20181004-1237.ubx.gz"
    data, _ = read_binary_log(path)
    dec = StreamDecoder()
    events = list(stream_events(chunks(data, 1), dec))
    assert dec.fmt == "ubx"
    epochs = [e for e in events if isinstance(e, ObsEpoch)]
    navs = [e for e in events if isinstance(e, NavData)]
    assert len(epochs) > 1000 and navs
    assert_epochs_equal_batch(epochs, path, None)


def test_nav_events_hold_each_ephemeris_once(s1: Path) -> None:
    """Each navigation event holds the records decoded since the one before (the module's
    contract): merged, the events are the file's ephemerides, none twice (a consumer that
    merges every event does not grow quadratically over a long run)."""
    from robustrtk.io.raw_collect import merge_nav

    path = s1 / "rover-20181004-1237.ubx.gz"
    data, _ = read_binary_log(path)
    dec = StreamDecoder()
    navs = [e for e in stream_events(chunks(data, 1), dec) if isinstance(e, NavData)]
    assert len(navs) > 2
    merged = merge_nav(navs)
    file_nav = read_ubx(path)[1]
    for sys in ("G", "R"):
        assert merged.n_records(sys) == file_nav.n_records(sys) > 0
    gps = merged.kepler["G"]
    keys = [(str(a), float(b)) for a, b in zip(gps.sat_id, gps.toe_s, strict=True)]
    assert len(set(keys)) == len(keys)
    assert sum(n.record_counts.get("EPH R FDMA", 0) for n in navs) == merged.n_records("R")
    assert merged.ion_gps_alpha is not None  # came with a later event than the first


def test_rtcm3_stream_equals_file(s1: Path) -> None:
    path = s1 / "base-20181004-1236.rtcm3"
    data, _ = read_binary_log(path)
    t_ref = reference_time_s(str(path), data)
    dec = StreamDecoder(t_ref_s=t_ref)
    epochs = [e for e in stream_events(chunks(data, 2), dec) if isinstance(e, ObsEpoch)]
    assert dec.fmt == "rtcm3" and "arp_ecef_m" in dec.station
    assert len(epochs) > 600  # a gappy base: 623 epochs over 1205 s
    assert_epochs_equal_batch(epochs, path, t_ref)


def test_corrupt_bytes_are_counted_not_raised(s1: Path) -> None:
    data, _ = read_binary_log(s1 / "rover-20181004-1237.ubx.gz")
    data = bytearray(data[:200_000])
    rng = np.random.default_rng(3)
    for k in rng.integers(0, len(data), 300):
        data[k] ^= 0xFF
    dec = StreamDecoder(fmt="ubx")
    epochs = [e for e in stream_events(chunks(bytes(data), 4), dec) if isinstance(e, ObsEpoch)]
    assert epochs and sum(v for k, v in dec.counts.items() if "crc" in k.lower() or "bad" in k) > 0
    assert all(b.t_s > a.t_s for a, b in zip(epochs[:-1], epochs[1:], strict=True))


def test_format_detection_and_batch_source(s1: Path) -> None:
    ubx, _ = read_binary_log(s1 / "rover-20181004-1237.ubx.gz")
    rtcm, _ = read_binary_log(s1 / "base-20181004-1236.rtcm3")
    assert detect_format(ubx[:4096]) == "ubx"
    assert detect_format(rtcm[:4096]) == "rtcm3"
    assert detect_format(b"\x00" * 4096) is None
    batch, nav, _ = read_ubx(s1 / "rover-20181004-1237.ubx.gz", data=ubx)
    events = list(BatchSource(batch, nav))
    assert events[0] is nav and len(events) == len(batch) + 1


@pytest.fixture(scope="module")
def heads(s1: Path) -> dict[str, bytes]:
    ubx, _ = read_binary_log(s1 / "rover-20181004-1237.ubx.gz")
    rtcm, _ = read_binary_log(s1 / "base-20181004-1236.rtcm3")
    t_ref = reference_time_s(str(s1 / "base-20181004-1236.rtcm3"), rtcm)
    return {"ubx": ubx[:30_000], "rtcm3": rtcm[:30_000], "t_ref": str(t_ref).encode()}


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    fmt=st.sampled_from(["ubx", "rtcm3"]),
    flips=st.lists(st.tuples(st.integers(0, 29_999), st.integers(1, 255)), max_size=40),
    cuts=st.lists(st.integers(1, 3000), min_size=1, max_size=30),
)
def test_mutated_streams_decode_without_exceptions(
    heads: dict[str, bytes], fmt: str, flips: list[tuple[int, int]], cuts: list[int]
) -> None:
    """Mutated bytes in random chunks: no exception, epochs still in increasing time."""
    data = bytearray(heads[fmt])
    for k, x in flips:
        data[k % len(data)] ^= x
    dec = StreamDecoder(fmt=None, t_ref_s=float(heads["t_ref"]))
    pieces, k, i = [], 0, 0
    while k < len(data):
        n = cuts[i % len(cuts)]
        pieces.append(bytes(data[k : k + n]))
        k, i = k + n, i + 1
    epochs = [e for e in stream_events(pieces, dec) if isinstance(e, ObsEpoch)]
    assert all(b.t_s > a.t_s for a, b in zip(epochs[:-1], epochs[1:], strict=True))
