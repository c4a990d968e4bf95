"""``wbmp retarget`` on the shared CMU clips, on talos and g1, with a per-frame IK peer beside it.

Run from the repository root (long: minutes per clip on a busy 2-core machine; run it in the
background with ``nice``)::

    nice .venv/bin/python benchmarks/bench_retarget.py --robots talos --out benchmarks/results/retarget_talos.json
    nice .venv/bin/python benchmarks/bench_retarget.py --robots g1 --out benchmarks/results/retarget_g1.json
    .venv/bin/python benchmarks/bench_retarget.py --table benchmarks/results/retarget_*.json --docs docs/retarget.md

For each clip of ``clips.csv`` (``--clips DIR``, default ``examples/motions``, five of the 13 CMU clips; its ``start``/``end``
columns when it has them, else the whole clip) and robot:

* **wbmp**: :func:`wbmp.retarget.retarget` (no motion cache): planned (the plan's constraint report
  passed), certified (the MuJoCo certificate passed), the plan's and the execution's figures
  (:mod:`tasks.mocap.figures`: tracking error mean / max, foot skate, penetration, float), the
  plan and certificate (simulation) times, wall and CPU, and source frames per second (frames of
  the clip over plan + certificate wall time).
* **mink** (``--peer mink``): a GMR-style per-frame inverse kinematics on mink
  (``benchmarks/peers/mink_retarget.py``, in its own environment: ``bash benchmarks/peers/setup.sh
  mink``), given the same scaled targets (:class:`tasks.mocap.retarget.Reference`) on the same
  kinematic tree (the robot's URDF as MuJoCo reads it, with a site at each tracked frame). Its
  configurations get the same figures (same code, same labelled contacts), and are then tracked by
  our controller in MuJoCo as a plan (lead-in from standing, lead-out held), with our certificate.

Results are written after every clip (a partial run keeps what it measured) as JSON with the
machine (CPU model, cores, load before and after, thread variables). ``--table`` makes the
markdown table (and medians) from one or more such files; with ``--docs`` it replaces the
section between ``<!-- bench_retarget -->`` markers of that page.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks" / "peers"))

from common import machine_info  # noqa: E402

DEFAULT_CLIPS = ROOT / "examples" / "motions"  # five of the 13 CMU clips; --clips DIR for all 13
MINK_VENV = Path(os.environ.get("MINK_VENV", ROOT / ".venv-mink"))
MARK = "<!-- bench_retarget -->"


def clips_of(folder: Path, only: list[str] | None) -> list[dict]:
    """The rows of ``folder/clips.csv`` (file, family, start, end), in file order (``only``: those
    whose file name holds one of these, in their order)."""
    rows = []
    with (folder / "clips.csv").open(newline="", encoding="utf-8") as f:
        for row in csv.DictReader(f):
            if only and not any(o in row["file"] for o in only):
                continue
            rows.append({"file": row["file"], "family": row.get("family") or row["file"],
                         "start": float(row["start"]) if row.get("start") else None,
                         "end": float(row["end"]) if row.get("end") else None})
    if only:  # in the order asked
        rows.sort(key=lambda r: next(i for i, o in enumerate(only) if o in r["file"]))
    return rows


def _figs(f) -> dict | None:
    return None if f is None else {k: v for k, v in f.to_dict().items() if k != "tracking_mean_per_keypoint_m"}


def run_ours(path: Path, row: dict, robot: str) -> tuple[dict, object]:
    """One clip on one robot with wbmp; (record, result)."""
    from wbmp.retarget import RetargetRequest, retarget

    req = RetargetRequest(clip=str(path), robot=robot, start=row["start"], end=row["end"], simulate=True)
    c0, w0 = time.process_time(), time.perf_counter()
    try:
        res = retarget(req, cache=False)
    except Exception as e:  # noqa: BLE001 (a benchmark records the failure and goes on)
        wall = time.perf_counter() - w0
        return {"error": f"{type(e).__name__}: {e}"[:300], "planned": False, "certified": False, "wall_s": wall,
                "cpu_s": time.process_time() - c0, "plan_s": wall}, None
    cpu, wall = time.process_time() - c0, time.perf_counter() - w0
    t = res.timings
    frames = int(res.clip_info["frames"])
    work = t.get("plan", 0.0) + t.get("simulate", 0.0)
    cert = res.execution.certificate if res.execution is not None else None
    rec = {
        "frames": frames, "duration_s": res.clip_info["duration_s"], "horizon_s": float(res.spec.horizon),
        "time_scale": res.reference.time_scale, "stride_scale": res.reference.stride_scale,
        "raised_m": res.reference.raised_max(), "arm_moved_m": res.reference.arm_moved_max(),
        "kept_out_m": res.reference.kept_out_max(),
        "grounded_s": res.reference.grounded_s, "stepped_s": res.reference.stepped_s,
        "planned": bool(res.plan.ok), "plan_status": res.plan.stats.status.value,
        "iterations": int(res.plan.stats.iterations), "diagnosis": res.plan.diagnosis[:300],
        "certified": bool(res.execution is not None and res.execution.ok),
        "certificate_failures": [] if cert is None else
        [f"{c.name}: {c.violation:.3g} {c.unit}" for c in cert.checks if not c.ok][:6],
        "plan": _figs(res.figures), "executed": _figs(res.exec_figures),
        "spec_s": t.get("spec", 0.0), "plan_s": t.get("plan", 0.0), "certificate_s": t.get("simulate", 0.0),
        "wall_s": wall, "cpu_s": cpu, "frames_per_s": frames / work if work > 0 else None,
    }
    return rec, res


def task_of(path: Path, row: dict, robot: str):
    """(robot, spec, reference) of a clip without planning it (for the peer when ours failed)."""
    import types

    from wbmp.retarget import RetargetRequest, build_retarget_spec

    req = RetargetRequest(clip=str(path), robot=robot, start=row["start"], end=row["end"])
    r, spec, ref, _, _ = build_retarget_spec(req)
    return types.SimpleNamespace(robot=r, spec=spec, reference=ref)


def run_peer(res, robot_name: str, path: Path) -> dict:
    """The mink peer on the reference of ``res`` (our result of the same clip and robot, or :func:`task_of`)."""
    from peer_mink import export_task, peer_plan

    python = MINK_VENV / "bin" / "python"
    if not python.exists():
        return {"skipped": f"{MINK_VENV} missing: bash benchmarks/peers/setup.sh mink"}
    with tempfile.TemporaryDirectory(prefix="wbmp-mink-") as tmp:
        task = Path(tmp) / "task.npz"
        out = Path(tmp) / "out.npz"
        export_task(res.robot, res.reference, task)
        env = dict(os.environ, OMP_NUM_THREADS=os.environ.get("OMP_NUM_THREADS", "1"))
        proc = subprocess.run([str(python), str(ROOT / "benchmarks" / "peers" / "mink_retarget.py"), str(task),
                               str(out)], capture_output=True, text=True, env=env, check=False)
        if proc.returncode != 0:
            tail = (proc.stderr or proc.stdout).strip().splitlines()[-1:] or ["?"]
            return {"error": f"mink_retarget.py exit {proc.returncode}: {tail[0]}"[:300]}
        import numpy as np

        data = dict(np.load(out, allow_pickle=False))
    return peer_plan(res, data, path)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--clips", type=Path, default=DEFAULT_CLIPS)
    p.add_argument("--robots", default="talos,g1")
    p.add_argument("--only", default=None, help="comma-separated parts of clip file names")
    p.add_argument("--peer", choices=("mink", "none", "only"), default="mink",
                   help="mink: wbmp then the mink peer per clip; none: wbmp only; only: the peer only")
    p.add_argument("--out", type=Path, default=None, help="JSON results (default benchmarks/results/retarget_<date>.json)")
    p.add_argument("--table", nargs="+", type=Path, default=None, help="make the markdown table from these JSON files")
    p.add_argument("--docs", type=Path, default=None, help="with --table: write it into this page between markers")
    args = p.parse_args(argv)
    if args.table:
        from peer_mink import markdown

        text = markdown([json.loads(f.read_text()) for f in args.table])
        if args.docs:
            page = args.docs.read_text()
            a, b = page.index(MARK), page.rindex(MARK)
            args.docs.write_text(page[: a + len(MARK)] + "\n" + text + "\n" + page[b:])
        print(text)
        return 0
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    rows = clips_of(args.clips, args.only.split(",") if args.only else None)
    out = args.out or ROOT / "benchmarks" / "results" / f"retarget_{time.strftime('%Y-%m-%d_%H%M')}.json"
    doc = {"machine": machine_info(), "threads": {k: os.environ.get(k) for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS")},
           "clips_dir": str(args.clips), "runs": []}
    for robot in args.robots.split(","):
        for row in rows:
            path = args.clips / row["file"]
            load0 = os.getloadavg()[0]
            rec, res = run_ours(path, row, robot) if args.peer != "only" else ({}, None)
            entry = {"clip": row["file"], "family": row["family"], "robot": robot, "load1_before": load0, "wbmp": rec}
            if args.peer != "none":
                try:
                    entry["mink"] = run_peer(res if res is not None else task_of(path, row, robot), robot, path)
                except Exception as e:  # noqa: BLE001
                    entry["mink"] = {"error": f"{type(e).__name__}: {e}"[:300]}
            entry["load1_after"] = os.getloadavg()[0]
            doc["runs"].append(entry)
            doc["machine_after"] = machine_info()
            out.write_text(json.dumps(doc, indent=1, default=float))
            w = rec
            print(f"{robot:6s} {row['file']:26s} planned={w.get('planned')} certified={w.get('certified')} "
                  f"wall={w.get('wall_s', 0):.0f}s {w.get('error', '')}"
                  + (f" | mink: {entry['mink'].get('certified', entry['mink'].get('error', entry['mink'].get('skipped')))}"
                     if "mink" in entry else ""), flush=True)
    print(f"wrote {out}")
    return 0


def median(values: list[float]) -> float | None:
    values = [v for v in values if v is not None]
    return statistics.median(values) if values else None


if __name__ == "__main__":
    sys.exit(main())
