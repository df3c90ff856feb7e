"""numba is imported on the solve path only: not by the command line's start-up nor by
importing the library's modules (kernels load on the first ambiguity search / filter update)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

SRC = Path(__file__).resolve().parents[2] / "src"

_PROBE = """
import contextlib, io, sys
from robustrtk.cli.entry import run
import robustrtk.pipeline.rtk_gnss, robustrtk.ambiguity.par, robustrtk.estimation.filters
with contextlib.redirect_stdout(io.StringIO()) as help_text:
    assert run(["--help"]) == 0
assert "solve" in help_text.getvalue()
print("numba" in sys.modules)
import numpy as np
from robustrtk.ambiguity.lambda_ import kernels, lambda_search
lambda_search(np.array([0.2, -1.3]), np.array([[0.5, 0.1], [0.1, 0.4]]))
print(kernels() is not None and "numba" in sys.modules)
"""


def test_help_and_imports_do_not_load_numba_and_a_search_does() -> None:
    out = subprocess.run(
        [sys.executable, "-c", _PROBE],
        env={
            "PYTHONPATH": str(SRC),
            "PATH": "/usr/bin:/bin",
            "ROBUSTRTK_JIT": "on",
            "ROBUSTRTK_LAMBDA_BACKEND": "numba",  # the C kernels, when built, load no numba
        },
        capture_output=True,
        text=True,
        check=True,
        timeout=300,
    ).stdout.split()
    assert out == ["False", "True"]
