"""Packages talk through their faces (docs/architecture.md): an import from another package names
the package itself (``from robots import Robot``), whose ``__init__`` lists the public names,
never one of its modules (``from robots.model import Robot``).

The imports that still reach into another package's modules are listed in
``tests/faces_bypasses.txt``; the list may only shrink. A new one fails (import the name from the
package, adding it to the package's ``__init__`` if it is public); one that is gone must be
deleted from the list, so the count recorded there is the count in the code. Imports under
``if TYPE_CHECKING:`` do not count (they never run), nor do imports inside a package.
"""

from __future__ import annotations

import ast
from pathlib import Path

from tests.test_layering import PACKAGES, ROOT, _runtime_imports

ALLOWLIST = Path(__file__).with_name("faces_bypasses.txt")


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


def allowed() -> set[tuple[str, str]]:
    """The recorded bypasses: ``file -> module`` lines (``#`` comments)."""
    out = set()
    for line in ALLOWLIST.read_text(encoding="utf-8").splitlines():
        line = line.split("#", 1)[0].strip()
        if line:
            file, module = (part.strip() for part in line.split("->"))
            out.add((file, module))
    return out


def test_no_new_import_bypasses_a_face():
    new = sorted(bypasses() - allowed())
    assert not new, ("imports that bypass a package's face (import the name from the package; add it to "
                     "its __init__ if it is public):\n" + "\n".join(f"  {f}: import of {m}" for f, m in new))


def test_the_list_of_bypasses_only_shrinks():
    gone = sorted(allowed() - bypasses())
    assert not gone, ("these bypasses are gone: delete their lines from tests/faces_bypasses.txt:\n"
                      + "\n".join(f"  {f} -> {m}" for f, m in gone))


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
