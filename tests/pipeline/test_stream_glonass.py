"""GLONASS FDMA carrier phase in the real-time solver: channels learnt from the stream, the
``glonass_ar = auto`` rule from the receivers' makes, and base epochs missing a system
completed as the file solve completes them."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from robustrtk.core import ObsEpoch
from robustrtk.gnss import wavelength_m
from robustrtk.pipeline.config import preset
from robustrtk.pipeline.stream import StreamSolver, epoch_glonass_channels, glonass_channel_of


@pytest.mark.parametrize("sig", ["1C", "1P", "2C", "2P"])
def test_channel_from_wavelength_round_trips(sig: str) -> None:
    for ch in range(-7, 7):
        assert glonass_channel_of(sig, wavelength_m("R", sig, ch)) == ch
    # not a GLONASS FDMA wavelength: the GPS L1 one, a CDMA band, unknown
    assert glonass_channel_of(sig, wavelength_m("G", "1C")) is None
    assert glonass_channel_of("4A", 0.2) is None
    assert glonass_channel_of(sig, math.nan) is None


def _epoch(tx: tuple[str, ...], wl: list[float], phase: list[float] | None = None) -> ObsEpoch:
    n = len(tx)
    ph = np.asarray(phase if phase is not None else [1.0e8] * n, float)[:, None]
    return ObsEpoch(
        t_s=1.0e9, tx_ids=tx, system=tuple(t[0] for t in tx), signals=("1C",),
        code_m=np.full((n, 1), 2.0e7), phase_cyc=ph, doppler_hz=np.full((n, 1), np.nan),
        cn0_dbhz=np.full((n, 1), 40.0), lli=np.zeros((n, 1), np.int8), wavelength_m=np.asarray(wl)[:, None],
    )  # fmt: skip


def test_epoch_channels_and_rows_without_a_channel() -> None:
    lam_g = wavelength_m("G", "1C")
    ep = _epoch(("G01", "R03", "R09"), [lam_g, wavelength_m("R", "1C", -4), math.nan])
    assert epoch_glonass_channels(ep) == {"R03": -4}
    cfg = preset("rtk").updated(freqs="L1").validate("rtk")
    solver = StreamSolver(cfg, np.zeros(3), spp_fallback=False)
    assert solver.systems is not None and "R" in solver.systems  # GLONASS by default
    rows = solver.rover_front(ep).epoch
    i9 = rows.tx_ids.index("R09:L1")
    assert np.isnan(rows.wavelength_m[i9, 0])  # no channel yet: no wavelength, no phase row
    # the base's epochs tell R09's channel: the rover's rows get it from then on
    solver.on_base(_epoch(("R09",), [wavelength_m("R", "1C", 2)]))
    assert solver.glo_channels["R09"] == 2
    rows = solver.rover_front(ep).epoch
    assert rows.wavelength_m[rows.tx_ids.index("R09:L1"), 0] == pytest.approx(wavelength_m("R", "1C", 2))
    # an epoch's own wavelength is kept (the channel the receiver decoded)
    assert rows.wavelength_m[rows.tx_ids.index("R03:L1"), 0] == wavelength_m("R", "1C", -4)


def test_channels_from_ephemerides() -> None:
    from robustrtk.io.raw_collect import GLO_FIELDS, NavCollector

    nav = NavCollector()
    rec: dict[str, object] = dict.fromkeys(GLO_FIELDS, 0.0)
    rec.update(sat_id="R11", freq_channel=5, pos_m=[2.0e7, 0.0, 0.0], vel_m_s=[0.0] * 3, acc_m_s2=[0.0] * 3)
    nav.add_glonass(rec)
    cfg = preset("rtk").updated(freqs="L1").validate("rtk")
    solver = StreamSolver(cfg, np.zeros(3), spp_fallback=False)
    ep = _epoch(("R11",), [math.nan])
    assert np.isnan(solver.rover_front(ep).epoch.wavelength_m[0, 0])
    solver.on_nav(nav.nav_data())
    assert solver.glo_channels == {"R11": 5}
    assert solver.rover_front(ep).epoch.wavelength_m[0, 0] == pytest.approx(wavelength_m("R", "1C", 5))
    # the GPS-only systems leave GLONASS rows out altogether
    solver = StreamSolver(cfg.updated(systems="GECJ").validate("rtk"), np.zeros(3), spp_fallback=False)
    assert solver.rover_front(ep).epoch.tx_ids == ()


@pytest.mark.parametrize(
    ("mode", "rover", "base", "want"),
    [
        ("auto", "", "", "off"),
        ("auto", "u-blox", "", "off"),  # one make unknown: float
        ("auto", "u-blox", "UBLOX NEO-M8P", "on"),
        ("auto", "u-blox", "LEICA GR30", "off"),
        ("on", "", "", "on"),
        ("off", "u-blox", "u-blox", "off"),
    ],
)
def test_glonass_ar_auto_follows_the_receiver_makes(mode: str, rover: str, base: str, want: str) -> None:
    cfg = preset("rtk").updated(freqs="L1", glonass_ar=mode).validate("rtk")
    solver = StreamSolver(cfg, np.zeros(3), spp_fallback=False)
    solver.set_receiver_type("rover", rover)
    solver.set_receiver_type("base", base)
    assert solver.glonass_ar == want
    with pytest.raises(ValueError):
        solver.set_receiver_type("peer", "u-blox")


@pytest.fixture(scope="module")
def part(shared_data: Path) -> dict[str, object]:
    d = shared_data / "galway_m8p_l1_lowcost" / "s1_static"
    if not d.is_dir():
        pytest.skip(f"{d} absent")
    import sys

    sys.path.insert(0, str(Path(__file__).parent))
    from test_loop_stream import galway_part

    return galway_part(d, 0.15)


def _replay(solver: StreamSolver, rover: list[ObsEpoch], base: list[ObsEpoch]) -> list[object]:
    events = sorted(
        [(e.t_s, 0, k) for k, e in enumerate(base)] + [(e.t_s, 1, k) for k, e in enumerate(rover)]
    )
    got: list[object] = []
    for _, kind, k in events:
        got += solver.on_base(base[k]) if kind == 0 else solver.on_rover(rover[k])
    return got + solver.flush()


def test_same_make_stream_fixes_glonass_as_the_file_solve(part: dict[str, object]) -> None:
    """Both receivers told u-blox (a UBX rover, a base whose 1033 says so): the stream fixes
    GLONASS ambiguities and gives the file solve's solutions with ``glonass_ar = on``."""
    from robustrtk.pipeline.rtk_gnss import solve_rtk

    rover, base, nav, arp = part["rover"], part["base"], part["nav"], part["arp"]
    assert isinstance(rover, list) and isinstance(base, list)
    cfg = preset("rtk").updated(freqs="L1", code_sigma_from_data=False).validate("rtk")
    solver = StreamSolver(cfg, arp, nav, spp_fallback=False)
    solver.set_receiver_type("rover", "u-blox")
    solver.set_receiver_type("base", "u-blox")
    got = _replay(solver, rover, base)
    assert solver.loop is not None and solver.loop.engine.rtk is not None
    assert solver.loop.engine.rtk.cfg.gnss.glonass_ar == "on"
    want = solve_rtk(part["rover_file"], part["base_file"], nav, arp, cfg.updated(glonass_ar="on")).solutions
    assert len(got) == len(want) > 100
    assert [s.status for s in got] == [s.status for s in want]  # type: ignore[attr-defined]
    assert {"fixed", "partial"} & {s.status for s in got}  # type: ignore[attr-defined]
    d = np.array([s.pos_m for s in got]) - np.array([s.pos_m for s in want])  # type: ignore[attr-defined]
    assert np.max(np.abs(d)) < 1e-5
    # a make told after the start reaches the running engine
    solver.set_receiver_type("base", "LEICA GR30")
    assert solver.loop.engine.rtk.cfg.gnss.glonass_ar == "off"


