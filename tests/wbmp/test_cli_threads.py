"""The console script pins BLAS threads to 1 unless the user chose a number."""

from __future__ import annotations

import os
import sys

import pytest

from wbmp import cli


@pytest.mark.parametrize("preset", [None, "3"])
def test_console_script_sets_thread_defaults(monkeypatch, capsys, preset):
    """Unset thread variables become 1 before any library loads BLAS; a user's value is kept."""
    for name in cli._THREAD_VARIABLES:
        if preset is None:
            monkeypatch.delenv(name, raising=False)
        else:
            monkeypatch.setenv(name, preset)
    monkeypatch.setattr(sys, "argv", ["wbmp", "--version"])
    with pytest.raises(SystemExit) as exit_info:
        cli.run()
    assert exit_info.value.code == 0
    assert "wbmp" in capsys.readouterr().out
    for name in cli._THREAD_VARIABLES:
        assert os.environ[name] == (preset or "1")
