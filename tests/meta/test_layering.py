"""The package's import graph: no cycles, no private names across modules, layers flow down."""

from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[2] / "src"

#: Layers from the bottom; a module may import its own layer or lower ones.
LAYERS: tuple[tuple[str, ...], ...] = (
    ("core", "errors", "timeutil", "gnss", "version", "blas"),
    # formats and geometry: readers build geometry's record types; geometry knows no format
    ("io", "geometry"),
    ("measurement", "cycleslip"),
    ("estimation",),
    ("ambiguity",),
    ("pipeline",),
    ("sim", "eval"),
    # task engines (a process pool or Dask) for batch jobs and for the experiments' seeds
    ("campaign",),
    ("experiments",),
    ("cli",),
)


def _modules() -> dict[str, Path]:
    mods = {}
    for p in (SRC / "robustrtk").rglob("*.py"):
        name = ".".join(p.relative_to(SRC).with_suffix("").parts)
        mods[name.removesuffix(".__init__")] = p
    return mods


def _imports(mods: dict[str, Path]) -> tuple[dict[str, set[str]], list[str]]:
    edges: dict[str, set[str]] = {m: set() for m in mods}
    private: list[str] = []
    for m, p in mods.items():
        pkg = m if p.name == "__init__.py" else m.rsplit(".", 1)[0]
        for node in ast.walk(ast.parse(p.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom):
                if node.level:
                    base = pkg.split(".")[: len(pkg.split(".")) - (node.level - 1)]
                    target = ".".join(base + ([node.module] if node.module else []))
                else:
                    target = node.module or ""
                if not target.startswith("robustrtk"):
                    continue
                for a in node.names:
                    full = f"{target}.{a.name}"
                    dst = full if full in mods else target
                    if dst in mods and dst != m:
                        edges[m].add(dst)
                    if a.name.startswith("_") and not a.name.startswith("__") and dst != m:
                        private.append(f"{m} imports {target}.{a.name}")
            elif isinstance(node, ast.Import):
                for a in node.names:
                    if a.name in mods and a.name != m:
                        edges[m].add(a.name)
    return edges, private


def _layer(mod: str) -> int | None:
    parts = mod.split(".")
    if len(parts) < 2:
        return None
    for i, names in enumerate(LAYERS):
        if parts[1] in names:
            return i
    return None


def test_no_import_cycles() -> None:
    mods = _modules()
    edges, _ = _imports(mods)
    # package __init__ modules only re-export: leave them out of the cycle search
    graph = {m: {d for d in ds if d in mods and mods[d].name != "__init__.py"} for m, ds in edges.items()}
    state: dict[str, int] = {}
    cycles: list[list[str]] = []

    def visit(v: str, path: list[str]) -> None:
        state[v] = 1
        path.append(v)
        for w in graph[v]:
            if state.get(w) == 1:
                cycles.append(path[path.index(w) :] + [w])
            elif w not in state:
                visit(w, path)
        path.pop()
        state[v] = 2

    for v in graph:
        if v not in state:
            visit(v, [])
    assert not cycles, "import cycles: " + "; ".join(" -> ".join(c) for c in cycles)


def test_no_private_names_across_modules() -> None:
    _, private = _imports(_modules())
    assert not private, "\n".join(private)


def test_lower_layers_never_import_higher_ones() -> None:
    edges, _ = _imports(_modules())
    bad = []
    for m, ds in edges.items():
        lm = _layer(m)
        for d in ds:
            ld = _layer(d)
            if lm is not None and ld is not None and ld > lm:
                bad.append(f"{m} imports {d}")
    assert not bad, "\n".join(sorted(bad))


def test_geometry_knows_no_file_format() -> None:
    edges, _ = _imports(_modules())
    bad = [f"{m} imports {d}" for m, ds in edges.items() if m.startswith("robustrtk.geometry") for d in ds
           if d.startswith("robustrtk.io")]  # fmt: skip
    assert not bad, "\n".join(bad)
