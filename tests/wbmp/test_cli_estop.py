"""``wbmp solve --estop-at --faults``: the stop and the faults through the command, in its JSON report."""

from __future__ import annotations

import json
import signal
from pathlib import Path

import pytest

from wbmp.cli import main

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "specs"


@pytest.fixture(autouse=True)
def _no_compilation(monkeypatch, tmp_path):
    """The CLI builds solvers in memory here; the SIGUSR1 handler `wbmp solve` installs is undone after."""
    monkeypatch.setenv("WBMP_COMPILE", "0")
    monkeypatch.setenv("WBMP_CACHE_DIR", str(tmp_path / "cache"))
    old = signal.getsignal(signal.SIGUSR1)
    yield
    signal.signal(signal.SIGUSR1, old)


def test_stop_and_push_in_the_report(tmp_path, capsys):
    """The example squat with a 10 N s push and a stop request at 1 s: exit 5 (the motion did not
    complete), the report's certificate names the stop, the robot stood, and the figures count it."""
    faults = tmp_path / "faults.json"
    faults.write_text(json.dumps({"pushes": [{"t": 0.5, "impulse": 10, "direction": [0, 1, 0]}]}))
    code = main(["solve", "--spec", str(EXAMPLES / "squat.json"), "--estop-at", "1.0", "--faults", str(faults),
                 "--quiet", "--json"])
    captured = capsys.readouterr()
    assert code == 5, captured.err
    report = json.loads(captured.out)
    cert = report["certificate"]
    (stop,) = cert["stops"]
    assert (stop["trigger"], stop["response"], stop["stayed_up"]) == ("request", "stand", True)
    assert cert["reason"].startswith("E-stop at t = 1.000 s") and cert["figures"]["estop_count"] == 1
    kinds = [e["kind"] for e in report["events"]]
    assert "push" in kinds and "estop" in kinds
    assert report["cached"] is False
