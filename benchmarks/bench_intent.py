"""Does a certified motion do what its sentence says? Sentences in users' words, one or more per
action, on Talos and G1: planned, certified, and the intent checked independently of wbmp.

Run: ``.venv/bin/python benchmarks/bench_intent.py [--robots talos,g1] [--actions clap,lean]
[--json out.json] [--markdown out.md]``

Each sentence is parsed, compiled, planned (``PlannerSettings(cache=CacheSettings(compile=False))``) and simulated in
MuJoCo with the certificate (whose intent lines are ``sim/intent.py``). The *independent* check
does not use wbmp's checks: it measures the simulated configurations with Pinocchio forward
kinematics (CoM, frames) and coal (the URDF collision meshes), and MuJoCo's sole forces, against
what the action means (:data:`INDEPENDENT`); where the meaning is relative to the plan (how far a
lean goes), the plan is measured the same way. A row is a *silent wrong motion* when the
certificate passes and the independent check says the intent was missed: the target is none.

Reported per sentence: refused (the reason) / planned / certified / intent met (independent), the
measured figure, and the certificate's first failure. This is a report, not a test; a run of the
default sentences takes tens of minutes on two cores (use ``--actions`` for a few).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

#: action -> sentences in users' words, without a scene (the object actions: :data:`SCENE_SENTENCES`).
SENTENCES: dict[str, tuple[str, ...]] = {
    "stand": ("stand still for two seconds",),
    "squat": ("squat", "do a deep squat"),
    "lean": ("lean to your right", "lean forward"),
    "bow": ("bow",),
    "raise_arms": ("raise your arms",),
    "turn_head": ("look left",),
    "nod": ("nod",),
    "shake_head": ("shake your head",),
    "clap": ("clap twice",),
    "salute": ("salute",),
    "point": ("point to your left", "point forward"),
    "wave": ("wave your right hand",),
    "punch": ("punch with your right hand",),
    "touch": ("touch your head",),
    "hands_on_hips": ("put your hands on your hips",),
    "arms_out": ("stretch your arms out",),
    "step": ("take two steps forward",),
    "walk": ("walk forward",),
    "turn": ("turn left",),
    "jump": ("jump",),
    "hop": ("hop twice on your left foot",),
    "kick": ("kick with your right leg",),
    "march": ("march in place",),
    "stomp": ("stomp your right foot",),
    "balance": ("balance on your left foot",),
    "lunge": ("lunge forward",),
    "reach": ("reach forward with your left hand",),
    "cross_arms": ("cross your arms",),
    "arm_circles": ("do arm circles",),
    "shrug": ("shrug your shoulders",),
    "stretch": ("stretch your arms up",),
    "walk_arc": ("walk in a circle",),
    "jog": ("run forward",),
}

#: Scene files of the object sentences, per robot: the box within both hands' reach (Talos on a
#: 0.85 m counter, G1 on a low table, docs/objects.md), and the kitchen (to walk in; its cup is in
#: the neck's range and not too close to point at: the box on the counter is 0.81 rad down).
_BOX = {"talos": "examples/scenes/box_on_counter.json", "g1": "examples/scenes/box_on_low_table.json"}
_KITCHEN = {"talos": "examples/scenes/kitchen.json", "g1": "examples/scenes/kitchen.json"}
#: A cup and a box on a table placed for each robot's reach (benchmarks/scenes): the box's near face
#: room for the hand in front of it (in the box scenes above it is 0.37 m / 0.16 m from the feet:
#: the pushing hand's approach point was at Talos's chest, inside G1's), the cup for one hand.
_TABLE = {"talos": "benchmarks/scenes/table_talos.json", "g1": "benchmarks/scenes/table_g1.json"}
_STAIRS = {"talos": "examples/scenes/stairs.json", "g1": "examples/scenes/stairs.json"}
#: action -> ((sentence, robot -> scene file), ...): the actions on scene objects.
SCENE_SENTENCES: dict[str, tuple[tuple[str, dict[str, str]], ...]] = {
    "pick_up": (("pick up the red box with both hands", _BOX),),
    "put_down": (("pick up the red box with both hands, then put it down", _BOX),),
    "push": (("push the red box gently", _TABLE),),
    "hand_over": (("pick up the cup and hand it to me", _TABLE),),
    "step_up": (("walk up the stairs", _STAIRS),),
    "step_down": (("walk down the stairs", _STAIRS),),
    "touch_object": (("touch the red box", _BOX),),
    "look_at": (("look at the cup", _KITCHEN),),
    "point_at": (("point at the cup", _KITCHEN),),
    "walk_to": (("walk to the table", _KITCHEN),),
}


#: action -> where its sentence starts (feet centre x, height, yaw), for a sentence that cannot start
#: standing at the origin: on the top tread of examples/scenes/stairs.json, facing down (the place
#: tests/sim/test_slope_walk.py starts from).
STARTS: dict[str, tuple[float, float, float]] = {"step_down": (0.7695, 0.3, math.pi)}


def start_state(robot, x: float, height: float, yaw: float):
    """A ``StartState`` standing at rest with the feet centred on (x, 0) at ``height``, facing ``yaw``."""
    import pinocchio as pin

    from tasks.specs import StartState

    q = np.array(robot.q_standing, dtype=float)
    R = pin.rpy.rpyToMatrix(0.0, 0.0, yaw)
    q[:2] = np.array([x, 0.0]) + R[:2, :2] @ q[:2]
    q[2] += height
    quat = pin.Quaternion(R @ pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix())
    q[3:7] = [quat.x, quat.y, quat.z, quat.w]
    return StartState(q=tuple(float(v) for v in q))


@dataclass
class Sim:
    """What the independent checks read: the plan and the simulation, both as configurations."""

    robot: object
    spec: object
    plan: object
    execution: object
    actions: object = None


def _fk(robot, qs: np.ndarray, frame: str) -> np.ndarray:
    import pinocchio as pin

    model, data = robot.model, robot.model.createData()
    fid = robot.frame_id(frame)
    out = np.empty((len(qs), 3, 4))
    for n, q in enumerate(qs):
        pin.framesForwardKinematics(model, data, q)
        m = data.oMf[fid]
        out[n, :, :3], out[n, :, 3] = m.rotation, m.translation
    return out


def _com(robot, qs: np.ndarray) -> np.ndarray:
    import pinocchio as pin

    data = robot.model.createData()
    return np.array([pin.centerOfMass(robot.model, data, q) for q in qs])


def _every(s: Sim, step_s: float = 0.02) -> np.ndarray:
    ex = s.execution
    step = max(1, int(round(step_s / ex.timestep)))
    return ex.q[::step]


def _ratio_of_extent(plan_values: np.ndarray, sim_values: np.ndarray) -> float:
    """Largest excursion of the simulation from its start over the plan's (same measure)."""
    p = float(np.max(np.abs(plan_values - plan_values[0])))
    x = float(np.max(np.abs(sim_values - sim_values[0])))
    return x / p if p > 1e-9 else math.inf


