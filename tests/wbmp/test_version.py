"""``wbmp --version`` prints ``wbmp.__version__``, the one place the version is written:
pyproject.toml reads it at build time, statically (setuptools' ``attr:`` needs a literal)."""

from __future__ import annotations

import ast
import tomllib
from pathlib import Path

import pytest

import wbmp
from wbmp.cli import main

REPO = Path(__file__).resolve().parents[2]


def test_version_is_a_literal_that_pyproject_reads():
    project = tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))
    assert "version" in project["project"]["dynamic"] and "version" not in project["project"]
    assert project["tool"]["setuptools"]["dynamic"]["version"] == {"attr": "wbmp.__version__"}
    tree = ast.parse((REPO / "wbmp" / "__init__.py").read_text(encoding="utf-8"))
    literals = [node.value.value for node in tree.body if isinstance(node, ast.Assign)
                and [getattr(t, "id", None) for t in node.targets] == ["__version__"]
                and isinstance(node.value, ast.Constant)]
    assert literals == [wbmp.__version__]
    from packaging.version import Version

    assert str(Version(wbmp.__version__)) == wbmp.__version__


def test_version_option_prints_it(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["--version"])
    assert exit_info.value.code == 0
    assert capsys.readouterr().out.strip() == f"wbmp {wbmp.__version__}"

