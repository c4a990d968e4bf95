"""``python -m wbmp``: the same as the ``wbmp`` console script."""

from wbmp.cli import run

run()
