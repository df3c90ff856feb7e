"""The Kalman SPP's satellite states computed a block of epochs at a time are, row by row,
exactly those of one call per epoch (real multi-system data, across a block boundary)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from robustrtk.geometry.ephemeris import EphemerisSource
from robustrtk.io.readers import read_observations
from robustrtk.io.rinex_nav import read_rinex_nav
from robustrtk.pipeline.spp_signals import SAT_STATES_BLOCK, SatStatesTable, sat_states, spp_signals

MOSAIC = "mosaicx5_static_1m"


def test_table_equals_the_per_epoch_states(shared_data: Path) -> None:
    d = shared_data / MOSAIC
    if not (d / "rover.obs").is_file():
        pytest.skip(f"{d} absent")
    batch = read_observations(d / "rover.obs")
    eph = EphemerisSource(read_rinex_nav(d / "base.nav"))
    sig = spp_signals(batch, eph.nav, True)
    t = np.asarray(batch.t_s, float)
    assert len(t) > SAT_STATES_BLOCK  # the table crosses a block boundary
    table = SatStatesTable(sig, t, eph)
    # out of order too: a later block first, then back to the start
    order = [len(t) - 1, 0, *range(len(t))]
    n_rows, systems = 0, set()
    for i in order:
        got, want = table.of(i), sat_states(sig, i, float(t[i]), eph)
        assert got.idx.dtype == want.idx.dtype and np.array_equal(got.idx, want.idx)
        for name in ("t_tx_s", "pos_m", "vel_m_s", "clk_m", "drift_m_s", "tgd_m"):
            a, b = getattr(got, name), getattr(want, name)
            assert a.shape == b.shape
            np.testing.assert_array_equal(a, b)
        n_rows += got.idx.size
        systems |= {sig.sys[j] for j in got.idx.tolist()}
    assert n_rows > 1000 and {"G", "E", "R"} <= systems  # real states, GLONASS integrated too
