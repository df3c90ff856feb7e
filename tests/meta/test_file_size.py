"""No source file does several jobs' worth of lines: every module of ``src`` stays within
600 lines (files split along their seams instead)."""

from __future__ import annotations

from pathlib import Path

SRC = Path(__file__).resolve().parents[2] / "src" / "robustrtk"
MAX_LINES = 600


def test_no_source_file_over_600_lines() -> None:
    sizes = {
        p.relative_to(SRC).as_posix(): len(p.read_text(encoding="utf-8").splitlines())
        for p in SRC.rglob("*.py")
    }
    assert len(sizes) > 100
    over = {name: n for name, n in sizes.items() if n > MAX_LINES}
    assert not over, f"source files over {MAX_LINES} lines: {over}"
