"""Run the peer benchmarks in their own environments and store the results for ``wbmp bench --peers``.

Standard library only (any Python 3.10+)::

    python3 benchmarks/peers/run_peers.py [--repeats 5] [--ticks 3000] [--only crocoddyl|tsid]

Runs ``crocoddyl_bench.py`` with ``.venv-crocoddyl`` and ``tsid_tick.py`` with ``.venv-tsid``
(both made by ``setup.sh``), adds the machine facts and the load average before and after each
run, and writes ``benchmarks/results/peers/<peer>.json`` (the latest, read by ``wbmp bench
--peers``) and a dated copy ``benchmarks/results/peers_<date>_<machine>_<peer>.json``. A peer
whose environment is missing is skipped with a message; the exit code is 3 when none ran.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
sys.path.insert(0, str(HERE))

from common import machine_info, machine_tag  # noqa: E402

PEERS = {  # peer -> (its environment's Python, its script)
    "crocoddyl": (ROOT / ".venv-crocoddyl" / "bin" / "python", "crocoddyl_bench.py"),
    "tsid": (ROOT / ".venv-tsid" / "bin" / "python", "tsid_tick.py"),
}


def run_peer(peer: str, args: list[str], *, show_output: bool = False) -> dict:
    """Run ``peer``'s script in its own environment; its JSON results with the machine facts and
    the load before and after, or ``{"skipped": reason}`` when it cannot run.

    BLAS/OpenMP threads default to 1 (as in wbmp's own benchmarks) unless set in the environment.
    With ``show_output`` the script prints to this terminal; otherwise its output is kept, and
    the last line of it explains a failure.
    """
    python, script = PEERS[peer]
    if not python.exists():
        return {"skipped": f"{python.parent.parent.name} missing; run `bash benchmarks/peers/setup.sh {peer}`"}
    fd, tmp = tempfile.mkstemp(suffix=".json", prefix=f"wbmp-peer-{peer}-")
    os.close(fd)
    before = machine_info()
    env = dict(os.environ)
    for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
        env.setdefault(name, "1")
    try:
        proc = subprocess.run([str(python), str(HERE / script), *args, "--json", tmp], env=env,
                              capture_output=not show_output, text=True, check=False)
        after = os.getloadavg()
        if proc.returncode != 0:
            tail = (proc.stderr or proc.stdout or "").strip().splitlines()[-1:] or ["see its output above"]
            return {"skipped": f"{script} failed (exit {proc.returncode}): {tail[0]}"}
        data = json.loads(Path(tmp).read_text())
    finally:
        os.unlink(tmp)
    data.setdefault("machine", before)
    data["loadavg_before"] = before["loadavg"]
    data["loadavg_after"] = list(after)
    data.setdefault("peer", peer)
    if data.get(peer) in (None, "?"):  # the script could not read the version from the module
        ver = subprocess.run([str(python), "-c", f"import importlib.metadata as m; print(m.version('{peer}'))"],
                             capture_output=True, text=True, check=False).stdout.strip()
        data[peer] = ver or "?"
    return data


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5, help="crocoddyl solves per task")
    parser.add_argument("--ticks", type=int, default=3000, help="TSID controller ticks")
    parser.add_argument("--only", choices=("crocoddyl", "tsid"), default=None)
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results")
    args = parser.parse_args(argv)

    jobs = {"crocoddyl": ["--repeats", str(args.repeats), "-v"], "tsid": ["--ticks", str(args.ticks)]}
    ran = 0
    stamp = dt.datetime.now(dt.UTC).strftime("%Y-%m-%d")
    for peer, extra in jobs.items():
        if args.only and peer != args.only:
            continue
        print(f"running {peer} ({PEERS[peer][1]})", file=sys.stderr)
        data = run_peer(peer, extra, show_output=True)
        if "skipped" in data:
            print(f"{peer}: {data['skipped']}", file=sys.stderr)
            continue
        ran += 1
        latest = args.out / "peers" / f"{peer}.json"
        latest.parent.mkdir(parents=True, exist_ok=True)
        text = json.dumps(data, indent=2) + "\n"
        latest.write_text(text)
        dated = args.out / f"peers_{stamp}_{machine_tag(data['machine'])}_{peer}.json"
        dated.write_text(text)
        print(f"{peer}: wrote {latest} and {dated}", file=sys.stderr)
    return 0 if ran else 3


if __name__ == "__main__":
    sys.exit(main())
