"""The newcomer's pages cannot rot: every file and folder they name exists, and every package is
on the map.

``docs/architecture.md`` is the map of the code and ``docs/notation.md`` its conventions; a module
renamed or moved without the page would send a newcomer to a file that is not there. The paths
are read from the pages' code spans (`like/this.py`), the code blocks' tree lines and the paths
written out in code blocks, so the test knows nothing of the pages beyond their own words.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = ("docs/architecture.md", "docs/notation.md")
PACKAGES = ("robots", "tasks", "language", "planner", "sim", "viz", "wbmp")
SUFFIXES = (".py", ".md", ".json", ".toml", ".html")
# `a/b.py`, `docs/x.md`, `wbmp/serve/` (a folder ends with a slash); placeholders such as
# `wbmp/commands/<name>.py` are checked by their folder
_SPAN = re.compile(r"`([^`\s]+)`")


def named_paths(text: str) -> set[str]:
    """Repository paths named in the page's code spans: a slash and a known suffix, or a folder."""
    out = set()
    for token in _SPAN.findall(text):
        token = token.rstrip(".,;:")
        if "/" not in token or "://" in token or token.startswith(("~", "$", "-")):
            continue
        if token.endswith("/") or token.endswith(SUFFIXES):
            out.add(token)
    return out


def tree_paths(text: str) -> set[str]:
    """Paths of the ``planner/`` tree block: each indented name under its folder."""
    out: set[str] = set()
    for block in re.findall(r"```\n(.*?)```", text, flags=re.S):
        lines = block.splitlines()
        if not lines or not re.fullmatch(r"[a-z_]+/", lines[0].strip()):
            continue
        stack = [(0, lines[0].strip())]
        for line in lines[1:]:
            indent = len(line) - len(line.lstrip())
            first = line.strip().split("  ")[0].strip()
            if not first or not re.fullmatch(r"[a-z_]+(/|\.py)(, [a-z_]+\.py)*", first):
                continue  # a continuation of the previous line's description
            while stack and stack[-1][0] >= indent:
                stack.pop()
            parent = "".join(name for _, name in stack)
            for name in first.split(", "):
                out.add(parent + name)
            if first.endswith("/"):
                stack.append((indent, first))
    return out


def block_paths(text: str) -> set[str]:
    """Paths written out in the code blocks (the flow diagram's ``language/parse.py``)."""
    out: set[str] = set()
    for block in re.findall(r"```\n(.*?)```", text, flags=re.S):
        out |= set(re.findall(r"(?<![\w/.])(?:[a-z_]+/)+[a-z_]+\.py\b", block))
    return out


def _exists(path: str) -> bool:
    if "<" in path:  # a placeholder: its folder must exist
        return (ROOT / path.split("<")[0]).is_dir()
    target = ROOT / path
    return target.is_dir() if path.endswith("/") else target.is_file()


@pytest.mark.parametrize("page", PAGES)
def test_every_named_path_exists(page: str) -> None:
    text = (ROOT / page).read_text(encoding="utf-8")
    paths = named_paths(text) | tree_paths(text) | block_paths(text)
    assert len(paths) > 10, f"{page}: the path reader found almost nothing ({sorted(paths)})"
    missing = sorted(p for p in paths if not _exists(p))
    assert not missing, f"{page} names files that do not exist: {missing}"


def test_the_path_reader_sees_a_missing_file() -> None:
    """The reader itself: a wrong path in a span and in a tree line are both reported."""
    text = ("see `planner/trajopt/nosuch.py` and `docs/cli.md`\n```\nplanner/\n  gone.py  text\n```\n"
            "```\nPlan   sim/loop.py   sim/lost.py\n```\n")
    paths = named_paths(text) | tree_paths(text) | block_paths(text)
    assert paths == {"planner/trajopt/nosuch.py", "docs/cli.md", "planner/gone.py", "sim/loop.py", "sim/lost.py"}
    assert [p for p in sorted(paths) if not _exists(p)] == ["planner/gone.py", "planner/trajopt/nosuch.py",
                                                            "sim/lost.py"]


def test_every_package_is_on_the_map() -> None:
    """Each import package (a folder with an ``__init__.py``) is named on the architecture page."""
    text = (ROOT / "docs/architecture.md").read_text(encoding="utf-8")
    named = named_paths(text) | tree_paths(text)
    folders = {p.rstrip("/") for p in named if p.endswith("/")} | {str(Path(p).parent) for p in named}
    packages = sorted(str(init.parent.relative_to(ROOT)) for top in PACKAGES
                      for init in (ROOT / top).rglob("__init__.py"))
    assert len(packages) >= len(PACKAGES)
    unmapped = [p for p in packages if p not in folders and f"`{p}`" not in text]
    assert not unmapped, f"docs/architecture.md does not name these packages: {unmapped}"


def test_every_command_is_on_the_map() -> None:
    """Each ``wbmp`` subcommand's module is named on the architecture page or its job is."""
    from wbmp.cli import COMMANDS

    text = (ROOT / "docs/architecture.md").read_text(encoding="utf-8")
    unmapped = [c for c in COMMANDS if f"wbmp {c}" not in text and f"wbmp/commands/{c}.py" not in text]
    assert not unmapped, f"docs/architecture.md does not mention these commands: {unmapped}"
