"""Facts about the machine a benchmark ran on (CPU, cores, load, library versions, threads); the
benchmark scripts of ``benchmarks/`` record them too."""

from __future__ import annotations

import os
import platform
from pathlib import Path
from typing import Any


def cpu_model() -> str:
    """CPU model name (``/proc/cpuinfo``), else the platform's processor string."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def machine_info() -> dict[str, Any]:
    """CPU, cores, load average, library versions and thread settings of this process."""
    versions: dict[str, str] = {}
    for mod in ("pinocchio", "casadi", "proxsuite", "mujoco", "numpy", "numba"):
        try:
            versions[mod] = str(__import__(mod).__version__)
        except Exception:  # noqa: BLE001 - a missing library is just not listed
            pass
    affinity: int | None
    try:
        affinity = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        affinity = os.cpu_count()
    threads: dict[str, object] = {k: os.environ[k] for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
               if k in os.environ}
    try:
        import threadpoolctl  # type: ignore[import-not-found]

        threads["blas_pools"] = {i["internal_api"]: i["num_threads"] for i in threadpoolctl.threadpool_info()}
    except Exception:  # noqa: BLE001
        pass
    return {
        "cpu_model": cpu_model(),
        "cores": os.cpu_count(),
        "cores_usable": affinity,
        "hostname": platform.node(),
        "python": platform.python_version(),
        "loadavg": [round(x, 2) for x in os.getloadavg()],
        "versions": versions,
        "threads": {"solver": 1, "controller": 1, **threads},
    }


def machine_tag(info: dict[str, Any]) -> str:
    """Short file-name tag of the machine: ``xeon-2.50ghz-2c``."""
    model = info.get("cpu_model", "cpu").lower()
    words = [w for w in model.replace("(r)", "").replace("(tm)", "").replace("@", " ").split()
             if w not in ("intel", "amd", "processor", "cpu", "core")]
    tag = "-".join(words[:1] + [w for w in words[1:] if "ghz" in w])
    return f"{tag or 'cpu'}-{info.get('cores', 0)}c"

