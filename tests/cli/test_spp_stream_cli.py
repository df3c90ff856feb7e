"""``robustrtk solve --mode spp`` streamed against the whole-file path: the same ``.pos``
bytes, summary, warnings, errors and exit codes (:mod:`robustrtk.cli.gnss_stream`)."""

from __future__ import annotations

import functools
from dataclasses import replace
from pathlib import Path

import pytest
from click.testing import CliRunner

import robustrtk.cli.gnss_stream as gnss_stream
import robustrtk.pipeline.spp_stream as spp_stream
from robustrtk.cli.main import main
from robustrtk.io.rinex_chunks import iter_rinex_obs
from robustrtk.io.rinex_obs import read_rinex_obs
from robustrtk.pipeline.config import preset
from robustrtk.pipeline.spp_common import select_band1

RUNS = {
    "pixel5": (
        "gsdc2021_mtv1_pixel5_phone/Pixel5/supplemental/Pixel5_GnssLog.21o",
        "gsdc2021_mtv1_pixel5_phone/Pixel5/supplemental/hour1180.21n",
    ),
    "mosaicx5": ("mosaicx5_static_1m/rover.obs", "mosaicx5_static_1m/base.nav"),
    "kamakura": ("kamakura_kinematic_5km/SEPT265G.21O", "kamakura_kinematic_5km/SEPT2650.21P"),
    "galway": (
        "galway_m8p_l1_lowcost/s1_static/rover-20181004-1237.obs",
        "galway_m8p_l1_lowcost/s1_static/rover-20181004-1237.nav",
    ),
}
KAMAKURA_NAV = "kamakura_kinematic_5km/SEPT2650.21P"


def _solve(
    monkeypatch: pytest.MonkeyPatch, obs: Path, nav: Path, out: Path, chunk: int | None, *extra: str
) -> tuple[int, str, bytes | None, bool]:
    """(exit code, output with the out name and timing left out, .pos bytes, streamed):
    whole-file with ``chunk`` None, else streamed ``chunk`` epochs at a time."""
    streamed: list[bool] = []
    whole = functools.partial(spp_stream.solve_spp_to_pos, epochs_per_chunk=chunk or 1)

    def spy(*args: object, **kwargs: object) -> object:
        streamed.append(True)
        return whole(*args, **kwargs)

    with monkeypatch.context() as m:
        if chunk is None:
            m.setattr(gnss_stream, "streamable", lambda *a: False)
        m.setattr(spp_stream, "solve_spp_to_pos", spy)
        r = CliRunner().invoke(
            main, ["solve", str(obs), "--nav", str(nav), "--mode", "spp", "--out", str(out), *extra]
        )
    text = "\n".join(
        line.replace(str(out), "OUT")
        for line in r.output.splitlines()
        if not line.lstrip().startswith("time ")
    )
    return r.exit_code, text, out.read_bytes() if out.exists() else None, bool(streamed)


def _same(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, obs: Path, nav: Path, chunk: int, *extra: str
) -> tuple[int, str, bool]:
    ref = _solve(monkeypatch, obs, nav, tmp_path / "whole.pos", None, *extra)
    got = _solve(monkeypatch, obs, nav, tmp_path / "streamed.pos", chunk, *extra)
    assert not ref[3]
    assert got[:3] == ref[:3]
    return got[0], got[1], got[3]


@pytest.mark.parametrize("name", sorted(RUNS))
@pytest.mark.parametrize("chunk", [4096, 37])
def test_streamed_spp_is_the_whole_file_run(
    shared_data: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, name: str, chunk: int
) -> None:
    obs, nav = RUNS[name]
    code, text, streamed = _same(monkeypatch, tmp_path, shared_data / obs, shared_data / nav, chunk)
    assert code == 0 and streamed
    assert "epochs " in text


def _lines(path: Path) -> list[str]:
    return path.read_text().splitlines(keepends=True)


def _epoch_starts(lines: list[str]) -> list[int]:
    return [i for i, s in enumerate(lines) if s.startswith(">")]