def com_axis(axis: int) -> Callable[[Sim], tuple[bool, str]]:
    def check(s: Sim) -> tuple[bool, str]:
        r = _ratio_of_extent(_com(s.robot, s.plan.q)[:, axis], _com(s.robot, _every(s))[:, axis])
        return r >= 0.8, f"CoM {'xyz'[axis]} excursion {100 * r:.0f} % of the plan's"
    return check


def held_com_shift(s: Sim) -> tuple[float, float]:
    """(achieved, planned) horizontal CoM shift of the spec's held (HARD, windowed) CoM target [m],
    the certificate's definition measured here: from where its action begins (the start of the
    action's first phase), the plan's mean shift over the hold window gives the direction ``u``
    and the size; the simulation's shift along ``u``, its median over the window, is what was
    achieved. Pinocchio CoM of the plan's knots and of the simulated configurations every 20 ms."""
    held = [c for c in s.spec.com_targets if c.window is not None and c.priority.name == "HARD"]
    target = held[0]
    number = target.name.split(" ", 1)[0]
    starts = s.spec.phase_start_times()
    t0 = min(float(t) for ph, t in zip(s.spec.phases, starts, strict=True) if ph.name.split(" ", 1)[0] == number)
    lo, hi = target.window
    pt, p = np.asarray(s.plan.t), _com(s.robot, s.plan.q)[:, :2]
    step = max(1, int(round(0.02 / s.execution.timestep)))
    xt, x = np.asarray(s.execution.t)[::step], _com(s.robot, _every(s))[:, :2]
    pin_p, pin_x = (pt >= lo - 1e-9) & (pt <= hi + 1e-9), (xt >= lo - 1e-9) & (xt <= hi + 1e-9)
    mean = (p[pin_p] - p[int(np.argmin(np.abs(pt - t0)))]).mean(axis=0)
    size = float(np.linalg.norm(mean))
    achieved = float(np.median((x[pin_x] - x[int(np.argmin(np.abs(xt - t0)))]) @ (mean / size)))
    return achieved, size


