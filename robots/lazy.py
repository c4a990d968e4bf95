"""One lazy public face for every package: a public name is imported from its module on first
access, so ``import planner`` (or ``sim``, ``tasks``, ...) loads neither CasADi nor MuJoCo until a
name that needs them is used.

A package's ``__init__.py`` lists its public names and the module of each, then::

    __getattr__, __dir__ = lazy_face(__name__, _EXPORTS)

This module lives in ``robots/``, the lowest layer, so every package may import it; it imports
nothing but the standard library.
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Mapping
from typing import Any


def lazy_face(package: str, exports: Mapping[str, str]) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """The module ``__getattr__`` and ``__dir__`` of ``package`` whose public names are the keys of
    ``exports`` (name -> the module that defines it). A name is imported on first access and kept
    in the package's namespace, so later accesses skip ``__getattr__``; an unknown name raises
    AttributeError as a module does."""

    def __getattr__(name: str) -> Any:
        module = exports.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(module), name)
        setattr(sys.modules[package], name, value)
        return value

    def __dir__() -> list[str]:
        return sorted({*vars(sys.modules[package]), *exports})

    return __getattr__, __dir__
