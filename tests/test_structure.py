"""The shape of the package, drawn from its source with ``ast`` (nothing is imported):
no import cycles between modules, no module using another module's private (``_name``)
names, no library module parsing arguments (argparse lives in ``csm_assets/cli/``), and
no source file over :data:`MAX_BYTES`."""

from __future__ import annotations

import ast
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "csm_assets"
MAX_BYTES = 16 * 1024

# Function-local imports that close a cycle, allowed with a reason. Keep it short; an entry
# that no longer closes a cycle (or became a module-level import) fails the test, so it empties.
LAZY_CYCLES = {
    # scene_module (the scene-format table) lives in convert.py, which imports convert_maps,
    # which imports pick_scene, which renders through verify_scene; goes when the table
    # moves into formats/ (issue 14)
    ("csm_assets.verify_scene", "csm_assets.convert"): "scene_module lives in convert.py",
}

# Files over MAX_BYTES allowed while their owner splits them, each with a reason (empty now:
# convert.py, formats/usd.py and formats/usd_write.py were split by job). A file listed here
# that is no longer over fails the test, so the list empties.
OVERSIZE: set[str] = set()


@dataclass(frozen=True)
class Edge:
    importer: str
    imported: str
    lazy: bool  # inside a function: runs when called, not when the module loads
    name: str | None  # the name taken from ``imported`` (None: the module itself)
    line: int


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


MODULES = {module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}
PACKAGES = {module_name(p) for p in PACKAGE.rglob("__init__.py")}


def _source(module: str) -> ast.Module:
    path = MODULES[module]
    return ast.parse(path.read_text(encoding="utf-8"), str(path))


def _absolute(module: str, node: ast.ImportFrom) -> str:
    if not node.level:
        return node.module or ""
    base = module.split(".") if module in PACKAGES else module.split(".")[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def _is_type_checking(node: ast.AST) -> bool:
    test = getattr(node, "test", None)
    return isinstance(node, ast.If) and (getattr(test, "id", None) == "TYPE_CHECKING"
                                         or getattr(test, "attr", None) == "TYPE_CHECKING")


def edges_of(module: str) -> list[Edge]:
    """Every import of a csm_assets module in ``module``: ``from X import m`` where X.m is a
    module counts as importing X.m; ``import a.b.c`` as its longest known prefix."""
    out = []

    def walk(node, lazy):
        for child in ast.iter_child_nodes(node):
            if _is_type_checking(child):
                continue
            inner = lazy or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda))
            if isinstance(child, ast.ImportFrom):
                source = _absolute(module, child)
                for alias in child.names:
                    if f"{source}.{alias.name}" in MODULES:
                        out.append(Edge(module, f"{source}.{alias.name}", inner, None, child.lineno))
                    elif source in MODULES:
                        out.append(Edge(module, source, inner, alias.name, child.lineno))
            elif isinstance(child, ast.Import):
                for alias in child.names:
                    name = alias.name
                    while name and name not in MODULES:
                        name = name.rpartition(".")[0]
                    if name:
                        out.append(Edge(module, name, inner, None, child.lineno))
            walk(child, inner)

    walk(_source(module), False)
    return [e for e in out if e.imported != e.importer]


EDGES = [e for m in MODULES for e in edges_of(m)]


def cycles(edges) -> list[list[str]]:
    """The strongly connected groups of more than one module (Tarjan), each sorted."""
    graph = defaultdict(set)
    for e in edges:
        graph[e.importer].add(e.imported)
    index, low, stack, on_stack, found = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                group.append(w)
                if w == v:
                    break
            if len(group) > 1:
                found.append(sorted(group))

    for v in sorted(set(graph) | {w for ws in graph.values() for w in ws}):
        if v not in index:
            visit(v)
    return found


def _describe(group, edges) -> str:
    inside = sorted({(e.importer, e.imported, e.lazy) for e in edges if e.importer in group and e.imported in group})
    return "; ".join(f"{a} -> {b}{' (in a function)' if lazy else ''}" for a, b, lazy in inside)


