"""The time window of a GNSS solve: ``time_start``, ``time_end`` and ``interval_s``
(RTKLIB's ``-ts``/``-te``/``-ti``), the instant parser behind them, and the command line."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st

from robustrtk.cli.main import main
from robustrtk.errors import InputError
from robustrtk.pipeline.config import Config, GnssConfig
from robustrtk.pipeline.gnss_inputs import EPOCH_TOL_S, time_window_mask
from robustrtk.timeutil import WEEK_S, gpst_from_calendar, is_time_of_day, parse_gpst_instant

DAY0 = gpst_from_calendar(2005, 4, 2)  # the geonet dataset's date


def _grid(start_s: float, n: int, step_s: float, jitter_s: float = 0.0) -> np.ndarray:
    return start_s + step_s * np.arange(n) + jitter_s


def test_instant_forms_agree() -> None:
    t = gpst_from_calendar(2005, 4, 2, 0, 30, 0.0)
    assert parse_gpst_instant("2005/04/02 00:30:00", 0.0, "x") == t
    assert parse_gpst_instant("2005-04-02T00:30:00", 0.0, "x") == t
    assert parse_gpst_instant("00:30:00", DAY0 + 5.0, "x") == t  # on the reference's date
    assert parse_gpst_instant(f"{t:.3f}", 0.0, "x") == t
    assert parse_gpst_instant("00:30:00.5", DAY0, "x") == t + 0.5
    assert is_time_of_day(" 00:30:00 ") and not is_time_of_day("2005/04/02 00:30:00")
    # one digit in a field, as RTKLIB's -ts/-te take them
    assert parse_gpst_instant("2005/4/2 0:30:0", 0.0, "x") == t
    assert parse_gpst_instant("0:30:0.5", DAY0, "x") == t + 0.5
    assert parse_gpst_instant("2005/04/02 00:30:05", 0.0, "x") == parse_gpst_instant(
        "2005/4/2 0:30:5", 0.0, "x"
    )


@pytest.mark.parametrize(
    "bad",
    ["25:00:00", "00:60:00", "00:00:60", "2005/13/01 00:00:00", "noon", "", "00:300:00", "0:0:", "00:00"],
)
def test_instant_errors_name_the_setting(bad: str) -> None:
    with pytest.raises(InputError, match="^time_start: "):
        parse_gpst_instant(bad, DAY0, "time_start")


def test_no_window_keeps_every_epoch() -> None:
    t = _grid(DAY0, 10, 30.0, 0.003)
    assert time_window_mask(t, GnssConfig()).all()


def test_bounds_are_inclusive_within_the_tolerance() -> None:
    t = _grid(DAY0, 121, 30.0, 0.004)  # tags 4 ms late, as a receiver clock leaves them
    g = GnssConfig(time_start="00:30:00", time_end="2005/04/02 00:40:00")
    keep = time_window_mask(t, g)
    assert keep.sum() == 21
    assert t[keep][0] == pytest.approx(DAY0 + 1800.004) and t[keep][-1] == pytest.approx(DAY0 + 2400.004)
    # one epoch just outside the tolerance is left out
    late = t + 2 * EPOCH_TOL_S
    assert time_window_mask(late, g).sum() == 20


def test_time_of_day_end_before_start_crosses_midnight() -> None:
    t = _grid(DAY0 + 86_400.0 - 600.0, 41, 30.0)  # 23:50 to 00:10 of the next day
    keep = time_window_mask(t, GnssConfig(time_start="23:55:00", time_end="00:05:00"))
    assert keep.sum() == 21
    assert t[keep][0] == DAY0 + 86_400.0 - 300.0 and t[keep][-1] == DAY0 + 86_400.0 + 300.0


def test_time_of_day_end_follows_a_calendar_start() -> None:
    """Three days of epochs: an end given as a time of day falls on the start's date (not the
    first epoch's), so the window is the same whether the reader cut the file or not."""
    t = _grid(DAY0, 3 * 24 * 120, 30.0)
    g = GnssConfig(time_start="2005/04/04 01:00:00", time_end="02:00:00")
    keep = time_window_mask(t, g)
    assert t[keep][0] == DAY0 + 2 * 86_400.0 + 3600.0 and t[keep][-1] == DAY0 + 2 * 86_400.0 + 7200.0
    np.testing.assert_array_equal(time_window_mask(t[keep], g), np.ones(int(keep.sum()), bool))


def test_calendar_end_before_start_is_an_error() -> None:
    g = GnssConfig(time_start="2005/04/02 00:40:00", time_end="2005/04/02 00:30:00")
    with pytest.raises(InputError, match="^time_end: .* is before time_start"):
        time_window_mask(_grid(DAY0, 10, 30.0), g)


