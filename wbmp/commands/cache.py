"""``wbmp cache [FOLDER ...] [--entries] [--clear] [--json]``: what wbmp keeps on disk, and emptying it.

Every cache lives in one folder of ``$WBMP_CACHE_DIR`` (default ``~/.cache/wbmp``):
``planner seeds robots mujoco viz collision motions`` (:data:`robots.store.CACHE_FOLDERS`). The
listing gives each folder's entries and bytes, the total and the size cap
(``$WBMP_CACHE_MAX_SIZE``, :func:`robots.store.max_cache_bytes`); ``--clear`` removes the
entries of all folders or of the ones named, and prints one line. Only wbmp's own entries are
touched (names that are keys); a symbolic link is never followed; temporary files of a write in
progress stay. With the ``planner`` folder, the listing also says which solver build is running
(structure key, pid, since when), which structures were skipped and why (another build ran; not
enough free memory), and the memory rule (:mod:`planner.trajopt.builds`).

Exit codes: 0 listed or cleared; 2 an unknown folder name, a ``$WBMP_CACHE_MAX_SIZE`` or
``$WBMP_BUILD_MEMORY`` that is not a size, or a bad option.
"""

from __future__ import annotations

import argparse
import json
import time
from typing import Any

from robots import CACHE_FOLDERS
from wbmp.errors import CliError, ExitCode

FOLDERS_TEXT = ", ".join(CACHE_FOLDERS)


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "cache", help="show the disk caches (entries, sizes, the cap) or empty them",
        description="Show each cache folder of $WBMP_CACHE_DIR (default ~/.cache/wbmp) with its entries "
                    "and size, the total and the cap (WBMP_CACHE_MAX_SIZE, default 4G; 0 or 'unlimited': "
                    "no cap; over it, the least recently used entries are removed after each store). "
                    f"Folders: {FOLDERS_TEXT}. With planner: the solver build running now (structure "
                    "key, pid, since when), the structures skipped and why, and the memory a build needs "
                    "(WBMP_BUILD_MEMORY, default 3.7G).",
        epilog="examples: wbmp cache; wbmp cache --clear planner; WBMP_CACHE_MAX_SIZE=2G wbmp cache",
    )
    p.add_argument("folder", nargs="*", help="cache folders to show or clear (default: all)")
    p.add_argument("--clear", action="store_true", help="remove every entry of these folders (one line of output)")
    p.add_argument("--entries", action="store_true", help="also list each entry with its size and last use")
    p.add_argument("--json", action="store_true", help="print JSON instead of text")
    p.set_defaults(run=run)


def _folders(names: list[str]) -> tuple[str, ...]:
    from robots import CACHE_FOLDERS

    for name in names:
        if name.strip("/") not in CACHE_FOLDERS:
            raise CliError(f"unknown cache folder {name!r}: give one or more of {', '.join(CACHE_FOLDERS)} "
                           "(or none for all)", ExitCode.USAGE)
    chosen = {n.strip("/") for n in names}
    return tuple(n for n in CACHE_FOLDERS if n in chosen) if chosen else CACHE_FOLDERS


def _age(seconds: float) -> str:
    for unit, size in (("d", 86400), ("h", 3600), ("min", 60)):
        if seconds >= size:
            return f"{seconds / size:.0f} {unit} ago"
    return "just now"


def _builds(base) -> Any:
    """The build status of the planner cache folder (:func:`planner.trajopt.builds.build_status`)."""
    from planner import MEMORY_MARGIN, build_status
    from wbmp.environment import build_memory

    return build_status(base / "planner", build_memory(), MEMORY_MARGIN)


def _build_lines(st, now: float) -> list[str]:
    from planner import describe_build

    gb = 1e9
    memory = "unknown" if st.available is None else f"{st.available / gb:.1f} GB"
    lines = [f"  builds     {'running ' + describe_build(st.running, now) if st.running else 'none running'}",
             f"             a build starts with {st.need / gb:.1f} GB + {st.margin / gb:.1f} GB free "
             f"(WBMP_BUILD_MEMORY; available now: {memory})"]
    for rec in st.skipped:
        lines.append(f"    skipped {rec.get('key', '?')} {_age(now - rec['when'])}: {rec.get('reason', '?')} "
                     "(the next solve of it builds it)")
    return lines


def run(args: argparse.Namespace) -> int:
    from robots import cache_base, cache_usage, format_size, max_cache_bytes, remove_entry

    folders = _folders(args.folder)
    base = cache_base()
    now = time.time()
    usage = cache_usage(base, folders, now=now)
    if args.clear:
        removed = [e for f in usage for e in f.entries if remove_entry(e)]
        freed = sum(e.size for e in removed)
        if args.json:
            print(json.dumps({"cache_dir": str(base), "cleared": list(folders), "removed": len(removed),
                              "bytes": freed}))
        else:
            print(f"wbmp cache: removed {len(removed)} entries ({format_size(freed)}) from "
                  f"{', '.join(folders)} in {base}")
        return ExitCode.OK
    try:
        cap = max_cache_bytes(strict=True)
    except ValueError as e:
        raise CliError(str(e), ExitCode.USAGE) from None
    total = sum(f.size for f in usage)
    if args.json:
        out: dict[str, Any] = {"cache_dir": str(base), "cap": cap, "total": total, "folders": []}
        for f in usage:
            row: dict[str, Any] = {"name": f.name, "path": str(f.path), "entries": len(f.entries), "size": f.size,
                                   "temporary": f.pending, "symlink": f.link}
            if args.entries:
                row["items"] = [{"folder": e.folder, "name": e.name, "size": e.size, "used": e.used}
                                for e in f.entries]
            out["folders"].append(row)
        if "planner" in folders:
            st = _builds(base)
            out["builds"] = {"running": st.running, "skipped": st.skipped, "memory_available": st.available,
                             "build_memory": st.need, "memory_margin": st.margin}
        print(json.dumps(out, indent=2))
        return ExitCode.OK
    print(f"{base}")
    print(f"  {'folder':10s} {'entries':>8s} {'size':>11s}")
    for f in usage:
        note = "  (a symbolic link: not followed)" if f.link else (
            f"  ({format_size(f.pending)} being written)" if f.pending else "")
        print(f"  {f.name:10s} {len(f.entries):8d} {format_size(f.size):>11s}{note}")
        if args.entries:
            for item in reversed(f.entries):  # most recently used first
                print(f"    {item.folder + '/' + item.name:78s} {format_size(item.size):>11s}  used {_age(now - item.used)}")
    entries = sum(len(f.entries) for f in usage)
    cap_text = "no cap" if cap is None else f"cap {format_size(cap)}"
    print(f"  {'total':10s} {entries:8d} {format_size(total):>11s}  ({cap_text}; WBMP_CACHE_MAX_SIZE)")
    if "planner" in folders:
        print("\n".join(_build_lines(_builds(base), now)))
    return ExitCode.OK
