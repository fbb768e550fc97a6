"""The import graph of the installed package (`gwr_predictor/` and its nodes) has no cycle, neither
between modules nor between subpackages, and a function imports only what is heavy to load and
needed by few (a plotting, rendering, simulator or video library), never a module of the package
to dodge a cycle.

`python test/test_import_graph.py` prints the cycles and the function-level imports it finds.
"""

from __future__ import annotations

import ast
import functools
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = "gwr_predictor"

#: What a function may import on use: libraries that cost a noticeable start-up (or a C extension, a
#: binary search) that only a plot, a video or the simulator needs.
HEAVY_OPTIONAL = {"matplotlib", "PIL", "pybullet", "pybullet_data", "imageio_ffmpeg", "torch"}

@dataclass(frozen=True)
class Import:
    importer: str  # dotted name of the module that imports
    line: int
    targets: tuple[str, ...]  # dotted names imported (a module, or a module's name)
    in_function: bool

    @property
    def top(self) -> set[str]:
        return {t.split(".")[0] for t in self.targets}


def package_modules(root: Path = ROOT) -> dict[str, Path]:
    """{dotted name: file} of every module installed as `gwr_predictor` (nodes/ as `gwr_predictor.nodes`)."""
    modules = {}
    for base, prefix in ((root / PACKAGE, PACKAGE), (root / "nodes", f"{PACKAGE}.nodes")):
        for path in sorted(base.rglob("*.py")):
            parts = path.relative_to(base).with_suffix("").parts
            if parts[-1] == "__init__":
                parts = parts[:-1]
            modules[".".join((prefix, *parts))] = path
    return modules


def _imports_of(name: str, path: Path) -> list[Import]:
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found: list[Import] = []

    def visit(node: ast.AST, in_function: bool) -> None:
        for child in ast.iter_child_nodes(node):
            inside = in_function or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda))
            if isinstance(child, ast.Import):
                found.append(Import(name, child.lineno, tuple(a.name for a in child.names), in_function))
            elif isinstance(child, ast.ImportFrom):
                base = child.module or ""
                if child.level:
                    anchor = package.rsplit(".", child.level - 1)[0] if child.level > 1 else package
                    base = f"{anchor}.{base}" if base else anchor
                found.append(Import(name, child.lineno, (base, *(f"{base}.{a.name}" for a in child.names)),
                                    in_function))
            visit(child, inside)

    visit(ast.parse(path.read_text(encoding="utf-8")), False)
    return found


@functools.cache
def all_imports(root: Path = ROOT) -> tuple[Import, ...]:
    return tuple(imp for name, path in package_modules(root).items() for imp in _imports_of(name, path))


def module_graph(root: Path = ROOT) -> dict[str, set[str]]:
    """{module: modules of the package it imports at module level}, a `TYPE_CHECKING` import included.

    Importing `a.b.c` runs `a/__init__` and `a/b/__init__` first, so those are edges too, but for the
    importer's own packages, which are always initialised before it."""
    return _graph(package_modules(root), all_imports(root))


def _graph(modules: dict[str, Path], imports: tuple[Import, ...]) -> dict[str, set[str]]:
    graph: dict[str, set[str]] = {name: set() for name in modules}
    for imp in imports:
        if imp.in_function:
            continue
        for target in imp.targets:
            parts = target.split(".")
            for i in range(1, len(parts) + 1):
                dep = ".".join(parts[:i])
                own_package = imp.importer.startswith(dep + ".")
                if dep in modules and dep != imp.importer and not own_package:
                    graph[imp.importer].add(dep)
    return graph


def part_of(module: str) -> str:
    """The part of the package a module belongs to: its subpackage (`gwr_predictor.data`), the nodes,
    or the module itself for one at the top (`gwr_predictor.errors`)."""
    return ".".join(module.split(".")[:2])