def lean(s: Sim) -> tuple[bool, str]:
    achieved, planned = held_com_shift(s)
    r = achieved / planned
    return r >= 0.8, f"CoM held {1000 * achieved:.0f} mm, {100 * r:.0f} % of the plan's {1000 * planned:.0f} mm"


def frame_turn(role: str) -> Callable[[Sim], tuple[bool, str]]:
    import pinocchio as pin

    def check(s: Sim) -> tuple[bool, str]:
        def angles(qs):
            m = _fk(s.robot, qs, role)
            return np.array([np.linalg.norm(pin.log3(m[0, :, :3].T @ r[:, :3])) for r in m])
        r = float(angles(_every(s)).max() / angles(s.plan.q).max())
        return r >= 0.8, f"{role} turned {100 * r:.0f} % of the plan's angle"
    return check


def feet_flight(s: Sim) -> tuple[bool, str]:
    ex, spec = s.execution, s.spec
    planned = sum(ph.duration for ph in spec.phases if not ph.contacts)
    fz = [f[:, 2] for f in ex.contact_forces.values()]
    air = float(np.count_nonzero(np.all([f < 1.0 for f in fz], axis=0))) * ex.timestep
    return air >= 0.25 * planned, f"both soles unloaded {air:.3f} s of the planned {planned:.2f} s flight"


def base_travel(s: Sim) -> tuple[bool, str]:
    p = float(np.linalg.norm(s.plan.q[-1, :2] - s.plan.q[0, :2]))
    x = float(np.linalg.norm(s.execution.q[-1, :2] - s.execution.q[0, :2]))
    return x >= 0.8 * p, f"base moved {x:.3f} m of the plan's {p:.3f} m"


def base_yaw(s: Sim) -> tuple[bool, str]:
    def yaw(q):
        x, y, z, w = q[3:7]
        return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    p = abs(yaw(s.plan.q[-1]) - yaw(s.plan.q[0]))
    x = abs(yaw(s.execution.q[-1]) - yaw(s.execution.q[0]))
    return x >= 0.8 * p, f"base turned {math.degrees(x):.0f} deg of the plan's {math.degrees(p):.0f}"


def sole_rise(s: Sim) -> tuple[bool, str]:
    best = None
    for role in ("left_foot", "right_foot"):
        p = _fk(s.robot, s.plan.q, role)[:, 2, 3]
        x = _fk(s.robot, _every(s), role)[:, 2, 3]
        if p.max() - p[0] > 0.01:
            r = (x.max() - x[0]) / (p.max() - p[0])
            best = r if best is None else min(best, r)
    if best is None:
        return True, "no sole planned to rise"
    return best >= 0.8, f"soles rose {100 * best:.0f} % of the plan's height"


def hands_follow(s: Sim) -> tuple[bool, str]:
    worst = 0.0
    idx = np.searchsorted(s.execution.t, s.plan.t).clip(0, len(s.execution.t) - 1)
    for role in ("left_hand", "right_hand"):
        p = _fk(s.robot, s.plan.q, role)[:, :, 3]
        x = _fk(s.robot, s.execution.q[idx], role)[:, :, 3]
        worst = max(worst, float(np.max(np.linalg.norm(p - x, axis=1))))
    return worst <= 0.05, f"hands within {worst:.3f} m of the planned hands"


def hand_moves(s: Sim) -> tuple[bool, str]:
    """The hand the plan moves (farthest from where it started, 3 cm or more) goes at least 80 % as
    far from its start in the simulation (peak), and both hands stay within 5 cm of the plan's
    hands (:func:`hands_follow`): the gesture's size and its path."""
    worst = math.inf
    for role in ("left_hand", "right_hand"):
        p = _fk(s.robot, s.plan.q, role)[:, :, 3]
        x = _fk(s.robot, _every(s), role)[:, :, 3]
        far = float(np.max(np.linalg.norm(p - p[0], axis=1)))
        if far >= 0.03:
            worst = min(worst, float(np.max(np.linalg.norm(x - x[0], axis=1))) / far)
    follow, words = hands_follow(s)
    if not math.isfinite(worst):
        return follow, f"no hand planned to move 3 cm; {words}"
    return worst >= 0.8 and follow, f"hand moved {100 * worst:.0f} % as far as planned; {words}"