def test_empty_window_names_the_span() -> None:
    with pytest.raises(
        InputError, match=r"no rover epoch selected; the rover epochs span 2005/04/02 00:00:00"
    ):
        time_window_mask(_grid(DAY0, 10, 30.0), GnssConfig(time_start="02:00:00"))


@settings(max_examples=60, deadline=None)
@given(
    step=st.sampled_from([0.2, 0.5, 1.0, 5.0, 15.0, 30.0]),
    mult=st.integers(1, 12),
    n=st.integers(1, 400),
    jitter=st.floats(-0.02, 0.02),
    week=st.integers(1000, 2400),
    tow0=st.integers(0, 590_000),  # the epochs stay in one GPS week
)
def test_interval_keeps_exactly_the_grid(
    step: float, mult: int, n: int, jitter: float, week: int, tow0: int
) -> None:
    """Kept ⇔ the epoch's time of week is within the tolerance of a multiple of the interval
    (brute force over the same epochs)."""
    interval = step * mult
    t = _grid(week * WEEK_S + tow0, n, step, jitter)
    tow = t - week * WEEK_S
    want = np.abs(tow - interval * np.round(tow / interval)) <= EPOCH_TOL_S
    if not want.any():  # the window keeps nothing: refused, not an empty solve
        with pytest.raises(InputError, match="no rover epoch selected"):
            time_window_mask(t, GnssConfig(interval_s=interval))
        return
    assert np.array_equal(time_window_mask(t, GnssConfig(interval_s=interval)), want)


def test_interval_refuses_a_window_with_no_grid_epoch() -> None:
    with pytest.raises(InputError, match="interval_s 7: no rover epoch selected"):
        time_window_mask(_grid(DAY0 + 1.0, 3, 1.0), GnssConfig(interval_s=7.0))


def test_config_validates_the_window() -> None:
    with pytest.raises(InputError, match="time_end: expected 'yyyy/mm/dd hh:mm:ss'"):
        Config().updated(time_end="soon").validate()
    with pytest.raises(InputError, match="interval_s: expected a finite number >= 0"):
        Config().updated(interval_s=-1.0).validate()
    cfg = Config().updated(time_start="00:30:00", interval_s=60.0).validate()
    assert cfg.gnss.time_start == "00:30:00" and cfg.gnss.interval_s == 60.0


def _geonet_args(d: Path, out: Path, mode: str) -> list[str]:
    return [
        "solve",
        str(d / "07590920.05o"),
        "--base",
        str(d / "30400920.05o"),
        "--nav",
        str(d / "07590920.05n"),
        "--mode",
        mode,
        "--base-pos=-3978241.958,3382840.234,3649900.853",
        "--out",
        str(out),
        "--quiet",
    ]


def test_cli_rtk_window_on_real_data(shared_data: Path, tmp_path: Path) -> None:
    from robustrtk.io.solution import read_pos

    d = shared_data / "geonet_0759_3040_static_3km"
    out = tmp_path / "w.pos"
    args = _geonet_args(d, out, "rtk") + ["--time-start", "00:30:00", "--time-end", "2005/04/02 00:40:00"]
    r = CliRunner().invoke(main, args)
    assert r.exit_code == 0, r.output
    sol = read_pos(out)
    lo, hi = DAY0 + 1800.0, DAY0 + 2400.0
    assert len(sol.t_s) == 21  # 30 s epochs, both bounds kept
    assert np.all((sol.t_s >= lo - EPOCH_TOL_S) & (sol.t_s <= hi + EPOCH_TOL_S))
    truth = np.array([-3976219.1879, 3382371.6056, 3652511.1425])
    assert np.percentile(np.linalg.norm(sol.pos_m - truth, axis=1), 50) < 1.0


