"""The one epoch loop: the base events it hands on, the file solve through it, and the
stream solver against the file solve on the same epochs."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk.core import ObsEpoch
from robustrtk.pipeline.base_buffer import BaseEvents
from robustrtk.pipeline.loop import EpochLoop, EventLog


@settings(max_examples=100, deadline=None)
@given(
    flags=st.lists(st.lists(st.booleans(), min_size=3, max_size=3), min_size=1, max_size=12),
    asks=st.lists(st.integers(0, 11), min_size=1, max_size=12),
)
def test_event_log_equals_base_events(flags: list[list[bool]], asks: list[int]) -> None:
    arr = np.array(flags, bool)
    ids = ("G01:L1", "G02:L1", "E11:L1")
    ref = BaseEvents(arr)
    log = EventLog()
    for k, f in enumerate(arr):
        log.push(k, ids, f)
    for j in sorted(a for a in asks if a < len(arr)):  # rover order: base indices do not decrease
        np.testing.assert_array_equal(log.since_last(j, ids, (3,)), ref.since_last(j))


def test_event_log_maps_rows_by_name() -> None:
    log = EventLog()
    log.push(0, ("G01:L1", "G02:L1"), np.array([True, False]))
    log.push(1, ("G02:L1", "G03:L1"), np.array([True, False]))
    log.since_last(0, ("G01:L1",), (1,))
    out = log.since_last(1, ("G03:L1", "G02:L1", "G01:L1"), (3,))
    np.testing.assert_array_equal(out, [False, True, False])  # G01's event went with epoch 0


@pytest.fixture(scope="module")
def s1(shared_data: Path) -> Path:
    d = shared_data / "galway_m8p_l1_lowcost" / "s1_static"
    if not d.is_dir():
        pytest.skip(f"{d} absent")
    return d


def galway_part(s1: Path, fraction: float) -> dict[str, object]:
    """The first ``fraction`` of the rover's and the base's bytes: their epochs decoded as
    streams and as files; nav; the base's ARP."""
    from robustrtk.io.epoch_source import StreamDecoder, stream_events
    from robustrtk.io.raw_file import read_binary_log
    from robustrtk.io.rinex_nav import read_rinex_nav
    from robustrtk.io.rtcm3 import read_rtcm3, reference_time_s
    from robustrtk.io.ubx import read_ubx

    r, _ = read_binary_log(s1 / "rover-20181004-1237.ubx.gz")
    b, _ = read_binary_log(s1 / "base-20181004-1236.rtcm3")
    t_ref = reference_time_s(str(s1 / "base-20181004-1236.rtcm3"), b)
    r, b = r[: int(len(r) * fraction)], b[: int(len(b) * fraction)]
    bdec = StreamDecoder(t_ref_s=t_ref)
    base = [e for e in stream_events([b[k : k + 4096] for k in range(0, len(b), 4096)], bdec)]
    rover = [e for e in stream_events([r[k : k + 4096] for k in range(0, len(r), 4096)], StreamDecoder())]
    return {
        "rover": [e for e in rover if isinstance(e, ObsEpoch)],
        "base": [e for e in base if isinstance(e, ObsEpoch)],
        "rover_file": read_ubx(s1 / "r.ubx", data=r)[0],
        "base_file": read_rtcm3(s1 / "b.rtcm3", t_ref_s=t_ref, data=b)[0],
        "nav": read_rinex_nav(s1 / "rover-20181004-1237.nav"),
        "arp": np.asarray(bdec.station["arp_ecef_m"]),
    }


@pytest.mark.parametrize(("mode", "systems"), [("rtk", None), ("rtk", "GECJ"), ("dgnss", None)])
def test_stream_solver_gives_the_file_solution(
    s1: Path, mode: str, systems: str | None, monkeypatch: pytest.MonkeyPatch
) -> None:
    from robustrtk.pipeline.config import preset
    from robustrtk.pipeline.gnss import solve_dgnss
    from robustrtk.pipeline.rtk_gnss import solve_rtk
    from robustrtk.pipeline.stream import StreamSolver

    part = galway_part(s1, 0.15)  # ≈ 190 s of the base, 140 s of the rover
    rover, base, nav, arp = part["rover"], part["base"], part["nav"], part["arp"]
    assert isinstance(rover, list) and isinstance(base, list) and len(rover) > 100
    # default systems: GLONASS carrier phase too (FDMA; float here: the RTCM 3 base has no 1033)
    cfg = preset(mode).updated(freqs="L1", code_sigma_from_data=False, systems=systems).validate(mode)
    solver = StreamSolver(cfg, arp, nav, spp_fallback=False)  # unpaired epochs: none, as the file
    events = sorted(
        [(e.t_s, 0, k) for k, e in enumerate(base)] + [(e.t_s, 1, k) for k, e in enumerate(rover)]
    )
    got = []
    for _, kind, k in events:
        got += solver.on_base(base[k]) if kind == 0 else solver.on_rover(rover[k])
    got += solver.flush()
    # the file solve runs its epochs through the same loop
    steps = []
    solve = EpochLoop.solve

    def counted(self: EpochLoop, *a: object) -> object:
        steps.append(1)
        return solve(self, *a)  # type: ignore[arg-type]

    monkeypatch.setattr(EpochLoop, "solve", counted)
    fn = solve_rtk if mode == "rtk" else solve_dgnss
    rb, bb = part["rover_file"], part["base_file"]
    want = fn(rb, bb, nav, arp, cfg).solutions
    assert len(steps) == len(want) == len(got) > 100
    assert [s.status for s in got] == [s.status for s in want]
    assert {s.status for s in got} & ({"fixed", "float"} if mode == "rtk" else {"dgnss"})
    pos_got = np.array([s.pos_m for s in got])
    pos_want = np.array([s.pos_m for s in want])
    # the same arithmetic up to the order of rows (the stream's epochs hold only the
    # satellites they observed): differences far below a millimetre
    assert np.max(np.abs(pos_got - pos_want)) < 1e-5
    np.testing.assert_array_equal([s.age_s for s in got], [s.age_s for s in want])
