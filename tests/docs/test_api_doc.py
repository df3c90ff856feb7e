"""Every ``python`` code block of docs/api.md runs, in a scratch directory.

The blocks carry their own assertions (fix rates, errors against the reference point, the
files written reading back). ``data/`` in the scratch directory links to the shared real
datasets; a block that names ``data/<dataset>`` is skipped when that dataset is absent.
"""

from __future__ import annotations

import os
import re
import warnings
from pathlib import Path

import pytest

DOC = Path(__file__).resolve().parents[2] / "docs" / "api.md"
FENCE = re.compile(r"^(<!-- slow -->\n)?```python\n(.*?)^```$", re.S | re.M)
DATASET = re.compile(r"data/([A-Za-z0-9_]+)")


def _blocks() -> list[tuple[int, str, bool]]:
    """(line, code, slow) of each block; ``<!-- slow -->`` before a fence marks a long one."""
    text = DOC.read_text(encoding="utf-8")
    return [(text[: m.start(2)].count("\n"), m.group(2), bool(m.group(1))) for m in FENCE.finditer(text)]


BLOCKS = _blocks()
PARAMS = [
    pytest.param(line, code, id=f"line{line}", marks=[pytest.mark.slow] if slow else [])
    for line, code, slow in BLOCKS
]


def test_the_page_has_blocks_of_every_kind() -> None:
    code = "\n".join(b for _, b, _ in BLOCKS)
    for name in ("solve_spp", "solve_dgnss", "solve_rtk", "solve_dpl", "to_pos", "to_dataframe"):
        assert f".{name}(" in code, name
    assert any(not DATASET.search(b) for _, b, _ in BLOCKS), "no block runs without the shared data"
    assert any(not slow for _, _, slow in BLOCKS), "every block is slow: the default suite runs none"


def _shared() -> Path:
    env = os.environ.get("ROBUSTRTK_SHARED_DATA")
    return Path(env) if env else Path(__file__).resolve().parents[3] / "shared" / "data"


@pytest.mark.parametrize(("line", "code"), PARAMS)
def test_block_runs(line: int, code: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    shared = _shared()
    for name in sorted(set(DATASET.findall(code))):
        if not (shared / name).is_dir():
            pytest.skip(f"docs/api.md:{line} reads data/{name}, absent at {shared / name}")
    if shared.is_dir():
        (tmp_path / "data").symlink_to(shared, target_is_directory=True)
    monkeypatch.chdir(tmp_path)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # an example must not rely on a warned-about default
        exec(compile(code, f"docs/api.md:{line}", "exec"), {"__name__": "__doc_example__"})