def test_cli_interval_and_empty_window(shared_data: Path, tmp_path: Path) -> None:
    from robustrtk.io.solution import read_pos

    d = shared_data / "geonet_0759_3040_static_3km"
    out = tmp_path / "i.pos"
    r = CliRunner().invoke(main, _geonet_args(d, out, "dgnss") + ["--interval-s", "60"])
    assert r.exit_code == 0, r.output
    sol = read_pos(out)
    assert len(sol.t_s) == 60
    assert np.all(np.abs(sol.t_s - 60.0 * np.round(sol.t_s / 60.0)) <= EPOCH_TOL_S)
    gone = tmp_path / "none.pos"
    r = CliRunner().invoke(main, _geonet_args(d, gone, "dgnss") + ["--time-start", "02:00:00"])
    assert r.exit_code == 2
    lines = [ln for ln in r.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and "no rover epoch selected" in lines[0] and "Traceback" not in r.output
    assert not gone.exists()


def test_window_refused_for_pseudolite_tables(tmp_path: Path) -> None:
    obs = tmp_path / "obs.csv"
    r = CliRunner().invoke(
        main, ["simulate", "demo", "--seed", "1", "--out", str(tmp_path), "--epochs", "20"]
    )
    assert r.exit_code == 0, r.output
    r = CliRunner().invoke(
        main,
        ["solve", str(obs), "--site", str(tmp_path / "site.toml"), "--out", str(tmp_path / "s.csv")]
        + ["--time-start", "00:00:10"],
    )
    assert r.exit_code == 2 and "--time-start" in r.output


def test_the_reader_decodes_only_the_window_and_matches_the_full_read(shared_data: Path) -> None:
    """The window goes to the RINEX reader (bounds, times of day and the interval alike);
    the batch equals the full read cut after, on the transmitters the window sees."""
    from robustrtk.pipeline.gnss_inputs import load_obs, select_time_window

    path = shared_data / "geonet_0759_3040_static_3km" / "07590920.05o"
    whole = load_obs(path, None)
    for g in (
        GnssConfig(time_start="2005/04/02 00:30:00", time_end="2005/04/02 00:40:00", interval_s=60.0),
        GnssConfig(time_start="00:30:00", time_end="00:40:00", interval_s=60.0),
        GnssConfig(time_end="00:05:00"),
    ):
        part = load_obs(path, None, g)
        full = select_time_window(whole, g)
        assert len(part) == len(full) < len(whole)
        assert np.array_equal(part.t_s, full.t_s) and part.signals == full.signals
        # the transmitter axis is the union over the epochs read: those seen in the window
        seen = [i for i in range(len(full.tx_ids)) if np.isfinite(full.code_m[:, i]).any()]
        assert part.tx_ids == tuple(full.tx_ids[i] for i in seen)
        for a, b in ((part.code_m, full.code_m), (part.phase_cyc, full.phase_cyc), (part.lli, full.lli)):
            np.testing.assert_array_equal(a, b[:, seen])
    assert len(load_obs(path, None, GnssConfig(interval_s=60.0))) == 60
    # a window outside the file: the reader's error gives the file's span
    far = GnssConfig(time_start="2006/01/01 00:00:00")
    with pytest.raises(InputError, match="the rover epochs span 2005/04/02 00:00:00"):
        load_obs(path, None, far)
    with pytest.raises(InputError, match="no base epoch selected"):
        load_obs(path, None, far, what="base")


def test_cli_calendar_and_time_of_day_windows_give_the_same_file(shared_data: Path, tmp_path: Path) -> None:
    """A window given as calendar times and as times of day solves the same epochs to the
    same bytes."""
    d = shared_data / "geonet_0759_3040_static_3km"
    a, b = tmp_path / "a.pos", tmp_path / "b.pos"
    r = CliRunner().invoke(main, _geonet_args(d, a, "rtk") + ["--time-start", "00:20:00"])
    assert r.exit_code == 0, r.output
    r = CliRunner().invoke(main, _geonet_args(d, b, "rtk") + ["--time-start", "2005/04/02 00:20:00"])
    assert r.exit_code == 0, r.output
    assert a.read_bytes() == b.read_bytes() and len(a.read_bytes()) > 1000


def test_base_read_over_the_rover_window_aligns_as_the_full_base(shared_data: Path) -> None:
    """The base is read over the rover's window ± BASE_MARGIN_S, and max_age_s before it (an
    older base epoch may serve the first rover epochs): the epochs matched to the rover are
    those of the full base file, value for value."""
    from robustrtk.pipeline.gnss import align_base
    from robustrtk.pipeline.gnss_inputs import BASE_MARGIN_S, base_read_bounds, load_obs, select_time_window

    d = shared_data / "geonet_0759_3040_static_3km"
    g = GnssConfig(time_start="00:20:00", time_end="00:30:00")
    rover = select_time_window(load_obs(d / "07590920.05o", None, g), g)
    bounds = base_read_bounds(rover, g)
    assert bounds == (rover.t_s[0] - max(BASE_MARGIN_S, g.max_age_s), rover.t_s[-1] + BASE_MARGIN_S)
    assert base_read_bounds(rover, GnssConfig()) is None and base_read_bounds(rover, None) is None
    part = load_obs(d / "30400920.05o", None, None, bounds)
    full = load_obs(d / "30400920.05o", None)
    assert len(rover) <= len(part) < len(full)
    a, b = align_base(rover, part), align_base(rover, full)
    cols = [full.tx_ids.index(t) for t in part.tx_ids]
    assert np.array_equal(a.t_s, b.t_s)
    np.testing.assert_array_equal(a.code_m, b.code_m[:, cols])
    np.testing.assert_array_equal(a.phase_cyc, b.phase_cyc[:, cols])
    # bounds with no base epoch: the full file, so that the later error can say why
    assert len(load_obs(d / "30400920.05o", None, None, (0.0, 1.0))) == len(full)
