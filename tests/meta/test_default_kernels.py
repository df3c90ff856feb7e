"""What a default solve executes: no numba, and the C LAMBDA kernels whenever they are built.

The RTK solve of the bundled mosaic-X5 pair (``robustrtk solve --mode rtk``, the preset's
settings, in-process through the console entry) runs in a fresh interpreter whose LAMBDA
entry points count their calls: every C kernel of ``lambda_ckernels`` and every pure
reference that ``lambda_`` falls back to. With the library built, the ambiguity resolution
must run on the C kernels alone; without it, on the pure references. numba must never be
imported.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import robustrtk

#: The directory that holds the ``robustrtk`` package this test process imported.
PKG_PARENT = Path(robustrtk.__file__).resolve().parents[1]
SAMPLE = Path(robustrtk.__file__).resolve().parent / "data" / "mosaicx5_static"

PROBE = """
import json, sys
from collections import Counter
from pathlib import Path

from robustrtk.ambiguity import lambda_
from robustrtk.geometry.frames import geodetic2ecef_deg

calls = Counter()


def counted(owner, name, tag):
    fn = getattr(owner, name)

    def wrapper(*args, **kwargs):
        calls[tag + "." + name] += 1
        return fn(*args, **kwargs)

    setattr(owner, name, wrapper)


try:
    from robustrtk.ambiguity import lambda_ckernels as ck
except ImportError:
    ck = None
if ck is not None:
    for name in ("ltdl_k", "reduce_k", "search_k", "ils_k", "ils_from_reduced_k", "lambda_all"):
        counted(ck, name, "c")
for name in ("ltdl_py", "reduce_ops_py", "search_py", "ils_search_py", "lambda_search_py"):
    counted(lambda_, name, "pure")

d = Path(sys.argv[1])
base_ecef = geodetic2ecef_deg(*(float(v) for v in (d / "base_position.txt").read_text().split()[:3]))
from robustrtk.cli.entry import run

rc = run([
    "solve", str(d / "rover.crx.gz"), "--base", str(d / "base.crx.gz"), "--nav", str(d / "base.nav.gz"),
    "--base-pos", ",".join(repr(float(v)) for v in base_ecef), "--mode", "rtk",
    "--out", sys.argv[2], "--quiet",
])
print(json.dumps({"rc": rc, "c_built": ck is not None, "numba": "numba" in sys.modules, "calls": calls}))
"""


def _solve(tmp_path: Path) -> dict[str, object]:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("ROBUSTRTK_", "NUMBA_"))}
    env["PYTHONPATH"] = os.pathsep.join([str(PKG_PARENT), env.get("PYTHONPATH", "")])
    out = tmp_path / "sample.pos"
    proc = subprocess.run(
        [sys.executable, "-c", PROBE, str(SAMPLE), str(out)],
        capture_output=True,
        text=True,
        env=env,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr
    res: dict[str, object] = json.loads(proc.stdout.strip().splitlines()[-1])
    assert res["rc"] == 0
    fixed = [ln.split()[5] for ln in out.read_text().splitlines() if not ln.startswith("%")]
    assert fixed.count("1") > 0  # the ambiguities were resolved, so LAMBDA ran
    return res


def test_a_default_rtk_solve_runs_the_c_lambda_kernels_and_never_imports_numba(tmp_path: Path) -> None:
    res = _solve(tmp_path)
    assert res["numba"] is False
    calls = res["calls"]
    assert isinstance(calls, dict)
    c_calls = sum(n for k, n in calls.items() if k.startswith("c."))
    pure_calls = {k: n for k, n in calls.items() if k.startswith("pure.")}
    if res["c_built"]:
        assert c_calls > 0 and calls.get("c.ils_from_reduced_k", 0) > 0, calls
        assert not pure_calls, pure_calls  # no fallback to the references
    else:  # no compiler at install: the pure references serve
        assert c_calls == 0 and sum(pure_calls.values()) > 0, calls