def hands_crossed(s: Sim) -> tuple[bool, str]:
    """Both hands on the other side of the body's midline (the start base's x-z plane) at once."""
    qs = _every(s)
    base = _fk(s.robot, qs[:1], "torso")[0] if s.robot.has_role("torso") else None
    R = np.eye(3) if base is None else base[:, :3]
    mid = qs[0, :3] if base is None else base[:, 3]
    left = (_fk(s.robot, qs, "left_hand")[:, :, 3] - mid) @ R[:, 1]
    right = (_fk(s.robot, qs, "right_hand")[:, :, 3] - mid) @ R[:, 1]
    across = float(np.max(np.minimum(-left, right)))  # > 0: the left hand right of the midline and the right hand left
    return across > 0.0, f"both hands {1000 * across:.0f} mm past the midline at the most"


def base_arc(s: Sim) -> tuple[bool, str]:
    """The base's yaw, unwrapped along the motion (a full circle is 360 deg, not 0): turned at
    least 80 % of the plan's, and moved at least 80 % as far from where it started (peak)."""
    def yaw(qs):
        x, y, z, w = qs[:, 3], qs[:, 4], qs[:, 5], qs[:, 6]
        return np.unwrap(np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)))
    qp, qx = s.plan.q, _every(s)
    turned_p, turned_x = abs(yaw(qp)[-1] - yaw(qp)[0]), abs(yaw(qx)[-1] - yaw(qx)[0])
    far_p = float(np.max(np.linalg.norm(qp[:, :2] - qp[0, :2], axis=1)))
    far_x = float(np.max(np.linalg.norm(qx[:, :2] - qx[0, :2], axis=1)))
    ok = turned_x >= 0.8 * turned_p and far_x >= 0.8 * far_p
    return ok, (f"base turned {math.degrees(turned_x):.0f} deg of the plan's {math.degrees(turned_p):.0f}, "
                f"went {far_x:.2f} m of {far_p:.2f} m out")


def jog(s: Sim) -> tuple[bool, str]:
    """A run: flights (:func:`feet_flight`) and the distance (:func:`base_travel`)."""
    (a, wa), (b, wb) = feet_flight(s), base_travel(s)
    return a and b, f"{wa}; {wb}"


def _object(s: Sim):
    """The scene object the sentence names (its name in the sentence's text), else the first movable one."""
    objects = list(s.spec.scene.objects) if s.spec.scene is not None else []
    text = getattr(s.actions, "text", "") or ""
    named = [o for o in objects if o.name in text] + [o for o in objects if o.movable]
    return named[0] if named else None


def object_lifted(s: Sim) -> tuple[bool, str]:
    """Every grasp that asks for a lift: the object's MuJoCo centre over its hold window at least
    80 % of the asked height above where it stood (median); with a place, it ends within 3 cm of it."""
    ex, ok, words = s.execution, True, []
    for g in s.spec.grasps:
        z = np.asarray(ex.objects[g.object])
        t = np.asarray(ex.t)
        if g.lift > 0 and g.hold is not None:
            rows = (t >= g.hold[0]) & (t <= g.hold[1])
            rise = float(np.median(z[rows, 2]) - z[0, 2])
            ok &= rise >= 0.8 * g.lift
            words.append(f"{g.object} held {1000 * rise:.0f} mm up of the asked {1000 * g.lift:.0f} mm")
        if g.place is not None:
            off = float(np.linalg.norm(z[-1] - np.asarray(g.place)))
            ok &= off <= 0.03
            words.append(f"put down {1000 * off:.0f} mm from its place")
    return bool(ok and words), "; ".join(words) or "no lift asked"


def object_pushed(s: Sim) -> tuple[bool, str]:
    """The pushed object's MuJoCo centre moves at least 80 % of the push's distance along the way
    the robot faces (the action's ``distance``)."""
    (act,) = [a for a in s.actions.actions if a.name == "push"]
    obj = _object(s)
    z = np.asarray(s.execution.objects[obj.name])
    moved = float(z[-1, 0] - z[0, 0])
    want = float(act.params["distance"])
    return moved >= 0.8 * want, f"{obj.name} moved {1000 * moved:.0f} mm of the asked {1000 * want:.0f} mm"


