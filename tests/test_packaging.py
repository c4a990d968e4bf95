"""Packaging: every import package of the project is listed in pyproject.toml."""

from __future__ import annotations

import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TOP = ("planner", "tasks", "robots", "language", "viz", "sim", "wbmp")


def test_every_package_is_listed():
    """A sub-package missing from the explicit list would be absent from a non-editable install."""
    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    found = {
        ".".join(p.parent.relative_to(ROOT).parts)
        for top in TOP
        for p in (ROOT / top).rglob("__init__.py")
    }
    assert found <= listed, f"add to [tool.setuptools] packages: {sorted(found - listed)}"


def test_data_files_are_declared():
    """Data files the code reads at run time are declared as package data."""
    data = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]
    for pkg, patterns in data.items():
        folder = ROOT.joinpath(*pkg.split("."))
        assert any(any(folder.glob(p)) for p in patterns), f"{pkg}: no file matches {patterns}"
