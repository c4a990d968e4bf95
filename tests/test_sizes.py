"""Sizes (issue 31): no module of the packages over 800 lines, no function over 100.

Lines are physical lines: a module's are its newline count (what ``wc -l`` says); a function's
run from its first decorator (or its ``def``) to its last line, nested functions included in
their parent's count (and counted on their own too). :data:`FUNCTION_ALLOWLIST` is empty: no
function is over the limit; an entry added there could only shrink (the test fails when one
grows, when a function not listed goes over, or when a listed one is gone or back under the
limit).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("robots", "tasks", "language", "planner", "sim", "viz", "wbmp")
MAX_MODULE_LINES = 800
MAX_FUNCTION_LINES = 100

# "path::Class.function": lines today. Each must only shrink; split it and remove its entry.
FUNCTION_ALLOWLIST: dict[str, int] = {}  # empty since session 15: keep it so


def module_lines(source: str) -> int:
    """Physical lines of a module (its newlines, as ``wc -l`` counts)."""
    return source.count("\n")


def function_lengths(source: str) -> dict[str, int]:
    """Qualified name (``Class.method``, ``outer.inner``) -> lines of every function of a module."""
    out: dict[str, int] = {}

    def walk(node: ast.AST, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef):
                start = min([child.lineno] + [d.lineno for d in child.decorator_list])
                name = prefix + child.name
                out[name] = max(out.get(name, 0), int(child.end_lineno or child.lineno) - start + 1)
                walk(child, name + ".")
            elif isinstance(child, ast.ClassDef):
                walk(child, prefix + child.name + ".")
            else:
                walk(child, prefix)

    walk(ast.parse(source), "")
    return out


def package_files() -> list[Path]:
    return sorted(p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py"))


def test_the_measures_count_lines_as_written():
    """The measures against sources whose sizes are known by construction."""
    body = "".join(f"    x{i} = {i}\n" for i in range(99))
    source = (
        "import functools\n\n\n"
        "@functools.cache\n"  # the decorator counts: 1 + def + 99 + return = 102
        f"def long(a):\n{body}    return a\n\n\n"
        "class K:\n"
        "    def short(self):\n"
        "        def inner():\n"
        "            return 1\n"
        "        return inner()\n"
    )
    assert module_lines(source) == source.count("\n") == 3 + 102 + 2 + 5
    assert function_lengths(source) == {"long": 102, "K.short": 4, "K.short.inner": 2}
    assert module_lines("a = 1\nb = 2\n") == 2


def test_the_packages_are_scanned():
    files = package_files()
    assert {p.relative_to(ROOT).parts[0] for p in files} == set(PACKAGES)
    assert len(files) > 100


@pytest.mark.parametrize("package", PACKAGES)
def test_no_module_over_800_lines(package):
    over = {
        str(p.relative_to(ROOT)): n
        for p in sorted((ROOT / package).rglob("*.py"))
        if (n := module_lines(p.read_text(encoding="utf-8"))) > MAX_MODULE_LINES
    }
    assert not over, f"modules over {MAX_MODULE_LINES} lines (split them by concern): {over}"


def test_no_function_over_100_lines_but_the_allowlisted_ones_which_only_shrink():
    found = {}
    for path in package_files():
        rel = path.relative_to(ROOT).as_posix()
        for name, n in function_lengths(path.read_text(encoding="utf-8")).items():
            if n > MAX_FUNCTION_LINES:
                found[f"{rel}::{name}"] = n
    new = {k: n for k, n in found.items() if k not in FUNCTION_ALLOWLIST}
    grown = {k: (FUNCTION_ALLOWLIST[k], n) for k, n in found.items()
             if k in FUNCTION_ALLOWLIST and n > FUNCTION_ALLOWLIST[k]}
    stale = sorted(set(FUNCTION_ALLOWLIST) - set(found))
    assert not new, f"functions over {MAX_FUNCTION_LINES} lines (extract helpers): {new}"
    assert not grown, f"allowlisted functions grew (allowed, now): {grown}; they may only shrink"
    assert not stale, f"allowlisted functions gone or now <= {MAX_FUNCTION_LINES} lines: remove {stale}"
