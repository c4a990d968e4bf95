"""Imports run one way (docs/architecture.md): a test parses every import and checks it.

Between packages, :data:`ALLOWED` says who may import whom. Inside a package the order is
learnt from the imports themselves (module-level and function-level; not the ones under
``if TYPE_CHECKING:``, which never run): the module graph must have no cycle, and inside
``planner/`` the subpackages follow :data:`PLANNER_ALLOWED`. Counting the ``TYPE_CHECKING``
imports too, there is no cycle either: a module that needs another's type takes data from below
it, not the object that imports it back.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("robots", "tasks", "language", "planner", "sim", "viz", "wbmp")
ALLOWED = {
    "robots": set(),
    "tasks": {"robots"},
    "language": {"tasks", "robots"},
    "planner": {"tasks", "robots"},
    "sim": {"planner", "tasks", "robots"},
    "viz": {"planner", "tasks", "robots", "sim", "language"},
    "wbmp": set(PACKAGES),
}
# inside planner/: the optimizer and the controller share the results and the exceptions only
PLANNER_ALLOWED = {
    "planner.exceptions": set(),
    "planner.results": set(),
    "planner.trajopt": {"planner.exceptions", "planner.results"},
    "planner.wbc": {"planner.exceptions", "planner.results"},
}


def _own_package(path: Path) -> str:
    return path.relative_to(ROOT).parts[0]


def imported_packages(path: Path, own: str | None = None) -> set[str]:
    """Top-level project packages imported by a Python file (absolute and relative imports)."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    out = set()
    own = own or _own_package(path)
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            names = [own] if node.level else [node.module or ""]
        else:
            continue
        out |= {n.split(".")[0] for n in names if n.split(".")[0] in PACKAGES}
    return out


def module_name(path: Path, root: Path = ROOT) -> str:
    """Dotted module name of a file under ``root`` (a package's ``__init__`` is the package)."""
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _runtime_imports(tree: ast.AST, type_checking: bool = False):
    """Import nodes that run: everywhere (functions included) except under ``if TYPE_CHECKING:``
    (those too with ``type_checking``)."""
    stack = [tree]
    while stack:
        node = stack.pop()
        if not type_checking and isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            stack.extend(node.orelse)
            continue
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            yield node
        stack.extend(ast.iter_child_nodes(node))


def imported_modules(source: str, module: str, is_package: bool, known: set[str],
                     type_checking: bool = False) -> set[str]:
    """Modules among ``known`` that the source of ``module`` imports (``from a import b``: the
    module ``a.b`` when it is one, else ``a``); with ``type_checking``, the imports under
    ``if TYPE_CHECKING:`` count too."""
    out = set()
    here = module.split(".") if is_package else module.split(".")[:-1]
    for node in _runtime_imports(ast.parse(source), type_checking):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        else:
            base = node.module or ""
            if node.level:
                anchor = here[: len(here) - (node.level - 1)]
                base = ".".join([*anchor, *([base] if base else [])])
            targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in known else base for a in node.names]
        for target in targets:
            while target and target not in known:  # `import a.b.c` of a name in a module
                target = target.rpartition(".")[0]
            if target and target != module:
                out.add(target)
    return out


def module_graph(package: str, root: Path = ROOT, type_checking: bool = False) -> dict[str, set[str]]:
    """Import graph of the modules of one top-level package: module -> modules it imports (with
    ``type_checking``, the imports under ``if TYPE_CHECKING:`` too)."""
    files = {module_name(p, root): p for p in sorted((root / package).rglob("*.py"))}
    known = set(files)
    return {m: imported_modules(p.read_text(encoding="utf-8"), m, p.name == "__init__.py", known, type_checking)
            for m, p in files.items()}


