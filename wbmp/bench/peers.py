"""Peer results (Crocoddyl, TSID) made by ``make bench-peers``, and the ratios ours/peer."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from wbmp.bench.tasks import PEER_TASKS


def default_peers_dir() -> Path:
    """``benchmarks/results/peers`` of the source checkout."""
    return Path(__file__).resolve().parents[2] / "benchmarks" / "results" / "peers"


def load_peers(folder: str | Path | None) -> dict[str, Any]:
    """The latest peer results: {"crocoddyl": {...} | None, "tsid": {...} | None, "note": str}."""
    folder = Path(folder) if folder else default_peers_dir()
    out: dict[str, Any] = {"folder": str(folder), "crocoddyl": None, "tsid": None, "note": ""}
    missing = []
    for name in ("crocoddyl", "tsid"):
        f = folder / f"{name}.json"
        try:
            out[name] = json.loads(f.read_text())
        except (OSError, json.JSONDecodeError):
            missing.append(name)
    if missing:
        out["note"] = f"{' and '.join(missing)} unavailable: run `make bench-peers` (creates their environments)"
    return out


def peer_ratios(tasks: dict[str, dict], peers: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """Ours/peer per task class: solve (warm and cached cold) against Crocoddyl's FDDP solve,
    controller tick median against TSID's."""
    ratios: dict[str, dict[str, Any]] = {}
    croc = (peers.get("crocoddyl") or {}).get("tasks", {})
    tsid = peers.get("tsid") or {}
    for name, rec in tasks.items():
        r: dict[str, Any] = {}
        peer_task = croc.get(PEER_TASKS.get(name, ""), None)
        if peer_task:
            ps = peer_task["solve_s"]["median"]
            r["crocoddyl_solve_s"] = ps
            r["crocoddyl_iterations"] = peer_task.get("iterations")
            if rec.get("solve_warm_s"):
                r["warm_over_crocoddyl"] = rec["solve_warm_s"] / ps
            if rec.get("cold_total_s"):
                r["cold_over_crocoddyl"] = rec["cold_total_s"] / ps
        if tsid.get("median_us") and rec.get("tick_median_us"):
            r["tsid_tick_median_us"] = tsid["median_us"]
            r["tick_over_tsid"] = rec["tick_median_us"] / tsid["median_us"]
        if r:
            ratios[name] = r
    return ratios

