"""The import structure of ``pipeline``: no import cycles, and the geometry/io layer imports
nothing above it.

Imports are read statically with :mod:`ast`, never executed. Every ``import`` and ``from ...
import`` counts: at module level, inside functions (lazy imports), classes, ``if`` and ``try``
blocks, including ``if TYPE_CHECKING:``. A cycle through a lazy, function-level import is still a
cycle: the two modules cannot be understood, tested or moved apart. Relative imports are resolved
against the importing module's package; ``from P import name`` is an edge to the module
``P.name`` when that module exists, otherwise to ``P``. Parent packages that Python imports on the
way (``pipeline/__init__.py`` for ``pipeline.geometry.sem``) are not edges. Dynamic imports
(``importlib.import_module``, ``__import__``) cannot be seen. ``.pyx`` files are read line by line
(single-line ``import``/``from`` statements; ``cimport`` lines are C-level and skipped).

The layers: ``pipeline.geometry`` and ``pipeline.io`` are the bottom, together with the shared
base ``pipeline`` (the package itself) and ``pipeline.errors``. A bottom module may import only
bottom modules; everything else (``pipeline.stages``, ``pipeline.config``, ``pipeline.runner*``,
``pipeline.cli``, ``pipeline.experiments``, ``pipeline.sample``, ...) is above and may import
downward only.

The checker is the public part of this file: :func:`import_graph`, :func:`find_cycles`,
:func:`format_cycle`, :func:`layering_violations`. Its own tests build tiny packages in
``tmp_path`` that contain a cycle and a layering violation, so it is shown to fail where it must.
"""

from __future__ import annotations

import ast
from dataclasses import dataclass
from pathlib import Path

from conftest import REPO

PACKAGE = "pipeline"
BOTTOM = ("pipeline.geometry", "pipeline.io")          # the layer, with every module under it
BASE = ("pipeline", "pipeline.errors")                 # exactly these modules, importable by all


@dataclass(frozen=True)
class Edge:
    """``source`` imports ``target`` at ``path:line``; ``lazy`` when inside a function."""

    source: str
    target: str
    path: str
    line: int
    lazy: bool

    def where(self) -> str:
        return f"{self.path}:{self.line}" + (" (in a function)" if self.lazy else "")


# --------------------------------------------------------------------------------- the checker


def _modules(package_dir: Path) -> dict[str, tuple[Path, bool]]:
    """Dotted module name → (file, is_package) for every ``.py``/``.pyx`` under ``package_dir``."""
    root = package_dir.parent
    out = {}
    for path in sorted(package_dir.rglob("*")):
        if path.suffix not in (".py", ".pyx") or "__pycache__" in path.parts:
            continue
        parts = list(path.relative_to(root).with_suffix("").parts)
        is_package = parts[-1] == "__init__"
        if is_package:
            parts.pop()
        out[".".join(parts)] = (path, is_package)
    return out


def _imports(tree: ast.AST):
    """Every import node of ``tree`` with ``lazy`` = inside a function or lambda."""
    stack = [(tree, False)]
    while stack:
        node, lazy = stack.pop()
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            yield node, lazy
        inner = lazy or isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda))
        stack.extend((child, inner) for child in ast.iter_child_nodes(node))


def _import_nodes(path: Path):
    """``(node, lazy)`` for every import statement of a ``.py`` or ``.pyx`` file."""
    text = path.read_text(encoding="utf-8")
    if path.suffix == ".py":
        yield from _imports(ast.parse(text, filename=str(path)))
        return
    # Cython is not Python: read single-line Python imports; indented ones count as lazy
    for lineno, line in enumerate(text.splitlines(), 1):
        s = line.strip()
        if not s.startswith(("import ", "from ")) or " cimport " in f" {s} ":
            continue
        try:
            tree = ast.parse(s)
        except SyntaxError:
            continue
        for node, _ in _imports(tree):
            node.lineno = lineno
            yield node, line[:1].isspace()


def _known(name: str, modules) -> str | None:
    """The longest prefix of the dotted ``name`` that is a module of the package, or None."""
    parts = name.split(".")
    for k in range(len(parts), 0, -1):
        candidate = ".".join(parts[:k])
        if candidate in modules:
            return candidate
    return None