def subpackage_graph(root: Path = ROOT) -> dict[str, set[str]]:
    """`module_graph` with each module replaced by its part (imports inside one part dropped)."""
    graph: dict[str, set[str]] = {}
    for module, deps in module_graph(root).items():
        part = part_of(module)
        graph.setdefault(part, set()).update(part_of(d) for d in deps if part_of(d) not in (part, PACKAGE))
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def connect(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                connect(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            connect(v)
    return sorted(found)


def function_level_imports(root: Path = ROOT) -> list[str]:
    """`module:line imported` for each import inside a function that is not of a heavy optional library
    """
    return [f"{imp.importer}:{imp.line} {imp.targets[0]}" for imp in all_imports(root)
            if imp.in_function and not imp.top <= HEAVY_OPTIONAL]


def test_no_module_imports_itself_back():
    found = cycles(module_graph())
    assert not found, "import cycles between modules:\n" + "\n".join(" <-> ".join(c) for c in found)


def test_no_subpackage_imports_itself_back():
    """data -> pipeline -> data is no cycle of modules, but two subpackages that each need the other."""
    found = cycles(subpackage_graph())
    assert not found, "import cycles between subpackages:\n" + "\n".join(" <-> ".join(c) for c in found)


def test_functions_import_only_heavy_optional_libraries():
    found = function_level_imports()
    assert not found, "imports inside functions (move them to the top of the module):\n" + "\n".join(found)


def research_modules(root: Path = ROOT) -> dict[str, Path]:
    """{dotted name: file} of the research part of the repository (research/, not installed)."""
    modules = {}
    for path in sorted((root / "research").rglob("*.py")):
        parts = path.relative_to(root).with_suffix("").parts
        modules[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return modules


def test_research_has_no_cycle_and_imports_the_package_and_itself_at_the_top():
    """The research code follows the package's rule: a function imports only a heavy optional library."""
    modules = research_modules()
    imports = tuple(imp for name, path in modules.items() for imp in _imports_of(name, path))
    lazy = [f"{imp.importer}:{imp.line} {imp.targets[0]}" for imp in imports
            if imp.in_function and imp.top & {PACKAGE, "research"}]
    assert not lazy, "imports of the package or research inside functions:\n" + "\n".join(lazy)
    found = cycles(_graph(modules, imports))
    assert not found, "import cycles in research:\n" + "\n".join(" <-> ".join(c) for c in found)


def test_the_graph_sees_a_cycle_and_a_function_level_import(tmp_path):
    """The checks above can fail: a two-module package with a cycle and a lazy import is caught."""
    (tmp_path / PACKAGE).mkdir()
    (tmp_path / "nodes").mkdir()
    (tmp_path / PACKAGE / "__init__.py").write_text("")
    (tmp_path / PACKAGE / "a.py").write_text("from gwr_predictor.b import f\n")
    (tmp_path / PACKAGE / "b.py").write_text("from . import a\n\ndef f():\n    import json\n    import PIL.Image\n")
    for part in ("c", "d"):
        (tmp_path / PACKAGE / part).mkdir()
        (tmp_path / PACKAGE / part / "__init__.py").write_text("")
    (tmp_path / PACKAGE / "c" / "x.py").write_text("from gwr_predictor.d.y import g\n")
    (tmp_path / PACKAGE / "d" / "z.py").write_text("from gwr_predictor.c import x\n")
    assert cycles(module_graph(tmp_path)) == [["gwr_predictor.a", "gwr_predictor.b"]]
    assert cycles(subpackage_graph(tmp_path)) == [["gwr_predictor.a", "gwr_predictor.b"],
                                                  ["gwr_predictor.c", "gwr_predictor.d"]]
    assert function_level_imports(tmp_path) == ["gwr_predictor.b:4 json"]


if __name__ == "__main__":
    for name, graph in (("modules", module_graph()), ("subpackages", subpackage_graph())):
        print(f"cycles between {name} (module-level imports):")
        for component in cycles(graph):
            print("  " + " <-> ".join(component))
    print("function-level imports that are not of a heavy optional library:")
    for line in function_level_imports():
        print("  " + line)