def test_base_fill_equals_the_file_fill(part: dict[str, object]) -> None:
    """The galway base's RTCM 3 link loses whole MSM messages: epochs with GLONASS only. The
    stream completes them epoch by epoch as the file solve's SystemFill does over the file."""
    from robustrtk.geometry.ephemeris import EphemerisSource
    from robustrtk.measurement.base_propagation import SystemFill
    from robustrtk.measurement.signals import RowSource, signal_rows
    from robustrtk.pipeline.stream import BaseSystemFill

    base, nav, arp = part["base"], part["nav"], part["arp"]
    assert isinstance(base, list)
    src = RowSource(EphemerisSource(nav))  # type: ignore[arg-type]
    batch = signal_rows(part["base_file"], ("L1",), "GRECJ")  # type: ignore[arg-type]
    file_fill = SystemFill(batch, src, arp, 30.0, sagnac=True, troposphere=True)  # type: ignore[arg-type]
    stream_fill = BaseSystemFill(30.0)
    cfg = preset("rtk").updated(freqs="L1").validate("rtk")
    front = StreamSolver(cfg, arp, nav).base_front  # type: ignore[arg-type]
    t_file = np.asarray(batch.t_s, float)
    n_filled = 0
    for ep in base:
        rows = front(ep).epoch
        got = stream_fill(rows, src, arp)  # type: ignore[arg-type]
        j = int(np.argmin(np.abs(t_file - ep.t_s)))
        assert abs(t_file[j] - ep.t_s) < 1e-6
        want = file_fill.epoch(j)
        have = np.isfinite(want.phase_cyc[:, 0])
        assert set(got.tx_ids) == {t for t, h in zip(want.tx_ids, have, strict=True) if h}
        idx = [want.tx_ids.index(t) for t in got.tx_ids]
        np.testing.assert_allclose(got.phase_cyc[:, 0], want.phase_cyc[idx, 0], rtol=0, atol=1e-6)
        np.testing.assert_allclose(got.code_m[:, 0], want.code_m[idx, 0], rtol=0, atol=1e-6)
        np.testing.assert_array_equal(got.lli[:, 0], want.lli[idx, 0])
        n_filled += len(got.tx_ids) > len(rows.tx_ids)
    assert n_filled >= 5  # the link did lose messages in these minutes


