"""meshcat, imported once without its import-time DeprecationWarning (pyzmq under numpy 2)."""

from __future__ import annotations

import warnings

with warnings.catch_warnings():
    warnings.simplefilter("ignore", DeprecationWarning)
    import meshcat
    import meshcat.geometry as mg
    import umsgpack
    import zmq

__all__ = ["meshcat", "mg", "umsgpack", "zmq"]
