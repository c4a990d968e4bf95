"""``wbmp robots``: the robots wbmp knows, with sizes and named frames.

Exit codes: 0 listed; 2 an empty name (``wbmp robots ""``) or a bad option; 3 an unknown robot
or a profile file that cannot be loaded (the message names it and lists the built-in robots).
Every name is checked before anything is printed.
"""

from __future__ import annotations

import argparse
import json

from wbmp.errors import ROBOT_HINT, ExitCode, require_text


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("robots", help="list the robots with nq/nv, mass, height and named frames",
                       description="List the built-in robots (or one profile file) with their sizes and frames.")
    p.add_argument("robot", nargs="*", help="robot names or profile files (default: all built-in robots)")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.add_argument("--collisions", action="store_true",
                   help="show the self-collision model: capsules per link, pairs checked and skipped")
    p.set_defaults(run=run)


def describe_collisions(name: str) -> dict:
    """A JSON-friendly summary of a robot's collision model (robots/collision.py)."""
    from robots import body_part, collision_model, load_robot

    r = load_robot(name)
    cm = collision_model(r)
    by_reason: dict[str, list[list[str]]] = {}
    for pair, why in cm.skipped.items():
        by_reason.setdefault(why, []).append(list(pair))
    return {
        "name": r.name,
        "capsules": [{"link": c.link, "body_part": body_part(r, c.link), "joint": r.model.names[c.joint],
                      "length": round(c.length, 4), "radius": round(c.radius, 4)} for c in cm.capsules],
        "pairs": [list(p) for p in cm.pairs],
        "skipped": by_reason,
    }


def _print_collisions(row: dict) -> None:
    print(f"{row['name']}: {len(row['capsules'])} capsules, {len(row['pairs'])} pairs checked, "
          f"{sum(len(v) for v in row['skipped'].values())} skipped")
    print(f"  {'link':34s} {'body part':16s} {'length [m]':>10s} {'radius [m]':>10s}")
    for c in row["capsules"]:
        print(f"  {c['link']:34s} {c['body_part']:16s} {c['length']:10.3f} {c['radius']:10.3f}")
    for why, pairs in row["skipped"].items():
        print(f"  skipped ({why}): {len(pairs)} pairs")
    print("  pairs checked: " + ", ".join(f"{a}-{b}" for a, b in row["pairs"][:12])
          + (f", ... ({len(row['pairs'])} in all; --json lists them)" if len(row["pairs"]) > 12 else ""))


def describe(name: str) -> dict:
    """A JSON-friendly summary of one robot."""
    from robots import ROLES, load_robot

    r = load_robot(name)
    return {
        "name": r.name,
        "description": r.profile.description,
        "nq": r.nq,
        "nv": r.nv,
        "actuated_joints": r.nv - 6,
        "mass": round(r.mass, 3),
        "height": round(r.height(), 3),
        "frames": {role: r.profile.frame(role) for role in ROLES if r.profile.frame(role)},
        "sole": {"x": [r.profile.sole.x_min, r.profile.sole.x_max], "y": [r.profile.sole.y_min, r.profile.sole.y_max]},
        "reference_posture": r.profile.reference_posture,
        "urdf": r.urdf_path,
    }


def run(args: argparse.Namespace) -> int:
    from robots import available_robots

    for name in args.robot:
        require_text(name, "a robot name", ROBOT_HINT)
    names = args.robot or available_robots()
    if args.collisions:
        rows = [describe_collisions(n) for n in names]
        if args.json:
            print(json.dumps(rows, indent=2))
        else:
            for row in rows:
                _print_collisions(row)
        return ExitCode.OK
    rows = [describe(n) for n in names]
    if args.json:
        print(json.dumps(rows, indent=2))
        return ExitCode.OK
    for i, row in enumerate(rows):
        default = "  (default)" if i == 0 and not args.robot else ""
        print(f"{row['name']}{default}: {row['description']}")
        print(f"  nq {row['nq']}, nv {row['nv']}, {row['actuated_joints']} actuated joints, "
              f"mass {row['mass']:.1f} kg, height {row['height']:.2f} m, standing posture '{row['reference_posture']}'")
        frames = ", ".join(f"{k}={v}" for k, v in row["frames"].items())
        print(f"  frames: {frames}")
        print(f"  sole [m]: x {row['sole']['x']}, y {row['sole']['y']}")
    return ExitCode.OK