def object_held_out(s: Sim) -> tuple[bool, str]:
    """A hand-over: over the hold-out window the object's MuJoCo centre is at least 0.15 m above
    where it stood, 0.25-0.7 m ahead of the feet's middle (simulated soles, Pinocchio) along the
    way the robot faces, and still (within 2 cm of its median)."""
    (g,) = [g for g in s.spec.grasps if g.offer is not None]
    t = np.asarray(s.execution.t)
    obj = np.asarray(s.execution.objects[g.object])
    rows = (t >= g.offer_window[0]) & (t <= g.offer_window[1])
    mid = np.median(obj[rows], axis=0)
    q = s.execution.q[int(np.flatnonzero(rows)[0])]
    feet = [_fk(s.robot, q[None], role)[0] for role in ("left_foot", "right_foot")]
    centre = 0.5 * (feet[0][:3, 3] + feet[1][:3, 3])
    forward = feet[0][:3, 0] + feet[1][:3, 0]
    forward[2] = 0.0
    ahead = float((mid - centre) @ (forward / np.linalg.norm(forward)))
    up = float(mid[2] - obj[0, 2])
    still = float(np.linalg.norm(obj[rows] - mid, axis=1).max())
    ok = up >= 0.15 and 0.25 <= ahead <= 0.7 and still <= 0.02
    return ok, f"{g.object} held out {ahead:.2f} m ahead, {up:.2f} m above where it stood, still within {1000 * still:.0f} mm"


def soles_at_height(s: Sim) -> tuple[bool, str]:
    """Up (down) stairs or a slope: both soles (simulated, Pinocchio) end within 1 cm of the height
    of the top (the floor), computed from the scene's numbers."""
    scene = s.spec.scene
    top = (scene.stairs[0].rise * scene.stairs[0].count if scene.stairs
           else scene.slopes[0].length * math.tan(scene.slopes[0].angle))
    want = top if any(a.name == "step_up" for a in s.actions.actions) else 0.0
    soles = [_fk(s.robot, s.execution.q[-1:], role)[0][2, 3] for role in ("left_foot", "right_foot")]
    stand = _fk(s.robot, s.robot.q_standing[None], "left_foot")[0][2, 3]
    off = max(abs(z - stand - want) for z in soles)
    return off <= 0.01, f"soles end {1000 * off:.0f} mm from the {'top' if want else 'floor'} ({want:.2f} m)"


def hand_at_object(s: Sim) -> tuple[bool, str]:
    """A hand's collision meshes (every link below its frame's joint) within 1 cm of the object's
    box (coal; the box where MuJoCo has it, a movable one's centre from the run) at some instant
    every 50 ms: the hand touched it."""
    import coal  # type: ignore[import-untyped]
    import pinocchio as pin

    obj = _object(s)
    robot, model = s.robot, s.robot.model
    gm = robot.collision_model
    box = coal.Box(*[float(v) for v in obj.size])
    R = pin.rpy.rpyToMatrix(np.asarray(getattr(obj, "rpy", (0.0, 0.0, 0.0)), dtype=float))
    step = max(1, int(round(0.05 / s.execution.timestep)))
    centres = np.asarray(s.execution.objects[obj.name])[::step] if obj.name in s.execution.objects else None
    data, gd = model.createData(), pin.GeometryData(gm)
    best = math.inf
    for side in ("left", "right"):
        sub = set(model.subtrees[model.frames[robot.frame_id(f"{side}_hand")].parentJoint])
        geoms = [i for i, o in enumerate(gm.geometryObjects) if o.parentJoint in sub]
        for n, q in enumerate(s.execution.q[::step]):
            pin.updateGeometryPlacements(model, data, gm, gd, q)
            c = np.asarray(obj.position, dtype=float) if centres is None else centres[min(n, len(centres) - 1)]
            T = coal.Transform3s(R, c)
            for i in geoms:
                d = coal.distance(gm.geometryObjects[i].geometry,
                                  coal.Transform3s(gd.oMg[i].rotation, gd.oMg[i].translation), box, T,
                                  coal.DistanceRequest(), coal.DistanceResult())
                best = min(best, max(float(d), 0.0))
    return best <= 0.01, f"a hand's meshes {1000 * best:.0f} mm from the {obj.name} at the closest"


def _facing_axis(s: Sim, role: str) -> np.ndarray:
    """The ``role`` frame's local axis that points forward (world +x) standing."""
    import pinocchio as pin

    data = s.robot.model.createData()
    pin.framesForwardKinematics(s.robot.model, data, s.robot.q_standing)
    R = data.oMf[s.robot.frame_id(role)].rotation
    k = int(np.argmax(np.abs(R[0])))
    return np.sign(R[0, k]) * np.eye(3)[k]