def test_the_graph_is_drawn():
    """The walk sees the imports it must (a test that could not fail would be worthless)."""
    pairs = {(e.importer, e.imported) for e in EDGES}
    assert ("csm_assets.cli", "csm_assets.cli.stepmap") in pairs  # from . import stepmap
    assert ("csm_assets.stepmap", "csm_assets.packing") in pairs  # from .packing import step_map
    assert ("csm_assets.cli.stepmap", "csm_assets.stepmap") in pairs  # from ..stepmap import DEFAULTS
    assert any(e.lazy for e in EDGES) and any(not e.lazy for e in EDGES)
    made_up = [Edge("a", "b", False, None, 1), Edge("b", "c", True, None, 1), Edge("c", "a", False, None, 1),
               Edge("c", "d", False, None, 1)]
    assert cycles(made_up) == [["a", "b", "c"]]


def test_no_import_cycles_at_load_time():
    """Module-level imports alone form no cycle: any import order works."""
    found = cycles([e for e in EDGES if not e.lazy])
    assert not found, "import cycles: " + " | ".join(_describe(g, EDGES) for g in found)


def test_no_import_cycles_through_function_local_imports_but_the_listed():
    """A cycle closed by an import inside a function still ties the modules together; only
    those in LAZY_CYCLES are allowed, each with its reason."""
    allowed = {(e.importer, e.imported) for e in EDGES if (e.importer, e.imported) in LAZY_CYCLES}
    kept = [e for e in EDGES if (e.importer, e.imported) not in allowed]
    found = cycles(kept)
    assert not found, "import cycles through function-local imports: " + " | ".join(
        _describe(g, EDGES) for g in found)
    for pair in LAZY_CYCLES:
        uses = [e for e in EDGES if (e.importer, e.imported) == pair]
        assert uses, f"LAZY_CYCLES lists {pair}, which is no import any more: remove it"
        assert all(e.lazy for e in uses), f"{pair} is allowed only as a function-local import"
        assert cycles(EDGES) and any(set(pair) <= set(g) for g in cycles(EDGES)), (
            f"LAZY_CYCLES lists {pair}, which closes no cycle any more: remove it")


def test_no_module_uses_another_modules_private_names():
    """``from .x import _name`` and ``x._name`` across modules: make a shared helper public."""
    found = [f"{e.importer}:{e.line} imports {e.name} from {e.imported}" for e in EDGES
             if e.name and e.name.startswith("_") and not e.name.startswith("__")]
    for module in MODULES:
        tree = _source(module)
        aliases = {}
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                source = _absolute(module, node)
                for alias in node.names:
                    if f"{source}.{alias.name}" in MODULES:
                        aliases[alias.asname or alias.name] = f"{source}.{alias.name}"
            elif isinstance(node, ast.Import):
                for alias in node.names:
                    if alias.name in MODULES and alias.asname:
                        aliases[alias.asname] = alias.name
        for node in ast.walk(tree):
            if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in aliases
                    and node.attr.startswith("_") and not node.attr.startswith("__")
                    and aliases[node.value.id] != module):
                found.append(f"{module}:{node.lineno} uses {aliases[node.value.id]}.{node.attr}")
    assert not found, "private names used across modules:\n" + "\n".join(found)


def test_argparse_lives_in_the_cli_package_only():
    """Library modules take values, not argv: every argparse import is under csm_assets/cli/."""
    found = []
    for module in MODULES:
        if module == "csm_assets.cli" or module.startswith("csm_assets.cli."):
            continue
        for node in ast.walk(_source(module)):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module] if isinstance(node, ast.ImportFrom) and not node.level else [])
            if "argparse" in names:
                found.append(f"{module}:{node.lineno}")
    assert not found, f"argparse outside csm_assets/cli/: {found}"


def test_no_source_file_over_16_kb():
    sizes = {p.relative_to(ROOT).as_posix(): p.stat().st_size for p in PACKAGE.rglob("*.py")}
    over = {k: v for k, v in sorted(sizes.items()) if v > MAX_BYTES}
    unlisted = [f"{k} ({v} bytes)" for k, v in over.items() if k not in OVERSIZE]
    assert not unlisted, f"files over {MAX_BYTES} bytes (split them by job): {unlisted}"
    stale = sorted(OVERSIZE - set(over))
    assert not stale, f"OVERSIZE lists files that are no longer over {MAX_BYTES} bytes: remove {stale}"


def test_every_package_is_installed():
    """A folder with an ``__init__.py`` that pyproject's package list leaves out is missing
    from a wheel (the pre-commit hook's install) although an editable install finds it."""
    import tomllib

    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    missing = sorted(PACKAGES - listed)
    assert not missing, f"packages missing from pyproject.toml's [tool.setuptools] packages: {missing}"