def import_graph(package_dir) -> dict[str, list[Edge]]:
    """Module → its import edges into the same package, for the package at ``package_dir``.

    Every module of the package is a key (with an empty list when it imports nothing of the
    package). Imports of other packages are ignored; self-imports are dropped.
    """
    package_dir = Path(package_dir)
    modules = _modules(package_dir)
    graph: dict[str, list[Edge]] = {}
    for module, (path, is_package) in modules.items():
        here = module if is_package else module.rpartition(".")[0]
        edges = []
        for node, lazy in _import_nodes(path):
            if isinstance(node, ast.Import):
                targets = [_known(alias.name, modules) for alias in node.names]
            else:
                if node.level:
                    parts = here.split(".")
                    if node.level - 1 >= len(parts):
                        raise ValueError(f"{path}:{node.lineno}: relative import beyond the top")
                    base = ".".join(parts[: len(parts) - (node.level - 1)])
                    base = f"{base}.{node.module}" if node.module else base
                else:
                    base = node.module
                targets = [f"{base}.{alias.name}" if f"{base}.{alias.name}" in modules
                           else _known(base, modules) for alias in node.names]
            rel = str(path.relative_to(package_dir.parent))
            edges.extend(Edge(module, t, rel, node.lineno, lazy)
                         for t in dict.fromkeys(targets) if t is not None and t != module)
        graph[module] = sorted(edges, key=lambda e: (e.target, e.line))
    return graph


