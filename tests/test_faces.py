"""Packages talk through their faces (docs/architecture.md): an import from another package names
the package itself (``from robots import Robot``), whose ``__init__`` lists the public names,
never one of its modules (``from robots.model import Robot``).

``tests/test_layering.py`` checks which package may import which; this test checks how: every
runtime import of another package names its face. Imports under ``if TYPE_CHECKING:`` do not
count (they never run), nor do imports inside a package.
"""

from __future__ import annotations

import ast
from pathlib import Path

from tests.test_layering import PACKAGES, ROOT, _runtime_imports


def bypasses(root: Path = ROOT) -> set[tuple[str, str]]:
    """(file, module) of every runtime import of another package's module (not its face)."""
    out = set()
    for pkg in PACKAGES:
        for path in sorted((root / pkg).rglob("*.py")):
            tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
            for node in _runtime_imports(tree):
                if isinstance(node, ast.ImportFrom):
                    modules = [] if node.level else [node.module or ""]
                else:
                    modules = [a.name for a in node.names]
                for m in modules:
                    top = m.split(".")[0]
                    if top in PACKAGES and top != pkg and m != top:
                        out.add((path.relative_to(root).as_posix(), m))
    return out


def test_every_import_of_another_package_goes_through_its_face():
    found = sorted(bypasses())
    assert not found, ("imports that bypass a package's face (import the name from the package; add it to "
                       "its __init__ if it is public):\n" + "\n".join(f"  {f}: import of {m}" for f, m in found))


def test_the_checker_sees_a_bypass_and_a_face(tmp_path):
    """The parser finds ``from robots.model import Robot`` in a function, ignores ``from robots
    import Robot``, an import inside the package and one under ``if TYPE_CHECKING:``."""
    for pkg in PACKAGES:
        (tmp_path / pkg).mkdir()
    (tmp_path / "tasks" / "a.py").write_text(
        "from typing import TYPE_CHECKING\nfrom robots import Robot\nfrom tasks.specs import TaskSpec\n"
        "if TYPE_CHECKING:\n    from robots.profile import RobotProfile\n"
        "def f():\n    from robots.model import load_robot\n    import planner.wbc\n", encoding="utf-8")
    assert bypasses(tmp_path) == {("tasks/a.py", "robots.model"), ("tasks/a.py", "planner.wbc")}


def test_no_public_name_of_a_lazy_face_is_also_a_module_of_its_package():
    """``from tasks import bind`` must give the function: once a submodule ``tasks.bind`` is
    imported, Python sets the package's attribute ``bind`` to that module and the lazy face's
    ``__getattr__`` is never asked (the function must live in a module of another name)."""
    clashes = []
    for init in sorted(i for pkg in PACKAGES for i in (ROOT / pkg).rglob("__init__.py")):
        tree = ast.parse(init.read_text(encoding="utf-8"))
        names: set[str] = set()
        for node in tree.body:
            if isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id in ("_EXPORTS", "_LAZY")
                                                    for t in node.targets) and isinstance(node.value, ast.Dict):
                names |= {k.value for k in node.value.keys if isinstance(k, ast.Constant)}
        folder = init.parent
        modules = {p.stem for p in folder.glob("*.py")} | {p.name for p in folder.iterdir() if (p / "__init__.py").is_file()}
        clashes += [f"{folder.relative_to(ROOT).as_posix()}: {n}" for n in sorted(names & modules)]
    assert not clashes, "a face name that is also a module of its package: " + ", ".join(clashes)
