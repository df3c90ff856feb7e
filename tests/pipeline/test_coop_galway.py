"""``coop`` on the galway M8P data (``../shared/data/galway_m8p_l1_lowcost``; skipped without
it): the rover as the node, occluded to 3 satellites, the M8P base (RINEX from its RTCM3 stream,
1-4 s gaps, GLONASS-only epochs) as its surveyed peer, paired by the base-epoch rule."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from robustrtk.geometry.frames import ecef2enu_rotation, ecef2geodetic
from robustrtk.io.solution_pos import read_pos

ROVER_TRUTH = np.array([3774088.6834, -601663.0382, 5089318.2298])


@pytest.mark.slow
def test_coop_node_against_its_m8p_base_with_gaps(shared_data: Path, tmp_path: Path) -> None:
    from robustrtk.cli.main import main

    s1 = shared_data / "galway_m8p_l1_lowcost" / "s1_static"
    if not (s1 / "base-20181004-1236_rtcm.obs").is_file():
        pytest.skip(f"galway_m8p_l1_lowcost not found in {shared_data}")
    out = tmp_path / "node.pos"
    r = CliRunner().invoke(
        main,
        [
            "coop", str(s1 / "rover-20181004-1237.obs"), "--peer", str(s1 / "base-20181004-1236_rtcm.obs"),
            "--peer-pos", "3774088.9004,-601662.8325,5089318.0783",
            "--nav", str(s1 / "base-20181004-1236_ubx.nav"),
            "--range-from-rtk", "--windowsill", "3", "--out", str(out),
        ],
    )  # fmt: skip
    assert r.exit_code == 0, r.output
    table = read_pos(out)
    # the rover's 1205 epochs: its three satellites and the range to the base are exactly as
    # many rows as its unknowns, and the first epoch's least squares does not converge (the
    # range's sphere misses the pseudoranges' curve): it starts one range above the base and
    # that epoch's rows update the start; one later epoch without an RTK solution gets the
    # range interpolated from its neighbours
    assert table.t_s.size == 1205
    lat, lon, _ = ecef2geodetic(ROVER_TRUTH)
    rot = ecef2enu_rotation(float(lat), float(lon))
    enu = (table.pos_m - ROVER_TRUTH) @ rot.T
    assert np.percentile(np.hypot(enu[:, 0], enu[:, 1]), 95) <= 10.0