def _components(graph: dict[str, list[Edge]]) -> list[list[str]]:
    """Strongly connected components (Tarjan, iterative), each sorted."""
    index, low, on_stack, stack, out = {}, {}, set(), [], []
    succ = {m: sorted({e.target for e in edges}) for m, edges in graph.items()}
    for start in sorted(graph):
        if start in index:
            continue
        work = [(start, iter(succ[start]))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is None:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    comp = []
                    while True:
                        m = stack.pop()
                        on_stack.discard(m)
                        comp.append(m)
                        if m == node:
                            break
                    out.append(sorted(comp))
            elif child not in index:
                index[child] = low[child] = len(index)
                stack.append(child)
                on_stack.add(child)
                work.append((child, iter(succ.get(child, ()))))
            elif child in on_stack:
                low[node] = min(low[node], index[child])
    return out


def find_cycles(graph: dict[str, list[Edge]], limit: int = 1000) -> list[list[str]]:
    """Every elementary import cycle, as ``[m0, m1, ..., m0]``, sorted; at most ``limit``.

    Each cycle is listed once, starting at its smallest module name. The search runs inside the
    strongly connected components, so modules on no cycle cost nothing.
    """
    succ = {m: sorted({e.target for e in edges}) for m, edges in graph.items()}
    cycles = []
    for comp in _components(graph):
        if len(comp) < 2:
            continue
        members = set(comp)
        for start in comp:           # cycles whose smallest module is ``start``
            allowed = {m for m in members if m >= start}
            path, stack = [start], [iter(succ[start])]
            while stack:
                nxt = next(stack[-1], None)
                if nxt is None:
                    stack.pop()
                    path.pop()
                elif nxt == start:
                    cycles.append(path + [start])
                    if len(cycles) >= limit:
                        return sorted(cycles)
                elif nxt in allowed and nxt not in path:
                    path.append(nxt)
                    stack.append(iter(succ[nxt]))
    return sorted(cycles)


def format_cycle(graph: dict[str, list[Edge]], cycle: list[str]) -> str:
    """``a -> b (a.py:3) -> a (b.py:9 (in a function))``: each step with where it happens."""
    steps = [cycle[0]]
    for a, b in zip(cycle, cycle[1:]):
        where = ", ".join(e.where() for e in graph[a] if e.target == b)
        steps.append(f"{b} ({where})")
    return " -> ".join(steps)


def _in(module: str, layer) -> bool:
    return any(module == p or module.startswith(p + ".") for p in layer)


def layering_violations(graph: dict[str, list[Edge]], bottom=BOTTOM, base=BASE) -> list[Edge]:
    """Edges from a module of the ``bottom`` layers (prefixes) to anything but the bottom layers
    and the ``base`` modules (exact names)."""
    return [e for m in sorted(graph) for e in graph[m]
            if _in(m, bottom) and not _in(e.target, bottom) and e.target not in base]


# --------------------------------------------------------------------- the checker, checked


def _package(root: Path, files: dict[str, str]) -> Path:
    for rel, text in files.items():
        path = root / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return root / rel.split("/")[0]


def test_checker_finds_cycles_through_lazy_and_relative_imports(tmp_path):
    pkg = _package(tmp_path, {
        "toy/__init__.py": "",
        "toy/a.py": "from . import b\n",
        "toy/b.py": "import os\n\ndef f():\n    from .a import something\n",     # lazy: a cycle
        "toy/c.py": "from toy.sub import d\n",
        "toy/sub/__init__.py": "",
        "toy/sub/d.py": "class K:\n    from ..c import x\n",
        "toy/sub/e.py": "from .d import K\nimport numpy\n",                    # no cycle
        "toy/f.py": "import toy.g as g\n",
        "toy/g.py": "if True:\n    try:\n        from toy import f\n    except ImportError:\n"
                    "        pass\n",
    })
    graph = import_graph(pkg)
    assert sorted(graph) == ["toy", "toy.a", "toy.b", "toy.c", "toy.f", "toy.g", "toy.sub",
                             "toy.sub.d", "toy.sub.e"]
    assert find_cycles(graph) == [["toy.a", "toy.b", "toy.a"], ["toy.c", "toy.sub.d", "toy.c"],
                                  ["toy.f", "toy.g", "toy.f"]]
    text = format_cycle(graph, ["toy.a", "toy.b", "toy.a"])
    assert text == "toy.a -> toy.b (toy/a.py:1) -> toy.a (toy/b.py:4 (in a function))"


def test_checker_lists_every_elementary_cycle_of_a_component(tmp_path):
    pkg = _package(tmp_path, {
        "toy/__init__.py": "",
        "toy/a.py": "from . import b, c\n",
        "toy/b.py": "from . import a, c\n",
        "toy/c.py": "def f():\n    from . import a\n",
    })
    assert find_cycles(import_graph(pkg)) == [["toy.a", "toy.b", "toy.a"],
                                              ["toy.a", "toy.b", "toy.c", "toy.a"],
                                              ["toy.a", "toy.c", "toy.a"]]


def test_checker_finds_imports_from_the_bottom_layer_upward(tmp_path):
    pkg = _package(tmp_path, {
        "toy/__init__.py": "__version__ = '1'\n",
        "toy/errors.py": "class UserError(Exception):\n    pass\n",
        "toy/config.py": "from toy.geometry import x\n",                        # downward: fine
        "toy/stages/__init__.py": "",
        "toy/stages/s.py": "from ..geometry.x import f\nfrom ..io import y\n",  # downward: fine
        "toy/geometry/__init__.py": "",
        "toy/geometry/x.py": ("from toy.errors import UserError\nfrom toy import __version__\n"
                              "from . import z\nfrom ..io.y import read\n\n"
                              "def f():\n    from ..stages import s\n"),       # upward, lazily
        "toy/geometry/z.py": "",
        "toy/io/__init__.py": "",
        "toy/io/y.py": "from toy import errors, config\n",                     # config: upward
        "toy/geometry/_k.pyx": "import numpy as np\nfrom libc.math cimport sqrt\n"
                               "from toy.stages import s\n",                    # upward, Cython
    })
    graph = import_graph(pkg)
    bad = layering_violations(graph, ("toy.geometry", "toy.io"), ("toy", "toy.errors"))
    found = [(e.source, e.target, e.line, e.lazy) for e in bad]
    assert found == [("toy.geometry._k", "toy.stages.s", 3, False),
                     ("toy.geometry.x", "toy.stages.s", 7, True),
                     ("toy.io.y", "toy.config", 1, False)]
    # the upward imports close cycles too, each one listed
    assert find_cycles(graph) == [
        ["toy.config", "toy.geometry.x", "toy.io.y", "toy.config"],
        ["toy.config", "toy.geometry.x", "toy.stages.s", "toy.io.y", "toy.config"],
        ["toy.geometry.x", "toy.stages.s", "toy.geometry.x"]]


# ------------------------------------------------------------------------ the real package


def _pipeline_graph():
    return import_graph(REPO / PACKAGE)


def test_the_import_graph_of_pipeline_is_read():
    """The checker sees the package (so the two tests below cannot pass vacuously)."""
    graph = _pipeline_graph()
    assert {"pipeline.cli", "pipeline.geometry.sem", "pipeline.io.meshio",
            "pipeline.geometry._kernels"} <= set(graph)
    targets = {m: {e.target for e in edges} for m, edges in graph.items()}
    assert "pipeline.geometry.laplacian" in targets["pipeline.geometry.sem"]
    assert "pipeline.errors" in targets["pipeline.io.meshio"]
    assert "pipeline.geometry.sem" in targets["pipeline.stages.parameterize"]


def test_pipeline_has_no_import_cycles():
    graph = _pipeline_graph()
    cycles = find_cycles(graph)
    assert not cycles, f"{len(cycles)} import cycle(s) in pipeline:\n" + "\n".join(
        format_cycle(graph, c) for c in cycles)


def test_geometry_and_io_import_nothing_above_them():
    bad = layering_violations(_pipeline_graph())
    assert not bad, "pipeline.geometry / pipeline.io import from above them:\n" + "\n".join(
        f"{e.source} -> {e.target} ({e.where()})" for e in bad)