def looks_at(s: Sim) -> tuple[bool, str]:
    """The head's forward axis within 15 deg of the object's centre at some instant."""
    obj = _object(s)
    m = _fk(s.robot, _every(s), "head")
    ahead = m[:, :, :3] @ _facing_axis(s, "head")
    to = np.asarray(obj.position) - m[:, :, 3]
    cos = np.sum(ahead * to, axis=1) / np.linalg.norm(to, axis=1)
    best = float(np.degrees(np.arccos(np.clip(cos, -1, 1))).min())
    return best <= 15.0, f"head {best:.0f} deg from the {obj.name} at the closest"


def points_at(s: Sim) -> tuple[bool, str]:
    """An arm (shoulder to hand) within 20 deg of the way from its shoulder to the object's centre."""
    obj = _object(s)
    best = math.inf
    for side in ("left", "right"):
        hand = _fk(s.robot, _every(s), f"{side}_hand")[:, :, 3]
        root = _fk(s.robot, _every(s), f"{side}_shoulder")[:, :, 3]
        arm, to = hand - root, np.asarray(obj.position) - root
        cos = np.sum(arm * to, axis=1) / (np.linalg.norm(arm, axis=1) * np.linalg.norm(to, axis=1))
        best = min(best, float(np.degrees(np.arccos(np.clip(cos, -1, 1))).min()))
    return best <= 20.0, f"arm {best:.0f} deg from the {obj.name} at the closest"


def _mesh_gap(s: Sim, a: str, b: str, qs: np.ndarray) -> float:
    """Smallest coal distance between the meshes below frames ``a`` and ``b`` over ``qs``. A frame
    whose joint carries the other's (G1's head, fixed on the torso that carries the arms) counts
    its own link's meshes only: the torso's and the arms' are not the head."""
    import pinocchio as pin

    robot = s.robot
    model = robot.model
    gm = robot.collision_model.copy()
    gm.removeAllCollisionPairs()

    def below(frame: str, other: str) -> list[int]:
        fid = robot.frame_id(frame)
        j = model.frames[fid].parentJoint
        if j in set(model.supports[model.frames[robot.frame_id(other)].parentJoint]):
            name = model.frames[fid].name
            return [i for i, o in enumerate(gm.geometryObjects) if model.frames[o.parentFrame].name == name]
        sub = set(model.subtrees[j])
        return [i for i, o in enumerate(gm.geometryObjects) if o.parentJoint in sub]

    for i in below(a, b):
        for j in below(b, a):
            gm.addCollisionPair(pin.CollisionPair(min(i, j), max(i, j)))
    gd, data = gm.createData(), model.createData()
    best = math.inf
    for q in qs:
        pin.computeDistances(model, data, gm, gd, q)
        best = min(best, min(max(r.min_distance, 0.0) for r in gd.distanceResults))
    return best


def hands_meet(s: Sim) -> tuple[bool, str]:
    gap = _mesh_gap(s, "left_hand", "right_hand", _every(s, 0.05))
    return gap <= 0.01, f"hands' meshes {gap:.3f} m apart at the closest"


def hand_at_head(s: Sim) -> tuple[bool, str]:
    gaps = [_mesh_gap(s, f"{side}_hand", "head", _every(s, 0.05)) for side in ("left", "right")]
    gap = min(gaps)
    return gap <= 0.03, f"hand's meshes {gap:.3f} m from the head's at the closest"


def pointing(s: Sim) -> tuple[bool, str]:
    best = math.inf
    want = {"left": (0, 1, 0), "right": (0, -1, 0), "up": (0, 0, 1), "down": (0, 0, -1), "forward": (1, 0, 0)}
    named = [t.name.rsplit("pointing ", 1)[-1] for t in s.spec.targets if "pointing " in t.name]
    d = np.array(want.get(named[0] if named else "forward", (1, 0, 0)), dtype=float)
    for side in ("left", "right"):
        hand = _fk(s.robot, _every(s), f"{side}_hand")[:, :, 3]
        root = _fk(s.robot, _every(s), f"{side}_shoulder" if s.robot.has_role(f"{side}_shoulder") else "torso")[:, :, 3]
        arm = hand - root
        cos = (arm @ d) / np.linalg.norm(arm, axis=1)
        best = min(best, float(np.degrees(np.arccos(np.clip(cos, -1, 1))).min()))
    vertical = abs(d[2]) > 0.5
    return best <= (30.0 if vertical else 20.0), f"arm {best:.0f} deg from the named direction at the closest"


