"""walk_to around an object and touch_object, planned and run in MuJoCo with the whole-body
controller: the certificate passes, the robot's closest approach to the obstacle (MuJoCo) stays
clear, and the touching hand really touches the box (MuJoCo contacts) while nothing else does."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import planner
from language import parse
from planner.results import CheckKind
from robots import load_robot
from sim import simulate
from tasks.compose import compile_actions
from tasks.primitives.route import footprint_distance
from tasks.scene import Scene, SceneObject

POST = SceneObject(name="post", shape="cylinder", size=(0.05, 1.2), position=(0.43, 0.51, 0.6))
BOX = SceneObject(name="box", shape="box", size=(0.3, 0.3, 0.7), position=(0.9, 0.8, 0.35),
                  colour=(0.1, 0.25, 0.8, 1.0), aliases=("盒子",))


@pytest.fixture(autouse=True)
def _no_compilation(monkeypatch, tmp_path):
    monkeypatch.setenv("WBMP_COMPILE", "0")
    monkeypatch.setenv("WBMP_CACHE_DIR", str(tmp_path / "cache"))


def _run(sentence: str, robot_name: str, scene: Scene, dt: float = 0.1):
    robot = load_robot(robot_name)
    spec = compile_actions(parse(sentence).actions, robot, dt=dt, scene=scene)
    plan = planner.plan(spec, robot,
                        settings=planner.PlannerSettings(cache=planner.CacheSettings(compile=False)),
                        throw=False)
    assert plan.ok, f"{plan.stats.status.value}: {plan.diagnosis}"
    return robot, spec, plan, simulate(plan, robot)


@pytest.mark.long  # in make test-long: the 2-core suite stays under 10 minutes (~29 s; talos touching the box below is certified with a scene)
@pytest.mark.slow
def test_g1_walks_around_a_post_to_the_box_certified_in_mujoco():
    """The post stands in the straight line to the box: the footsteps go around it (every sole
    frame more than 0.1 m from its footprint, the sole's half length), and in MuJoCo nothing
    touches it or the box (the closest approach stays positive) and the certificate passes."""
    scene = Scene(name="a post in the way", objects=(POST, BOX))
    robot, spec, plan, execution = _run("walk to the box", "g1", scene, dt=0.075)  # at 0.1 s a swing sole scuffs
    soles = [c.placement.position for p in spec.phases for c in p.contacts]
    assert len({p.name.split(": ")[1] for p in spec.phases if ": leg " in p.name}) >= 2  # a route, not a line
    assert min(float(footprint_distance(POST, np.array(s[:2]))[0]) for s in soles) > 0.1
    cert = execution.certificate
    assert cert.ok, cert.reason
    (scene_check,) = [c for c in cert.checks if c.kind == CheckKind.SCENE_COLLISION]
    assert scene_check.value > 0.0, scene_check.name  # closest approach [mm], no contact


@pytest.mark.slow
def test_talos_touches_the_box_certified_in_mujoco():
    """"摸一下那个盒子": MuJoCo reports contacts between the touching hand and the box, all inside the
    planned touch; the certificate passes and names the touch."""
    box = SceneObject(name="box", shape="box", size=(0.4, 0.4, 0.75), position=(0.75, 0.0, 0.375), aliases=("盒子",))
    scene = Scene(name="one box", objects=(box,))
    _, spec, _, execution = _run("摸一下那个盒子", "talos", scene)
    cert = execution.certificate
    assert cert.ok, cert.reason
    (scene_check,) = [c for c in cert.checks if c.kind == CheckKind.SCENE_COLLISION]
    assert "planned touch" in scene_check.name and "'box'" in scene_check.name, scene_check.name


@pytest.mark.long  # minutes on 2 cores (a plan and its run); fast twins: tests/sim/test_touch_intent.py (the
# certificate's line on made-up configurations) and tests/tasks/test_touch_object.py (the posed hand reaches the box)
def test_talos_touches_the_red_box_on_the_counter():
    """"touch the red box" (examples/scenes/box_on_counter.json; issue 37: certified while the hand's
    meshes stopped 47 mm short of the box). Now certified with its touch_object line, and
    independently: the left hand's meshes (every link below the hand frame's joint) within 1 cm
    of the box over the held window (coal, the box where MuJoCo has it; median), and the box moved
    less than 1 cm (a touch, not a push)."""
    import coal
    import pinocchio as pin

    from tasks.scene import load_scene

    scene = load_scene(Path(__file__).resolve().parents[2] / "examples" / "scenes" / "box_on_counter.json")
    # at the default knot spacing (0.075 s, as wbmp solve and bench_intent plan it); at 0.1 s the hand
    # moved the box 2.2 cm between knots (the certificate's "objects not held" line failed)
    robot, spec, _, ex = _run("touch the red box", "talos", scene, dt=0.075)
    assert ex.certificate.ok, ex.certificate.reason
    (line,) = [c for c in ex.certificate.checks if c.name.startswith("intent: touch object")]
    (target,) = [t for t in spec.targets if t.touch == "red box"]
    box = scene.get("red box")
    model, gm = robot.model, robot.collision_model
    sub = set(model.subtrees[model.frames[robot.frame_id(target.frame)].parentJoint])
    geoms = [i for i, o in enumerate(gm.geometryObjects) if o.parentJoint in sub]
    data, gd = model.createData(), pin.GeometryData(gm)
    t, where = np.asarray(ex.t), np.asarray(ex.objects["red box"])
    rows = np.flatnonzero((t >= target.window[0]) & (t <= target.window[1]))[::25]
    gaps = []
    for n in rows:
        pin.updateGeometryPlacements(model, data, gm, gd, ex.q[n])
        at = coal.Transform3s(np.eye(3), where[n])
        gaps.append(min(max(0.0, coal.distance(gm.geometryObjects[i].geometry,
                                               coal.Transform3s(gd.oMg[i].rotation, gd.oMg[i].translation),
                                               coal.Box(*box.size), at, coal.DistanceRequest(), coal.DistanceResult()))
                        for i in geoms))
    assert float(np.median(gaps)) <= 0.01 and line.ok
    assert np.linalg.norm(where[-1] - np.asarray(box.position)) < 0.01
