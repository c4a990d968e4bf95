"""Fixtures of the CLI tests: the synthetic plan and execution of the viz tests (no solver)."""

from tests.viz.conftest import synth_execution, synth_plan  # noqa: F401 - fixtures shared with tests/viz
