"""Without the shared real datasets, pytest says in one line why tests were skipped."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_one_line_names_the_missing_shared_data(tmp_path: Path) -> None:
    missing = tmp_path / "no-such-folder"
    env = {**os.environ, "ROBUSTRTK_SHARED_DATA": str(missing)}
    cmd = [sys.executable, "-m", "pytest", "-q", "-n", "0", "-p", "no:cacheprovider",
           "tests/eval/test_truth_formats.py", "-k", "gsdc_2021 or short_pos"]  # fmt: skip
    out = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=300).stdout
    lines = [ln for ln in out.splitlines() if "shared real datasets are not at" in ln]
    assert lines == [
        f"1 test skipped: the shared real datasets are not at {missing} (set ROBUSTRTK_SHARED_DATA)"
    ]