def stand(s: Sim) -> tuple[bool, str]:
    x = float(np.linalg.norm(s.execution.q[-1, :2] - s.execution.q[0, :2]))
    return x <= 0.01, f"base moved {x:.3f} m"


#: action -> its independent intent check (Pinocchio FK, coal, MuJoCo forces; no wbmp check).
INDEPENDENT: dict[str, Callable[[Sim], tuple[bool, str]]] = {
    "stand": stand, "squat": com_axis(2), "lean": lean, "bow": frame_turn("torso"),
    "raise_arms": hands_follow, "turn_head": frame_turn("head"), "nod": frame_turn("head"),
    "shake_head": frame_turn("head"), "clap": hands_meet, "salute": hand_at_head, "point": pointing,
    "wave": hands_follow, "punch": hands_follow, "touch": hand_at_head, "hands_on_hips": hands_follow,
    "arms_out": hands_follow, "step": base_travel, "walk": base_travel, "turn": base_yaw, "jump": feet_flight,
    "hop": feet_flight, "kick": sole_rise, "march": sole_rise, "stomp": sole_rise, "balance": sole_rise,
    "lunge": base_travel, "reach": hand_moves, "cross_arms": hands_crossed, "arm_circles": hand_moves,
    "shrug": hand_moves, "stretch": hand_moves, "walk_arc": base_arc, "jog": jog,
    "pick_up": object_lifted, "put_down": object_lifted, "push": object_pushed, "touch_object": hand_at_object,
    "look_at": looks_at, "point_at": points_at, "walk_to": base_travel, "hand_over": object_held_out,
    "step_up": soles_at_height, "step_down": soles_at_height,
}


def mesh_collisions(robot, qs: np.ndarray) -> dict[tuple[str, str], int]:
    """Link pairs whose URDF collision meshes intersect (coal), with how many of ``qs`` they do so
    at: every pair of geometries on joints more than two apart along the chain (a wrist folds its
    hand into its forearm by construction) whose meshes are at least 2 mm apart standing (built
    touching: they cannot be kept apart from the first instant)."""
    import coal  # type: ignore[import-untyped]
    import pinocchio as pin

    model, cm = robot.model, robot.collision_model
    objs = cm.geometryObjects
    data, gd = model.createData(), pin.GeometryData(cm)

    def near(ja: int, jb: int) -> bool:
        up = {ja: [ja, model.parents[ja], model.parents[model.parents[ja]]],
              jb: [jb, model.parents[jb], model.parents[model.parents[jb]]]}
        return ja in up[jb] or jb in up[ja]

    def placed(q):
        pin.updateGeometryPlacements(model, data, cm, gd, q)
        return [coal.Transform3s(gd.oMg[i].rotation, gd.oMg[i].translation) for i in range(len(objs))]

    rest = placed(robot.q_standing)
    pairs = [(i, j) for i in range(len(objs)) for j in range(i + 1, len(objs))
             if not near(int(objs[i].parentJoint), int(objs[j].parentJoint))
             and coal.distance(objs[i].geometry, rest[i], objs[j].geometry, rest[j], coal.DistanceRequest(),
                               coal.DistanceResult()) >= 0.002]
    hits: dict[tuple[str, str], int] = {}
    for q in qs:
        T = placed(q)
        for i, j in pairs:
            if coal.collide(objs[i].geometry, T[i], objs[j].geometry, T[j], coal.CollisionRequest(), coal.CollisionResult()):
                key = (model.frames[objs[i].parentFrame].name, model.frames[objs[j].parentFrame].name)
                hits[key] = hits.get(key, 0) + 1
    return hits