def test_base_fill_leaves_rare_and_stale_systems(part: dict[str, object]) -> None:
    from robustrtk.geometry.ephemeris import EphemerisSource
    from robustrtk.measurement.signals import RowSource
    from robustrtk.pipeline.stream import BaseSystemFill

    base, nav, arp = part["base"], part["nav"], part["arp"]
    assert isinstance(base, list)
    src = RowSource(EphemerisSource(nav))  # type: ignore[arg-type]
    cfg = preset("rtk").updated(freqs="L1").validate("rtk")
    front = StreamSolver(cfg, arp, nav).base_front  # type: ignore[arg-type]
    full = [front(e).epoch for e in base]
    full = [e for e in full if {"G", "R"} <= set(e.system)]
    r_only = [replace(e, **_only(e, "R")) for e in full]
    fill = BaseSystemFill(30.0)
    fill(full[0], src, arp)  # type: ignore[arg-type]
    t0 = full[0].t_s
    got = fill(r_only[1], src, arp)  # type: ignore[arg-type]
    assert {"G", "R"} <= set(got.system)  # a regular system, 1 s old: filled
    stale = next(e for e in r_only if e.t_s - t0 > 31.0)
    fill2 = BaseSystemFill(30.0)
    fill2(full[0], src, arp)  # type: ignore[arg-type]
    assert set(fill2(stale, src, arp).system) == {"R"}  # older than max_age_s
    fill3 = BaseSystemFill(30.0)
    fill3(full[0], src, arp)  # type: ignore[arg-type]
    for e in r_only[1:4]:
        out = fill3(e, src, arp)  # type: ignore[arg-type]
    assert set(out.system) == {"R"}  # GPS in 1 of 4 epochs: not regular, not filled


def _only(ep: ObsEpoch, system: str) -> dict[str, object]:
    keep = np.array([s == system for s in ep.system])
    out: dict[str, object] = {
        "tx_ids": tuple(t for t, k in zip(ep.tx_ids, keep, strict=True) if k),
        "system": tuple(s for s in ep.system if s == system),
    }
    for f in ("code_m", "phase_cyc", "doppler_hz", "cn0_dbhz", "lli", "wavelength_m"):
        out[f] = np.asarray(getattr(ep, f))[keep]
    for f in ("code_sigma_m", "phase_sigma_cyc"):
        v = getattr(ep, f)
        out[f] = None if v is None else np.asarray(v)[keep]
    return out


def test_msm4_glonass_phase_takes_a_channel_told_elsewhere() -> None:
    """RTCM 3 MSM4 gives the GLONASS phase in metres: in cycles only with the satellite's
    channel, which a navigation file or another stream's decoder may know (shared dict)."""
    import sys

    sys.path.insert(0, str(Path(__file__).parents[1] / "io"))
    from test_raw_frames import msm4

    from robustrtk.core import CLIGHT
    from robustrtk.io.epoch_source import StreamDecoder

    t_ref = 2021 * 604800.0 + 2 * 86400.0
    frame = msm4(1084, 3_600_000, {1: (70, 1)})  # R01, GLONASS time of day 1 h

    def first_epoch(dec: StreamDecoder) -> ObsEpoch:
        return next(e for e in [*dec.feed(frame), *dec.close()] if isinstance(e, ObsEpoch))

    alone = first_epoch(StreamDecoder(t_ref_s=t_ref))
    assert alone.tx_ids == ("R01",) and np.isnan(alone.phase_cyc[0, 0])  # no channel: no phase
    assert np.isfinite(alone.code_m[0, 0])
    shared = {"R01": 3}
    ep = first_epoch(StreamDecoder(t_ref_s=t_ref, glo_channels=shared))
    lam = wavelength_m("R", "1C", 3)
    phase_range_m = (70 + 1 / 1024 - 2000 * 2.0**-29) * CLIGHT / 1000
    assert ep.phase_cyc[0, 0] == pytest.approx(phase_range_m / lam, abs=1e-6)
    assert ep.wavelength_m[0, 0] == lam
    assert epoch_glonass_channels(ep) == {"R01": 3}
