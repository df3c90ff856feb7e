"""The Kalman SPP one epoch at a time (:class:`KalmanSppStream`, :class:`SppStreamSolver`) is
the file's (:func:`solve_spp_kalman`):

* the Pixel 5 drive (GPS L1 + L5, carrier phase, Doppler) given epoch by epoch: every
  epoch's status, rows used and position as the file solve's (to 0.1 mm; measured 4e-7 m
  over the whole drive: the stream's state also carries the clocks of systems it never
  sees, which changes the order of a few sums, nothing else);
* the galway s1 rover's UBX bytes decoded as a socket delivers them (4 KiB at a time), with
  the RINEX navigation file: the same;
* with the stream's own ephemerides instead: no solution before the first ephemerides
  arrive, every epoch solved after that, and the solution pulled towards the file solve's
  once the broadcast ionosphere (Klobuchar, sent every 12.5 min) arrives: the stream
  cannot use what it has not received (inherent, bounded below).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from robustrtk.core import InputError, ObsEpoch
from robustrtk.io.epoch_source import StreamDecoder, epoch_batch
from robustrtk.io.raw_file import read_binary_log
from robustrtk.pipeline.config import preset
from robustrtk.pipeline.gnss import load_obs, nav_source
from robustrtk.pipeline.spp_common import SppEpoch
from robustrtk.pipeline.spp_kalman import solve_spp_kalman
from robustrtk.pipeline.spp_kalman_stream import KalmanSppStream, SppStreamSolver, stream_config_error
from robustrtk.pipeline.spp_signals import spp_columns

KALMAN = preset("spp").updated(filter="ekf")
ROVER, NAV = "rover-20181004-1237.ubx.gz", "rover-20181004-1237.nav"


def ubx_events(path: Path, chunk: int = 4096) -> list[object]:
    """The events of a UBX log fed to the stream decoder ``chunk`` bytes at a time."""
    data, _ = read_binary_log(path)
    dec = StreamDecoder()
    out: list[object] = []
    for lo in range(0, len(data), chunk):
        out += dec.feed(data[lo : lo + chunk])
    return out + dec.close()


def assert_same(got: list[SppEpoch], want: list[SppEpoch], tol_m: float = 1e-4) -> None:
    assert len(got) == len(want)
    assert [g.t_s for g in got] == [w.t_s for w in want]
    assert [g.status for g in got] == [w.status for w in want]
    assert [g.n_used for g in got] == [w.n_used for w in want]
    solved = [w.status == "single" for w in want]
    assert sum(solved) > 0.9 * len(want)
    pairs = zip(got, want, solved, strict=True)
    d = [float(np.linalg.norm(g.pos_ecef_m - w.pos_ecef_m)) for g, w, s in pairs if s]
    assert max(d) <= tol_m


def test_phone_epochs_one_at_a_time_are_the_file_solution(pixel5_drive: Path) -> None:
    batch = load_obs(pixel5_drive / "Pixel5_GnssLog.21o", None).select_epochs(np.arange(300))
    eph = nav_source([pixel5_drive / "hour1180.21n"])
    want = solve_spp_kalman(batch, eph, KALMAN)
    stream = KalmanSppStream(KALMAN, eph)
    got = [stream.step(batch.epoch(i)) for i in range(len(batch))]
    assert_same(got, want)
    # band 2 used: the signal kept per system and band is the file's choice
    assert stream.chosen[("G", 0)] == "1C" and stream.chosen[("G", 1)] == "5X"


def test_replayed_ubx_bytes_are_the_file_solution(galway_s1: Path) -> None:
    eph = nav_source([galway_s1 / NAV])
    batch = load_obs(galway_s1 / ROVER, None).select_epochs(np.arange(300))
    want = solve_spp_kalman(batch, eph, KALMAN)
    stream = KalmanSppStream(KALMAN, eph)
    epochs = [e for e in ubx_events(galway_s1 / ROVER) if isinstance(e, ObsEpoch)][:300]
    assert_same([stream.step(e) for e in epochs], want)


@pytest.mark.slow
def test_own_ephemerides_solve_from_their_arrival_and_join_the_file_solution(galway_s1: Path) -> None:
    events = ubx_events(galway_s1 / ROVER)
    solver = SppStreamSolver(KALMAN)
    got: dict[float, np.ndarray] = {}
    first_nav = iono_at = None
    n = 0
    for ev in events:
        if isinstance(ev, ObsEpoch):
            for sol in solver.on_rover(ev):
                got[sol.t_s] = sol.pos_m
            n += 1
            continue
        solver.on_nav(ev)  # type: ignore[arg-type]
        first_nav = n if first_nav is None else first_nav
        if iono_at is None and getattr(ev, "ion_gps_alpha", None) is not None:
            iono_at = n
    assert first_nav is not None and first_nav > 0 and iono_at is not None and iono_at > first_nav
    epochs = [e for e in events if isinstance(e, ObsEpoch)]
    t = [float(e.t_s) for e in epochs]
    # nothing before the first ephemerides; everything from the first epoch they serve
    assert not any(tt < t[first_nav] for tt in got)
    start = min(got)
    assert all(tt in got for tt in t if tt >= start)
    want = {
        e.t_s: e.pos_ecef_m
        for e in solve_spp_kalman(load_obs(galway_s1 / ROVER, None), nav_source([galway_s1 / ROVER]), KALMAN)
        if e.status == "single"
    }
    d = np.array([np.linalg.norm(got[tt] - want[tt]) for tt in t[iono_at:]])
    # the bias of the epochs without ionosphere fades once it is known (measured: 4.3 m
    # when it arrives, 3.1 m 86 s later)
    assert d[-1] < 0.8 * d[0]
    assert d.max() < 10.0


def test_a_kept_signal_is_taken_or_none_never_another(pixel5_drive: Path) -> None:
    batch = load_obs(pixel5_drive / "Pixel5_GnssLog.21o", None).select_epochs(np.arange(1))
    nav = nav_source([pixel5_drive / "hour1180.21n"]).nav
    one = epoch_batch(batch.epoch(0))
    assert spp_columns(one, nav, True) == {"G": (0, 1)}
    assert spp_columns(one, nav, True, fixed={("G", 1): "7Q"}) == {"G": (0, -1)}
    assert spp_columns(one, nav, False) == {"G": (0, -1)}


@pytest.mark.parametrize(
    ("overrides", "word"),
    [
        ({"filter": "lsq"}, "filter"),
        ({"smoother": True}, "smoother"),
        ({"fgo": True}, "fgo"),
        ({"code_bias": True}, "code_bias_sigma_m"),
    ],
)
def test_what_needs_the_whole_record_is_refused(overrides: dict[str, object], word: str) -> None:
    cfg = KALMAN.updated(**overrides)
    why = stream_config_error(cfg)
    assert why is not None and why.startswith(word + ":")
    with pytest.raises(InputError, match=word):
        KalmanSppStream(cfg)
    given = KALMAN.updated(code_bias=True, code_bias_sigma_m=1.0, code_bias_tau_s=60.0)
    assert stream_config_error(given) is None
