"""Reading a RINEX observation file a block of epochs at a time gives the whole-file read's
epochs and values, for any block size; errors name the file's own line; the streamed SPP
writes the ``.pos`` of the whole-file solve."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from robustrtk.core import ObsBatch
from robustrtk.errors import InputError
from robustrtk.io.rinex_chunks import iter_rinex_obs
from robustrtk.io.rinex_obs import read_rinex_obs
from robustrtk.io.solution_pos import write_pos
from robustrtk.pipeline.api import spp_series
from robustrtk.pipeline.gnss import nav_source
from robustrtk.pipeline.spp import select_band1, solve_spp
from robustrtk.pipeline.spp_stream import solve_spp_to_pos

FILES = {
    "pixel5": "gsdc2021_mtv1_pixel5_phone/Pixel5/supplemental/Pixel5_GnssLog.21o",
    "mosaicx5": "mosaicx5_static_1m/rover.obs",
    "kamakura": "kamakura_kinematic_5km/SEPT265G.21O",
    "geonet": "geonet_0759_3040_static_3km/07590920.05o",  # RINEX 2: read whole, handed out in blocks
}
_CACHE: dict[str, ObsBatch] = {}


def _whole(shared: Path, name: str) -> ObsBatch:
    if name not in _CACHE:
        _CACHE[name] = read_rinex_obs(shared / FILES[name])
    return _CACHE[name]


def assert_blocks_equal_whole(blocks: list[ObsBatch], whole: ObsBatch) -> None:
    t = np.concatenate([b.t_s for b in blocks])
    np.testing.assert_array_equal(t, whole.t_s)
    i0 = 0
    for b in blocks:
        idx = np.arange(i0, i0 + len(b))
        i0 += len(b)
        rows = [whole.tx_ids.index(s) for s in b.tx_ids]
        cols = [whole.signals.index(s) for s in b.signals]
        assert set(
            whole.tx_ids[j] for j in np.flatnonzero(np.isfinite(whole.code_m[idx]).any(axis=(0, 2)))
        ) <= set(b.tx_ids)
        for name in ("code_m", "phase_cyc", "doppler_hz", "cn0_dbhz"):
            got = getattr(b, name)
            ref = getattr(whole, name)[np.ix_(idx, rows, cols)]
            np.testing.assert_array_equal(got, ref, err_msg=name)
        np.testing.assert_array_equal(b.lli, whole.lli[np.ix_(idx, rows, cols)])


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(name=st.sampled_from(sorted(FILES)), n=st.integers(1, 400))
def test_blocks_equal_the_whole_file(shared_data: Path, name: str, n: int) -> None:
    blocks = list(iter_rinex_obs(shared_data / FILES[name], epochs_per_chunk=n))
    whole = _whole(shared_data, name)
    assert all(1 <= len(b) <= n for b in blocks)
    assert len(blocks) == -(-len(whole) // n)
    assert_blocks_equal_whole(blocks, whole)


def test_systems_are_kept_per_block(shared_data: Path) -> None:
    blocks = list(iter_rinex_obs(shared_data / FILES["mosaicx5"], systems="GE", epochs_per_chunk=50))
    assert {s[0] for b in blocks for s in b.system} == {"G", "E"}
    assert_blocks_equal_whole(blocks, read_rinex_obs(shared_data / FILES["mosaicx5"], systems="GE"))


def _lines(path: Path) -> list[str]:
    return path.read_text().splitlines(keepends=True)


def test_an_error_names_the_line_of_the_file(shared_data: Path, tmp_path: Path) -> None:
    lines = _lines(shared_data / FILES["kamakura"])
    epoch_lines = [i for i, s in enumerate(lines) if s.startswith(">")]
    k = epoch_lines[200]
    lines[k] = "> 2021 13 45" + lines[k][12:]  # month 13 in the 201st epoch
    bad = tmp_path / "bad.obs"
    bad.write_text("".join(lines))
    with pytest.raises(InputError) as whole:
        read_rinex_obs(bad)
    with pytest.raises(InputError) as chunked:
        list(iter_rinex_obs(bad, epochs_per_chunk=64))
    assert whole.value.line == k + 1
    assert chunked.value.line == whole.value.line
    assert chunked.value.message == whole.value.message


def test_epochs_out_of_order_across_blocks_are_refused(shared_data: Path, tmp_path: Path) -> None:
    lines = _lines(shared_data / FILES["kamakura"])
    starts = [i for i, s in enumerate(lines) if s.startswith(">")]
    head = lines[: starts[0]]
    first, second = lines[starts[0] : starts[10]], lines[starts[10] : starts[20]]
    swapped = tmp_path / "swapped.obs"
    swapped.write_text("".join(head + second + first))
    with pytest.raises(InputError, match="does not increase") as err:
        list(iter_rinex_obs(swapped, epochs_per_chunk=10))
    assert err.value.line == len(head) + len(second) + 1


def test_streamed_spp_writes_the_whole_file_solution(shared_data: Path, tmp_path: Path) -> None:
    obs = shared_data / FILES["kamakura"]
    nav = shared_data / "kamakura_kinematic_5km/SEPT2650.21P"
    eph = nav_source([str(nav)])
    whole = solve_spp(select_band1(read_rinex_obs(obs)), eph)
    write_pos([e.to_solution() for e in whole], tmp_path / "whole.pos", inputs=[str(obs), str(nav)])
    counts = solve_spp_to_pos(
        obs, eph, tmp_path / "streamed.pos", epochs_per_chunk=45, inputs=[str(obs), str(nav)]
    )
    assert (tmp_path / "streamed.pos").read_text() == (tmp_path / "whole.pos").read_text()
    assert counts.epochs == len(whole)
    assert counts.single == sum(e.status == "single" for e in whole)
    assert counts.excluded == sum(len(e.excluded) for e in whole)
    got, ref = counts.summary(), spp_series(whole).summary()
    assert np.isnan(got.time_to_first_fix_s) and np.isnan(ref.time_to_first_fix_s)  # nothing fixed
    no_ttff = {"time_to_first_fix_s": 0.0}
    assert dataclasses.replace(got, **no_ttff) == dataclasses.replace(ref, **no_ttff)


def test_a_failed_stream_leaves_the_old_output(shared_data: Path, tmp_path: Path) -> None:
    lines = _lines(shared_data / FILES["kamakura"])
    k = [i for i, s in enumerate(lines) if s.startswith(">")][300]
    lines[k] = "> 2021 13 45" + lines[k][12:]
    bad = tmp_path / "bad.obs"
    bad.write_text("".join(lines))
    out = tmp_path / "out.pos"
    out.write_text("old\n")
    eph = nav_source([str(shared_data / "kamakura_kinematic_5km/SEPT2650.21P")])
    with pytest.raises(InputError):
        solve_spp_to_pos(bad, eph, out, epochs_per_chunk=32)
    assert out.read_text() == "old\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.obs", "out.pos"]