def test_header_only_file_fails_as_the_whole_file_run(
    shared_data: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    lines = _lines(shared_data / RUNS["kamakura"][0])
    head = tmp_path / "head.obs"
    head.write_text("".join(lines[: _epoch_starts(lines)[0]]))
    code, text, _ = _same(monkeypatch, tmp_path, head, shared_data / KAMAKURA_NAV, 37)
    assert code == 2 and "no observations" in text


def test_navigation_of_another_day_fails_as_the_whole_file_run(
    shared_data: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    obs = shared_data / RUNS["kamakura"][0]
    nav = shared_data / "geonet_0759_3040_static_3km/07590920.05n"
    code, text, _ = _same(monkeypatch, tmp_path, obs, nav, 37)
    assert code == 2 and "covers none of the observation span" in text


def test_masked_values_are_said_as_by_the_whole_file_run(
    shared_data: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    lines = _lines(shared_data / RUNS["kamakura"][0])
    for k in (_epoch_starts(lines)[5] + 1, _epoch_starts(lines)[300] + 1):  # first record's first field
        lines[k] = lines[k][:3] + f"{-1234.5:14.3f}" + lines[k][17:]
    bad = tmp_path / "masked.obs"
    bad.write_text("".join(lines))
    code, text, streamed = _same(monkeypatch, tmp_path, bad, shared_data / KAMAKURA_NAV, 37)
    assert code == 0 and streamed
    assert "impossible values masked as missing (2 code_m)" in text


def test_nothing_solved_exits_3_as_the_whole_file_run(
    shared_data: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    obs = shared_data / RUNS["kamakura"][0]
    code, text, streamed = _same(
        monkeypatch, tmp_path, obs, shared_data / KAMAKURA_NAV, 37, "--elev-mask", "89"
    )
    assert code == 3 and streamed
    assert "no epoch solved of 360" in text
    assert not (tmp_path / "streamed.pos").exists()


def test_a_repeated_epoch_between_blocks_is_dropped_as_by_the_whole_file_run(
    shared_data: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    lines = _lines(shared_data / RUNS["kamakura"][0])
    st = _epoch_starts(lines)
    lines[st[37] : st[37]] = lines[st[36] : st[37]]  # epoch 36 twice: the repeat opens the second block
    dup = tmp_path / "dup.obs"
    dup.write_text("".join(lines))
    code, text, _ = _same(monkeypatch, tmp_path, dup, shared_data / KAMAKURA_NAV, 37)
    assert code == 0 and "1 epoch(s) written twice" in text


def test_a_signal_missing_from_the_first_blocks_gives_the_whole_file_choice(
    shared_data: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """GPS with two L1 codes (``C2W`` renamed ``C1W``), ``C1C`` blank in the first 50
    epochs: the first blocks would take ``C1W``; the whole file takes ``C1C`` throughout."""
    src = shared_data / "mosaicx5_static_1m/rover.obs"
    lines = _lines(src)
    lines = [s.replace(" C2W ", " C1W ") if s.startswith("G ") and "OBS TYPES" in s else s for s in lines]
    st = _epoch_starts(lines)
    for k in range(st[0], st[50]):
        if lines[k].startswith("G"):
            lines[k] = lines[k][:19] + " " * 16 + lines[k][35:]  # C1C: the second field
    two = tmp_path / "two_l1.obs"
    two.write_text("".join(lines))
    code, _, streamed = _same(monkeypatch, tmp_path, two, shared_data / "mosaicx5_static_1m/base.nav", 20)
    assert code == 0 and streamed
    first = next(iter_rinex_obs(two, epochs_per_chunk=20))
    assert select_band1(first).meta["signal_by_system"]["G"] == "1W"
    assert select_band1(read_rinex_obs(two)).meta["signal_by_system"]["G"] == "1C"


def test_streamable_refuses_what_the_stream_cannot_give(shared_data: Path, tmp_path: Path) -> None:
    obs = str(shared_data / RUNS["kamakura"][0])
    cfg = preset("spp")
    assert gnss_stream.streamable(obs, cfg, "pos", None)
    assert not gnss_stream.streamable(obs, cfg, "csv", None)
    assert not gnss_stream.streamable(obs, cfg, "pos", "d.csv")
    assert not gnss_stream.streamable(
        str(shared_data / "geonet_0759_3040_static_3km/07590920.05o"), cfg, "pos", None
    )


def test_a_time_window_or_another_estimator_keeps_the_whole_file_path(shared_data: Path) -> None:
    obs = str(shared_data / RUNS["kamakura"][0])
    cfg = preset("spp")
    for other in (
        replace(cfg, gnss=replace(cfg.gnss, interval_s=2.0)),
        replace(cfg, gnss=replace(cfg.gnss, time_start="06:30:00")),
        replace(cfg, estimator=replace(cfg.estimator, filter="ekf")),
    ):
        assert not gnss_stream.streamable(obs, other, "pos", None)
