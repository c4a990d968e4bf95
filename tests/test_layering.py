"""Imports run one way (DESIGN.md section 2): a test parses every import and checks it."""

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


def imported_packages(path: Path) -> set[str]:
    """Top-level project packages imported by a Python file (absolute and relative imports)."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    out = set()
    own = path.relative_to(ROOT).parts[0]
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            names = [own] if node.level else [node.module or ""]
        else:
            continue
        out |= {n.split(".")[0] for n in names if n.split(".")[0] in PACKAGES}
    return out


def test_layering():
    """No package imports one it must not (language -> tasks -> robots, etc.)."""
    bad = []
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            for dep in imported_packages(path) - ALLOWED[pkg] - {pkg}:
                bad.append(f"{path.relative_to(ROOT)} imports {dep}")
    assert not bad, "imports against the layering:\n" + "\n".join(bad)


def test_layering_check_detects_violation(tmp_path, monkeypatch):
    """The checker itself flags a wrong-way import (so the test above can fail)."""
    fake = ROOT / "robots" / "_layering_probe.py"
    fake.write_text("import planner\n")
    try:
        assert "planner" in imported_packages(fake)
    finally:
        fake.unlink()
