"""Peak memory of a whole RTK solve on mosaicx5 (301 epochs, five systems): at most 80 MiB.

The solve runs in a fresh interpreter that reports its own peak resident set size
(``ru_maxrss``), so other tests' processes do not count. Where the memory went before
(154 MiB): scipy.stats imported for one chi-square quantile, scipy.linalg for one Cholesky
solve, and the RINEX reader's int64 gather index (8 bytes per byte of text).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[2] / "src"

#: Acceptance bound (issue 13): peak RSS of the mosaicx5 RTK solve, MiB.
PEAK_RSS_MIB = 80.0


@pytest.mark.slow
def test_mosaicx5_rtk_peak_rss_below_80_mib(shared_data: Path, tmp_path: Path) -> None:
    d = shared_data / "mosaicx5_static_1m"
    if not (d / "rover.obs").is_file():
        pytest.skip(f"mosaicx5 dataset not found in {shared_data}")
    args = [
        "solve", str(d / "rover.obs"), "--base", str(d / "base.obs"), "--nav", str(d / "base.nav"),
        "--base-pos", "-3817681.1213,3562839.4311,3650159.1593", "--mode", "rtk",
        "--out", str(tmp_path / "m.pos"), "--quiet",
    ]  # fmt: skip
    code = (
        "import resource\nfrom robustrtk.cli.entry import run\n"
        f"rc = run({args!r})\n"
        "print(rc, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)\n"
    )
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(SRC), env.get("PYTHONPATH", "")])
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=600)
    assert proc.returncode == 0, proc.stderr
    rc, maxrss_kib = (int(w) for w in proc.stdout.split()[-2:])
    assert rc == 0
    lines = (tmp_path / "m.pos").read_text().splitlines()
    assert sum(1 for ln in lines if not ln.startswith("%")) == 301
    assert maxrss_kib / 1024 <= PEAK_RSS_MIB, f"peak RSS {maxrss_kib / 1024:.1f} MiB"