def run_one(robot_name: str, action: str, sentence: str, scene: str | None = None) -> dict:
    from language.exceptions import LanguageError
    from planner import CacheSettings, PlannerSettings, plan
    from sim import SimSettings, simulate
    from tasks.exceptions import TaskError
    from wbmp.pipeline import SolveRequest, build_spec

    row: dict = {"robot": robot_name, "action": action, "sentence": sentence}
    if scene:
        row["scene"] = Path(scene).name
    t0 = time.perf_counter()
    try:
        from robots import load_robot

        start = start_state(load_robot(robot_name), *STARTS[action]) if action in STARTS else None
        robot, spec, actions = build_spec(SolveRequest(instruction=sentence, robot=robot_name, start=start,
                                                       scene_path=str(ROOT / scene) if scene else None))
    except (TaskError, LanguageError) as e:  # a refusal is a result: reported with its reason
        row.update(status="refused", reason=str(e).splitlines()[0])
        return row
    p = plan(spec, robot, settings=PlannerSettings(cache=CacheSettings(compile=False)), throw=False)
    if not p.ok:
        row.update(status="not planned", reason=p.stats.status.name)
        return row
    ex = simulate(p, robot, settings=SimSettings(settle_time=0.2))
    met, figure = INDEPENDENT[action](Sim(robot, spec, p, ex, actions))
    cert = ex.certificate
    intent = [c for c in cert.checks if c.kind.value.startswith("intent") or c.kind.value == "self_collision_mesh"]
    row.update(status="certified" if cert.ok else "failed", certified=cert.ok, intent_met=met, figure=figure,
               reason=cert.reason, intent_lines_failed=[c.message for c in intent if not c.ok],
               seconds=round(time.perf_counter() - t0, 1))
    row["silent_wrong"] = bool(cert.ok and not met)
    if cert.ok:  # issue 37: on the meshes no certified motion has a colliding pair
        row["mesh_plan"] = {" / ".join(k): n for k, n in mesh_collisions(robot, p.q).items()}
        sim_q = _every(Sim(robot, spec, p, ex), 0.08)
        row["mesh_sim"] = {" / ".join(k): n for k, n in mesh_collisions(robot, sim_q).items()}
    return row


def markdown(rows: list[dict]) -> str:
    lines = ["| robot | action | sentence | planned | certified | intent met (independent) | figure | "
             "certificate's first failure | colliding mesh pairs, plan / simulation (coal) |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        planned = "refused" if r["status"] == "refused" else ("no" if r["status"] == "not planned" else "yes")
        cert = "yes" if r.get("certified") else ("—" if planned != "yes" else "no")
        met = {True: "yes", False: "**no**"}.get(r.get("intent_met"), "—")
        mesh = ""
        if "mesh_plan" in r:
            mesh = "; ".join(f"{k} {w}" for w, d in (("plan", r["mesh_plan"]), ("sim", r["mesh_sim"])) for k in d) or "none"
        where = f" ({r['scene']})" if r.get("scene") else ""
        lines.append(f"| {r['robot']} | {r['action']} | {r['sentence']}{where} | {planned} | {cert} | {met} | "
                     f"{r.get('figure', '')} | {r.get('reason', '')} | {mesh} |")
    n = [r for r in rows if r["status"] != "refused"]
    lines.append("")
    lines.append(f"{len(rows)} sentences, {len(n)} in scope (not refused), "
                 f"{sum(bool(r.get('certified')) for r in n)} certified, "
                 f"{sum(bool(r.get('intent_met')) for r in n)} met their intent (independent), "
                 f"{sum(bool(r.get('silent_wrong')) for r in n)} silent wrong motions (certified, intent missed), "
                 f"{sum(bool(r.get('mesh_plan') or r.get('mesh_sim')) for r in n)} certified with a colliding mesh pair.")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--robots", default="talos,g1", help="comma-separated robots (default: talos,g1)")
    ap.add_argument("--actions", default="", help="comma-separated actions (default: every one of SENTENCES and "
                                                   "SCENE_SENTENCES)")
    ap.add_argument("--json", default="", help="write the rows as JSON here")
    ap.add_argument("--markdown", default="", help="write the Markdown table here")
    args = ap.parse_args(argv)
    every = {**{a: tuple((t, None) for t in ts) for a, ts in SENTENCES.items()},
             **{a: tuple((t, sc) for t, sc in ts) for a, ts in SCENE_SENTENCES.items()}}
    actions = [a for a in args.actions.split(",") if a] or list(every)
    unknown = sorted(set(actions) - set(every))
    if unknown:
        ap.error(f"unknown action(s) {', '.join(unknown)}; choose from {', '.join(every)}")
    rows = []
    for robot in [r for r in args.robots.split(",") if r]:
        for action in actions:
            for sentence, scenes in every[action]:
                row = run_one(robot, action, sentence, None if scenes is None else scenes[robot])
                rows.append(row)
                print(f"{robot:6} {action:13} {row['status']:11} intent met: {row.get('intent_met', '-')!s:5} "
                      f"{row.get('figure', row.get('reason', ''))}"
                      + (f" | mesh plan {row['mesh_plan'] or 'none'}, sim {row['mesh_sim'] or 'none'}" if "mesh_plan" in row else ""),
                      flush=True)
    text = markdown(rows)
    print(text)
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1, default=lambda o: o.item() if hasattr(o, "item") else str(o)))
    if args.markdown:
        Path(args.markdown).write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