def find_cycle(graph: dict[str, set[str]]) -> list[str]:
    """The members of one import cycle, in import order (empty when there is none)."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    path: list[str] = []

    def visit(node: str) -> list[str]:
        state[node] = 1
        path.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return path[path.index(nxt):]
            if nxt not in state:
                found = visit(nxt)
                if found:
                    return found
        state[node] = 2
        path.pop()
        return []

    for start in sorted(graph):
        if start not in state:
            found = visit(start)
            if found:
                return found
    return []


def import_order(graph: dict[str, set[str]]) -> list[str]:
    """Modules ordered so that each comes after every module it imports (graph without cycles)."""
    order: list[str] = []
    done: set[str] = set()

    def visit(node: str) -> None:
        if node in done:
            return
        done.add(node)
        for nxt in sorted(graph.get(node, ())):
            visit(nxt)
        order.append(node)

    for node in sorted(graph):
        visit(node)
    return order


def test_layering():
    """No package imports one it must not (language -> tasks -> robots, etc.)."""
    bad = []
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            for dep in imported_packages(path) - ALLOWED[pkg] - {pkg}:
                bad.append(f"{path.relative_to(ROOT)} imports {dep}")
    assert not bad, "imports against the layering:\n" + "\n".join(bad)


def test_layering_check_detects_violation(tmp_path):
    """The checker itself flags a wrong-way import (so the test above can fail)."""
    fake = tmp_path / "robots" / "_layering_probe.py"  # a copy's layout, never the source tree
    fake.parent.mkdir()
    fake.write_text("import planner\nfrom . import model\n")
    assert imported_packages(fake, own="robots") == {"planner", "robots"}


def test_no_import_cycle_inside_a_package():
    """Inside every package the modules import each other one way (the order is learnt)."""
    cycles = []
    for pkg in PACKAGES:
        cycle = find_cycle(module_graph(pkg))
        if cycle:
            cycles.append(f"{pkg}: " + " -> ".join([*cycle, cycle[0]]))
    assert not cycles, "import cycles:\n" + "\n".join(cycles)


def test_no_import_cycle_even_counting_type_checking_imports():
    """Inside every package the modules import each other one way even for their types (the
    imports under ``if TYPE_CHECKING:`` counted): no module takes an object whose module imports it."""
    cycles = []
    for pkg in PACKAGES:
        cycle = find_cycle(module_graph(pkg, type_checking=True))
        if cycle:
            cycles.append(f"{pkg}: " + " -> ".join([*cycle, cycle[0]]))
    assert not cycles, "import cycles through TYPE_CHECKING imports:\n" + "\n".join(cycles)


def test_planner_subpackages_one_way():
    """planner.trajopt and planner.wbc share only planner.results and planner.exceptions."""
    graph = module_graph("planner")

    def part(module: str) -> str | None:
        return next((p for p in PLANNER_ALLOWED if module == p or module.startswith(p + ".")), None)

    bad = [f"{m} imports {d}" for m, deps in graph.items() for d in deps
           if part(m) and part(d) and part(d) != part(m) and part(d) not in PLANNER_ALLOWED[part(m)]]
    assert not bad, "imports against planner's layering:\n" + "\n".join(bad)
    order = import_order(graph)
    assert order.index("planner.trajopt.layout") < order.index("planner.trajopt.transcription") < \
        order.index("planner.trajopt.centroidal.layout") < order.index("planner.trajopt.api")


def test_cycle_checker_on_a_synthetic_graph():
    """The checker reports a cycle with its members, and none in a graph without one."""
    graph = {"p.a": {"p.b"}, "p.b": {"p.c"}, "p.c": {"p.a", "p.d"}, "p.d": set()}
    assert find_cycle(graph) == ["p.a", "p.b", "p.c"]
    del graph["p.c"]
    graph["p.c"] = {"p.d"}
    assert find_cycle(graph) == []
    assert import_order(graph) == ["p.d", "p.c", "p.b", "p.a"]


def test_module_graph_reads_function_level_and_relative_imports():
    """Function-level and relative imports are edges; imports under TYPE_CHECKING are not."""
    known = {"p", "p.a", "p.b", "p.c", "p.sub", "p.sub.d"}
    source = ("from typing import TYPE_CHECKING\nfrom . import b\nif TYPE_CHECKING:\n    from p.c import X\n"
              "def f():\n    from .sub.d import g\n    import p.c as c\n")
    assert imported_modules(source, "p.a", False, known) == {"p.b", "p.sub.d", "p.c"}
    typed = "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from p.c import X\n"
    assert imported_modules(typed, "p.a", False, known) == set()
    assert imported_modules(typed, "p.a", False, known, type_checking=True) == {"p.c"}
    assert imported_modules("from .sub import d\n", "p", True, known) == {"p.sub.d"}
