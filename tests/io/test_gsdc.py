"""GSDC device_gnss.csv reader: fixtures against the GnssLogger reader, malformed rows."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from robustrtk.core import InputError
from robustrtk.io.gnsslogger import read_gnsslogger
from robustrtk.io.gsdc import read_device_gnss

FIX = Path(__file__).resolve().parents[2] / ".." / "shared" / "data" / "android_parser_fixtures"
P7 = FIX / "google_decimeter_2023" / "2023-09-07-18-59-us-ca" / "pixel7pro"
needs_fixtures = pytest.mark.skipif(not FIX.is_dir(), reason="../shared/data/android_parser_fixtures absent")


@needs_fixtures
def test_2023_same_layout_as_the_raw_log() -> None:
    g = read_device_gnss(P7 / "device_gnss.csv")
    raw = read_gnsslogger(P7 / "gnss_log.txt", clock="first")
    assert g.meta["format"] == "gsdc_device_gnss"
    assert g.tx_ids == raw.tx_ids and g.signals == raw.signals == ("1C", "5Q")
    # tags from ArrivalTimeNanosSinceGpsEpoch (the CSV's FullBiasNanos lost digits): 1e-5 s
    np.testing.assert_allclose(g.t_s, raw.t_s, atol=1e-5)
    d = g.code_m - raw.code_m
    assert np.isfinite(d).sum() > 150
    assert np.nanmax(np.abs(d - np.nanmedian(d))) < 1e-3
    for name in ("phase_cyc", "doppler_hz", "cn0_dbhz", "phase_sigma_cyc"):
        np.testing.assert_allclose(getattr(g, name), getattr(raw, name), rtol=0, atol=1e-6, equal_nan=True)
    np.testing.assert_array_equal(g.lli, raw.lli)
    assert g.approx_pos_m is not None and np.linalg.norm(g.approx_pos_m) > 6.3e6


@needs_fixtures
def test_2022_signals_and_gating() -> None:
    b = read_device_gnss(FIX / "google_decimeter_2022" / "device_gnss.csv")
    assert len(b) == 6 and b.signals == ("1C", "2I", "5X")
    assert set(b.system) == {"G", "R", "E", "C", "J"}
    # rows with TOW_KNOWN only (no code lock) have no RawPseudorangeMeters use
    assert b.meta["n_code_rejected"]["no code lock"] > 0  # type: ignore[index]
    # epoch tags from the exact integer fields: TimeNanos - FullBiasNanos - BiasNanos
    assert b.t_s[0] == pytest.approx((2122186000000 + 1303768821813692247) * 1e-9, abs=1e-6)
    assert ((b.lli & 1) != 0).any()  # ADR state 29: cycle slip
    assert not ((b.lli & 2) != 0).any()  # every reported half cycle is resolved


def _csv(tmp_path: Path, body: str) -> Path:
    p = tmp_path / "device_gnss.csv"
    p.write_text(
        "MessageType,utcTimeMillis,Svid,ConstellationType,CarrierFrequencyHz,State,RawPseudorangeMeters\n"
        + body
    )
    return p


def test_malformed(tmp_path: Path) -> None:
    with pytest.raises(InputError, match=r"device_gnss.csv:3: column RawPseudorangeMeters: 'abc'"):
        read_device_gnss(
            _csv(tmp_path, "Raw,1000,5,1,1575420000,16399,2.1e7\nRaw,1000,6,1,1575420000,16399,abc\n")
        )
    with pytest.raises(InputError, match=r"device_gnss.csv:2: row has fewer fields"):
        read_device_gnss(_csv(tmp_path, "Raw,1000,5,1\n"))
    with pytest.raises(InputError, match=r"device_gnss.csv:3: utcTimeMillis 900 is earlier"):
        read_device_gnss(
            _csv(tmp_path, "Raw,1000,5,1,1575420000,16399,2.1e7\nRaw,900,5,1,1575420000,16399,2.1e7\n")
        )
    p = tmp_path / "other.csv"
    p.write_text("utcTimeMillis,Svid\n1,2\n")
    with pytest.raises(InputError, match="lacks column"):
        read_device_gnss(p)


def test_minimal_file_utc_tags(tmp_path: Path) -> None:
    ms = 1_619_735_726_000  # 2021-04-29 UTC, leap 18 s
    p = _csv(tmp_path, f"Raw,{ms},5,1,1575420000,16399,21000000.5\nRaw,{ms + 1000},5,1,,16399,21000100.5\n")
    b = read_device_gnss(p)
    assert b.tx_ids == ("G05",) and b.signals == ("1C",)
    assert b.t_s[0] == pytest.approx((ms - 315_964_800_000) / 1000 + 18)
    np.testing.assert_allclose(b.code_m[:, 0, 0], [21000000.5, 21000100.5])
