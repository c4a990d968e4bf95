"""``wbmp actions [NAME ...] [--json] [--robot R]``: the motion primitives and their parameters.

Exit codes: 0 listed; 2 an empty name or ``--robot ""``, or a bad option; 3 an unknown
primitive or robot (the message lists the known ones). Every name is checked before anything
is printed.
"""

from __future__ import annotations

import argparse
import json
from typing import Any

from wbmp.errors import ROBOT_HINT, ExitCode, require_text


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "actions", help="list the motion primitives with their parameters, units, defaults and ranges",
        description="List every motion primitive a sentence can ask for, with its parameters (SI units), "
                    "defaults and allowed ranges. With --robot, also the limits of that robot "
                    "(e.g. the deepest squat).",
    )
    p.add_argument("name", nargs="*", help="primitive names (default: all)")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.add_argument("--robot", default=None, help="add this robot's limits (name or profile file)")
    p.set_defaults(run=run)


def _param_dict(p) -> dict[str, Any]:
    out: dict[str, Any] = {"name": p.name, "type": p.kind, "unit": p.unit,
                           "default": list(p.default) if isinstance(p.default, tuple) else p.default}
    if p.minimum is not None:
        out["minimum"] = p.minimum
    if p.maximum is not None:
        out["maximum"] = p.maximum
    if p.choices:
        out["choices"] = list(p.choices)
    out["description"] = p.description
    return out


def describe(names: list[str] | None = None, robot: Any = None) -> list[dict[str, Any]]:
    """JSON-friendly description of the primitives ``names`` (all when None)."""
    from tasks import PRIMITIVES, REGISTRY, get_action

    schemas = [get_action(n) for n in names] if names else list(REGISTRY.values())
    rows = []
    for s in schemas:
        prim = PRIMITIVES[s.name]
        row: dict[str, Any] = {
            "name": s.name,
            "summary": s.summary,
            "body": s.body,
            "dynamic": s.dynamic,
            "available": prim.available,
            "params": [_param_dict(p) for p in s.params],
        }
        if robot is not None:
            row["robot"] = robot.name
            row["robot_limits"] = prim.limits(robot)
        rows.append(row)
    return rows


def _range(p: dict[str, Any]) -> str:
    if "choices" in p:
        return "|".join(p["choices"])
    if p["type"] == "vec3":
        return "x, y, z"
    if p["type"] == "bool":
        return "true|false"
    lo, hi = p.get("minimum"), p.get("maximum")
    if lo is None and hi is None:
        return ""
    return f"{'' if lo is None else f'{lo:g}'}..{'' if hi is None else f'{hi:g}'}"


def _default(p: dict[str, Any]) -> str:
    d = p["default"]
    if d is None:
        return "-"
    if isinstance(d, list):
        return ", ".join(f"{x:g}" for x in d)
    return f"{d:g}" if isinstance(d, float) else str(d)


def run(args: argparse.Namespace) -> int:
    require_text(args.robot, "--robot", ROBOT_HINT)
    for name in args.name:
        require_text(name, "an action name", "give a primitive name (`wbmp actions` lists them)")
    robot = None
    if args.robot:
        from robots import load_robot

        robot = load_robot(args.robot)
    rows = describe(args.name or None, robot)
    if args.json:
        print(json.dumps(rows, indent=2))
        return ExitCode.OK
    for row in rows:
        flags = [row["body"] + " body"]
        if row["dynamic"]:
            flags.append("dynamic")
        if not row["available"]:
            flags.append("not available yet")
        print(f"{row['name']} ({', '.join(flags)}): {row['summary']}")
        for p in row["params"]:
            unit = "" if p["unit"] in ("", "count") else f" [{p['unit']}]"
            print(f"  {p['name'] + unit:<16} default {_default(p):<8} range {_range(p):<36} {p['description']}")
        for param, text in (row.get("robot_limits") or {}).items():
            print(f"  {row['robot']} limit on {param}: {text}")
    return ExitCode.OK
