"""Every repository path and every ``robustrtk.…`` name that the documentation cites exists.

Read: the README, ``docs/*.md``, and the docstrings and comments of ``src`` and ``bench``.
Cited paths are those under the repository's own folders (``docs/``, ``bench/``, ``src/``,
``tests/``, ``.ci/``, and ``robustrtk/…`` inside ``src``), globs included, and the relative
targets of Markdown links; cited names are dotted ``robustrtk.module.attribute`` references.
"""

from __future__ import annotations

import ast
import importlib
import io
import re
import tokenize
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

_PATH = re.compile(r"(?<![\w./-])((?:docs|bench|src|tests|\.ci|robustrtk)/[A-Za-z0-9_.*/-]*[A-Za-z0-9_*/])")
_LINK = re.compile(r"\]\(([^)\s]+)\)")
_NAME = re.compile(r"(?<![\w.])(robustrtk(?:\.[A-Za-z_]\w*)+)")


def _python_text(path: Path) -> str:
    """The docstrings and comments of one source file."""
    src = path.read_text(encoding="utf-8")
    parts = []
    for node in ast.walk(ast.parse(src)):
        if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef):
            doc = ast.get_docstring(node, clean=False)
            if doc:
                parts.append(doc)
    for tok in tokenize.generate_tokens(io.StringIO(src).readline):
        if tok.type == tokenize.COMMENT:
            parts.append(tok.string)
    return "\n".join(parts)


def _documents() -> dict[Path, str]:
    docs = {ROOT / "README.md": (ROOT / "README.md").read_text(encoding="utf-8")}
    docs.update({p: p.read_text(encoding="utf-8") for p in sorted((ROOT / "docs").glob("*.md"))})
    for folder in ("src", "bench"):
        docs.update({p: _python_text(p) for p in sorted((ROOT / folder).rglob("*.py"))})
    return docs


def _exists(cited: str) -> bool:
    rel = cited.rstrip("/")
    base = ROOT / "src" if rel.startswith("robustrtk/") else ROOT
    if any(c in rel for c in "*?["):
        return any(base.glob(rel))
    return (base / rel).exists()


def test_every_cited_repository_path_exists() -> None:
    missing = []
    for path, text in _documents().items():
        where = path.relative_to(ROOT)
        for m in _PATH.finditer(text):
            if not _exists(m.group(1)):
                missing.append(f"{where}: {m.group(1)}")
        if path.suffix == ".md":
            for m in _LINK.finditer(text):
                target = m.group(1).split("#", 1)[0]
                if target and "://" not in target and not target.startswith("mailto:"):
                    if not (path.parent / target).exists():
                        missing.append(f"{where}: link {m.group(1)}")
    assert not missing, "cited but absent:\n" + "\n".join(sorted(set(missing)))


def _resolves(dotted: str) -> bool:
    parts = dotted.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj: object = importlib.import_module(".".join(parts[:i]))
        except ModuleNotFoundError:
            continue
        for attr in parts[i:]:
            if not hasattr(obj, attr):
                return False
            obj = getattr(obj, attr)
        return True
    return False


def test_every_cited_robustrtk_name_exists() -> None:
    missing = sorted(
        {
            f"{path.relative_to(ROOT)}: {m.group(1)}"
            for path, text in _documents().items()
            for m in _NAME.finditer(text)
            if not _resolves(m.group(1))
        }
    )
    assert not missing, "cited but absent:\n" + "\n".join(missing)


def test_the_check_sees_a_missing_path_and_name() -> None:
    assert _exists("docs/api.md") and _exists("robustrtk/sim/presets/*.toml") and _exists("bench/")
    assert not _exists("bench/bench_nothing.py") and not _exists("docs/*.nothing")
    assert _resolves("robustrtk.io.tables.format_table") and _resolves("robustrtk.sim.scenario")
    assert not _resolves("robustrtk.io.tables.no_such_name") and not _resolves("robustrtk.no_such_module")
    assert [m.group(1) for m in _PATH.finditer("see `bench/bench_x.py`, (docs/a.md) and data/bench/y")] == [
        "bench/bench_x.py",
        "docs/a.md",
    ]
