"""Helpers shared by the peer benchmark scripts (run in their own virtual environments).

These scripts run without wbmp installed, so they only use the standard library and numpy.
"""

from __future__ import annotations

import datetime as _dt
import json
import os
import platform
import statistics
import time
from pathlib import Path


def cpu_model() -> str:
    """The CPU model name from /proc/cpuinfo, or the platform's processor string."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def machine_info() -> dict:
    """CPU model, core count, load average and thread-related environment variables."""
    return {
        "cpu_model": cpu_model(),
        "cores": os.cpu_count(),
        "hostname": platform.node(),
        "python": platform.python_version(),
        "loadavg": list(os.getloadavg()),
        "threads_env": {
            k: os.environ.get(k)
            for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
            if os.environ.get(k) is not None
        },
        "date_utc": _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ"),
    }


def summarize(samples: list[float]) -> dict:
    """Median, min, max and p99 of a list of timings [s]."""
    s = sorted(samples)
    p99 = s[min(len(s) - 1, int(round(0.99 * (len(s) - 1))))]
    return {"median": statistics.median(s), "min": s[0], "max": s[-1], "p99": p99, "n": len(s)}


class Timer:
    """Context manager measuring wall time with perf_counter [s]."""

    def __enter__(self) -> Timer:
        self.t0 = time.perf_counter()
        return self

    def __exit__(self, *exc: object) -> None:
        self.elapsed = time.perf_counter() - self.t0


def write_json(path: str | None, payload: dict) -> None:
    """Write the payload as indented JSON (creating parent folders) when a path is given."""
    if not path:
        return
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(json.dumps(payload, indent=2, sort_keys=False) + "\n")


def machine_tag(info: dict) -> str:
    """Short file-name tag of the machine, as ``wbmp bench`` writes it: ``xeon-2.50ghz-2c``."""
    model = info.get("cpu_model", "cpu").lower()
    words = [w for w in model.replace("(r)", "").replace("(tm)", "").replace("@", " ").split()
             if w not in ("intel", "amd", "processor", "cpu", "core")]
    tag = "-".join(words[:1] + [w for w in words[1:] if "ghz" in w])
    return f"{tag or 'cpu'}-{info.get('cores', 0)}c"
