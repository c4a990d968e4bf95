"""Packaging: every import package is listed in pyproject.toml; constraints.txt pins every dependency."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

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


LOCK = ROOT / "constraints.txt"


def _lock_pins(path: Path = LOCK) -> dict[str, str]:
    """Canonical name -> exact version of every line of the lock (comments skipped)."""
    from packaging.utils import canonicalize_name

    pins = {}
    for n, raw in enumerate(path.read_text().splitlines(), 1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        name, sep, version = line.partition("==")
        assert sep and name.strip() and version.strip() and not any(c in line for c in " ;@<>~!,"), (
            f"{path.name}:{n}: {raw!r} is not an exact `name==version` pin"
        )
        key = canonicalize_name(name)
        assert key not in pins, f"{path.name}:{n}: {name} is pinned twice"
        pins[key] = version
    return pins


def test_lock_pins_every_dependency_at_or_above_its_lower_bound():
    """`make` installs from constraints.txt: each runtime and test dependency of pyproject.toml
    is pinned there with `==` to a version that pyproject's bound admits, and the lock holds
    neither the project itself nor pip's build tools."""
    from packaging.requirements import Requirement
    from packaging.utils import canonicalize_name
    from packaging.version import Version

    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    pins = _lock_pins()
    assert canonicalize_name(project["name"]) not in pins, "the lock must not pin the project itself"
    assert not {"setuptools", "wheel"} & set(pins), "build tools come from [build-system], not the lock"
    required = [Requirement(r) for r in project["dependencies"]]
    required += [Requirement(r) for extra in project["optional-dependencies"].values() for r in extra]
    assert len(required) >= 10
    for req in required:
        name = canonicalize_name(req.name)
        assert name in pins, f"{req.name} ({req}) is not pinned in {LOCK.name}: run `make lock`"
        assert req.specifier.contains(Version(pins[name]), prereleases=True), (
            f"{LOCK.name} pins {req.name}=={pins[name]}, outside pyproject's {req.specifier}"
        )
        assert any(s.operator == ">=" for s in req.specifier), f"{req}: pyproject.toml keeps a lower bound"


def test_lock_parser_refuses_loose_pins(tmp_path):
    """The check above cannot pass on a lock with a range, a URL or a package pinned twice."""
    bad = tmp_path / "constraints.txt"
    for text, fragment in (("numpy>=2.0\n", "not an exact"), ("numpy==2.0\nNumPy==2.1\n", "pinned twice"),
                           ("wbmp @ file:///x\n", "not an exact"), ("pin==4.1.0 ; python_version<'3'\n", "not an exact")):
        bad.write_text(text)
        with pytest.raises(AssertionError, match=fragment):
            _lock_pins(bad)
    bad.write_text("# comment\n\nNumPy==2.4.6  # why\n")
    assert _lock_pins(bad) == {"numpy": "2.4.6"}
