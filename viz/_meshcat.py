"""meshcat, imported once without its import-time DeprecationWarning (pyzmq under numpy 2), in two
weights.

``mg`` (``meshcat.geometry``), ``commands``, ``Path`` and ``umsgpack`` load only meshcat's
geometry, command and path modules: all that drawing a scene into a recording needs (the HTML
replay, :class:`viz.html.RecordingVisualizer`). ``meshcat`` (the package: its ``Visualizer``,
ZMQ server, IPython, tornado and PIL, ~0.3 s of a ``wbmp solve --html``) and ``zmq`` are
imported on first use (``from viz._meshcat import meshcat``). The light modules are the ones the
full package uses later (the same classes): the package's ``__init__`` is only deferred.
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
import warnings
from typing import TYPE_CHECKING, Any

import umsgpack


def _import_light() -> None:
    """Import meshcat.geometry, meshcat.commands and meshcat.path without running meshcat's
    ``__init__`` (which imports its server): a not yet executed package module stands in while
    they load, and is removed again, so ``import meshcat`` later runs the real ``__init__``,
    which picks the loaded submodules up from ``sys.modules``."""
    if "meshcat" in sys.modules:
        for name in ("meshcat.geometry", "meshcat.commands", "meshcat.path"):
            importlib.import_module(name)
        return
    spec = importlib.util.find_spec("meshcat")
    if spec is None or spec.submodule_search_locations is None:
        raise ModuleNotFoundError("No module named 'meshcat' (pip install meshcat)", name="meshcat")
    package = importlib.util.module_from_spec(spec)  # its __path__, not its __init__
    sys.modules["meshcat"] = package
    try:
        for name in ("meshcat.geometry", "meshcat.commands", "meshcat.path"):
            importlib.import_module(name)
    finally:
        if sys.modules.get("meshcat") is package:
            del sys.modules["meshcat"]


_import_light()
if TYPE_CHECKING:
    import meshcat
    import meshcat.commands as commands
    import meshcat.geometry as mg
    import zmq
    from meshcat.path import Path
else:
    mg = sys.modules["meshcat.geometry"]
    commands = sys.modules["meshcat.commands"]
    Path = sys.modules["meshcat.path"].Path


def _full(name: str) -> Any:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        return importlib.import_module(name)


def __getattr__(name: str) -> Any:
    if name in ("meshcat", "zmq"):
        module = _full(name)
        globals()[name] = module
        return module
    raise AttributeError(f"module 'viz._meshcat' has no attribute {name!r}")


__all__ = ["Path", "commands", "meshcat", "mg", "umsgpack", "zmq"]
