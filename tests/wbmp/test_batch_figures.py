"""``wbmp batch``'s summary: the task success rate and the mean evaluation figures (docs/safety.md)."""

from __future__ import annotations

from sim.figures import FIGURES
from wbmp.batch.index import summary_text


def _record(i: int, status: str, work: float | None) -> dict:
    rec = {"id": f"m{i}", "robot": "talos", "status": status, "exit_code": 0 if status == "ok" else 5}
    if work is not None:
        rec["figures"] = {**{k: 1.0 for k in FIGURES}, "work": work, "estop_count": float(status != "ok")}
    return rec


def test_summary_has_the_success_rate_and_the_figures():
    """3 of 4 records ok: 75 %; the mean work of the three simulated ones (10, 20, 60 J: 30 J) and the E-stops summed."""
    records = [_record(0, "ok", 10.0), _record(1, "ok", 20.0), _record(2, "failed", 60.0), _record(3, "ok", None)]
    text = summary_text(records, title="t")
    assert "Task success rate: 75.0 % (4 records)." in text
    assert "| work | 30 | J |" in text and "| estop_count (total) | 1 | - |" in text
    assert "mean over the 3 simulated records" in text


def test_summary_without_figures_has_only_the_rate():
    text = summary_text([_record(0, "ok", None), _record(1, "failed", None)], title="t")
    assert "Task success rate: 50.0 %" in text and "Evaluation figures" not in text
