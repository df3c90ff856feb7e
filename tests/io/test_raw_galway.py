"""UBX and RTCM 3 decoding of the galway u-blox M8P logs against RINEX written by RTKLIB's
convbin from the same files (``../shared/data/galway_m8p_l1_lowcost``; skipped without it).

convbin's RINEX has 3 decimals: our values must round to its values (1 mm, 0.001 cycle,
0.001 Hz, 0.001 dB-Hz; a Doppler may sit on a rounding tie, hence the 1.1e-3 bound). LLI bits
must be equal, except RTCM 3 slips we flag where the time since a signal's previous epoch
exceeds its lock time (convbin compares only successive lock indicators).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from robustrtk.core import ObsBatch
from robustrtk.geometry.navdata import NavData
from robustrtk.geometry.orbits import glonass_states, kepler_position
from robustrtk.io.readers import detect_format, read_navigation, read_observations
from robustrtk.io.rinex_nav import read_rinex_nav
from robustrtk.io.rinex_obs import read_rinex_obs
from robustrtk.io.rtcm3 import read_rtcm3
from robustrtk.io.ubx import read_ubx

FIELDS = ("code_m", "phase_cyc", "doppler_hz", "cn0_dbhz")


@pytest.fixture(scope="module")
def galway(shared_data: Path) -> Path:
    d = shared_data / "galway_m8p_l1_lowcost"
    if not d.is_dir():
        pytest.skip(f"{d} absent")
    return d


def _aligned(ours: ObsBatch, ref: ObsBatch) -> tuple[np.ndarray, np.ndarray, list[int], list[int]]:
    assert set(ours.tx_ids) == set(ref.tx_ids)
    assert ours.signals == ref.signals
    np.testing.assert_array_equal(np.round(ours.t_s, 6), np.round(ref.t_s, 6))
    n_o = [ours.tx_ids.index(t) for t in ref.tx_ids]
    return np.arange(len(ours)), np.arange(len(ref)), n_o, list(range(len(ref.tx_ids)))


def _assert_values_equal(ours: ObsBatch, ref: ObsBatch) -> tuple[np.ndarray, np.ndarray]:
    io, ir, no, nr = _aligned(ours, ref)
    for f in FIELDS:
        a = getattr(ours, f)[np.ix_(io, no)]
        b = getattr(ref, f)[np.ix_(ir, nr)]
        np.testing.assert_array_equal(np.isfinite(a), np.isfinite(b), err_msg=f)
        ok = np.isfinite(b)
        assert np.max(np.abs(np.round(a[ok], 3) - b[ok])) <= 1.1e-3, f
    return ours.lli[np.ix_(io, no)], ref.lli[np.ix_(ir, nr)]


@pytest.mark.parametrize(
    "session, name", [("s1_static", "rover-20181004-1237"), ("s3_kinematic", "rover-20181009-1221")]
)
def test_ubx_rover_equals_convbin(galway: Path, session: str, name: str) -> None:
    path = galway / session / f"{name}.ubx.gz"
    assert detect_format(path) == "ubx"
    ours, nav, counts = read_ubx(path)
    ref = read_rinex_obs(galway / session / f"{name}.obs")
    lli_o, lli_r = _assert_values_equal(ours, ref)
    has_phase = np.isfinite(ref.phase_cyc)
    np.testing.assert_array_equal(lli_o[has_phase], lli_r[has_phase])
    assert (lli_r[has_phase] & 1).sum() > 100  # the comparison covers real slips
    assert ours.meta["glonass_channels"] == ref.meta["glonass_channels"]
    assert counts["RXM-RAWX"] == len(ref)


def _kepler_positions(nav: NavData, system: str, keys: list[tuple[str, int]]) -> np.ndarray:
    k = nav.kepler[system]
    idx = {(str(k.sat_id[i]), round(float(k.toe_s[i]))): i for i in range(len(k))}
    rows = np.array([idx[key] for key in keys])
    eph = k.take(rows)
    return np.asarray(kepler_position(eph, eph.toe_s, system)[0])


def test_ubx_ephemerides_equal_convbin(galway: Path) -> None:
    d = galway / "s1_static"
    _, nav, _ = read_ubx(d / "rover-20181004-1237.ubx.gz")
    ref = read_rinex_nav(d / "rover-20181004-1237.nav")
    g, gr = nav.kepler["G"], ref.kepler["G"]
    keys = sorted((str(g.sat_id[i]), round(float(g.toe_s[i]))) for i in range(len(g)))
    keys_ref = sorted((str(gr.sat_id[i]), round(float(gr.toe_s[i]))) for i in range(len(gr)))
    assert keys == keys_ref and len(keys) == 14
    # same satellite positions at their times of ephemeris to 1 mm
    p = _kepler_positions(nav, "G", keys)
    q = _kepler_positions(ref, "G", keys)
    assert np.max(np.linalg.norm(p - q, axis=-1)) < 1e-3
    for f in ("af0_s", "af1_s_s", "iode", "iodc", "health", "accuracy_m", "tgd1_s", "week", "fit_or_aodc"):
        a = getattr(g, f)[np.argsort([str(s) + str(t) for s, t in zip(g.sat_id, g.toe_s, strict=True)])]
        b = getattr(gr, f)[np.argsort([str(s) + str(t) for s, t in zip(gr.sat_id, gr.toe_s, strict=True)])]
        np.testing.assert_allclose(a, b, rtol=1e-11, atol=1e-20, err_msg=f)
    # GLONASS: same records, states at tb + 15 min to 1 mm
    r, rr = nav.glonass, ref.glonass
    ko = {(str(r.sat_id[i]), round(float(r.toe_s[i]))): i for i in range(len(r))}
    kr = {(str(rr.sat_id[i]), round(float(rr.toe_s[i]))): i for i in range(len(rr))}
    assert set(ko) == set(kr) and len(ko) == 8
    keys_r = sorted(ko)
    a = r.take(np.array([ko[k] for k in keys_r]))
    b = rr.take(np.array([kr[k] for k in keys_r]))
    pa = glonass_states(a, a.toe_s + 900.0)[0]
    pb = glonass_states(b, b.toe_s + 900.0)[0]
    assert np.max(np.linalg.norm(pa - pb, axis=-1)) < 1e-3
    np.testing.assert_array_equal(a.freq_channel, b.freq_channel)
    np.testing.assert_allclose(a.minus_tau_n_s, b.minus_tau_n_s, rtol=1e-11, atol=1e-20)


@pytest.mark.parametrize(
    "session, name", [("s1_static", "base-20181004-1236"), ("s3_kinematic", "base-20181009-1220")]
)
def test_rtcm3_base_equals_convbin(galway: Path, session: str, name: str) -> None:
    path = galway / session / f"{name}.rtcm3"
    assert detect_format(path) == "rtcm3"
    ours, _, counts = read_rtcm3(path)  # week from the date in the file name
    ref = read_rinex_obs(galway / session / f"{name}_rtcm.obs")
    lli_o, lli_r = _assert_values_equal(ours, ref)
    np.testing.assert_allclose(ours.approx_pos_m, ref.approx_pos_m, atol=1e-4)
    assert counts.get("bad_crc", 0) == 0 and counts["skipped_bytes"] == 0
    # equal LLI, except our extra slips after a gap longer than the lock time
    diff = np.argwhere(lli_o != lli_r)
    assert len(diff) <= 0.002 * np.isfinite(ref.phase_cyc).sum()
    for e, n, k in diff:
        assert lli_o[e, n, k] == 1 and lli_r[e, n, k] == 0
        prev = np.flatnonzero(np.isfinite(ref.phase_cyc[:e, n, k]))
        assert prev.size and ref.t_s[e] - ref.t_s[prev[-1]] > 1.5, (ref.t_s[e], ref.tx_ids[n])


def test_readers_and_navigation_dispatch(galway: Path) -> None:
    d = galway / "s1_static"
    b = read_observations(d / "base-20181004-1236.rtcm3", systems="G")
    assert set(b.system) == {"G"} and len(b) == 623
    nav = read_navigation([d / "rover-20181004-1237.ubx.gz", d / "rover-20181004-1237.nav"])
    assert len(nav.kepler["G"]) == 28 and len(nav.glonass) == 16


def test_gzip_rtcm3_read_by_content(galway: Path, tmp_path: Path) -> None:
    import gzip

    src = galway / "s1_static" / "base-20181004-1236.rtcm3"
    dst = tmp_path / "base-20181004.bin.gz"  # neither name nor extension says RTCM 3
    dst.write_bytes(gzip.compress(src.read_bytes()))
    assert detect_format(dst) == "rtcm3"
    a, b = read_observations(dst), read_observations(src)
    np.testing.assert_array_equal(a.phase_cyc, b.phase_cyc)
    assert a.meta["compression"] == "gzip"
