"""hand_over planned and simulated on talos in the kitchen (examples/scenes/kitchen.json, seen from
where the robot stands at the table), and push planned and simulated: the planned hand (Pinocchio on
the planned configurations) at its targets, the simulated cup (its MuJoCo body) at the hand-over
point, the pushed box (its MuJoCo body) moved by the asked distance."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from language import parse
from planner import plan
from sim import simulate
from sim.grasp import OFFER_TOLERANCE, PUSH_TOLERANCE
from sim.zmp import plan_zmp_excursion
from tasks.compose import compile_actions
from tasks.scene import Scene, SceneObject, load_scene

KITCHEN = Path(__file__).resolve().parents[2] / "examples" / "scenes" / "kitchen.json"
AT_THE_TABLE = -0.75  # [m] the kitchen moved along x so that the table's edge is 0.45 m ahead of the robot


def _kitchen_at_the_table() -> Scene:
    """The kitchen with every object moved by AT_THE_TABLE along x: the robot stands at the table, the
    cup 0.57 m ahead and 0.2 m to the left (no walk needed; the walk is tested with pick_up)."""
    k = load_scene(KITCHEN)
    objects = tuple(dataclasses.replace(o, position=(o.position[0] + AT_THE_TABLE, o.position[1], o.position[2]))
                    for o in k.objects)
    return dataclasses.replace(k, objects=objects)


def _frame_positions(talos, q: np.ndarray, frame: str, offset=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Where ``offset`` (in ``frame``) is on each configuration (Pinocchio) (T, 3)."""
    model, data = talos.model, talos.data()
    fid = model.getFrameId(frame)
    out = []
    for qk in q:
        pin.framesForwardKinematics(model, data, qk)
        out.append(data.oMf[fid].act(np.asarray(offset, dtype=float)))
    return np.array(out)


@pytest.mark.long  # in make test-long: the 2-core suite stays under 10 minutes (~53 s; tests/tasks/test_handover_push.py plans the hand-over; the grasp sims run the grasp in MuJoCo)
@pytest.mark.slow
def test_pick_up_the_cup_and_hand_it_to_me_in_the_kitchen(talos):
    """"pick up the cup and hand it to me": the planned hand frame (Pinocchio) stays within its 4 mm
    tolerance of the hand-over target over the hold-out window; in MuJoCo the cup's body stays within
    the certificate's 3 cm of the hand-over point over that window (0.35-0.45 m ahead, more than
    0.25 m above where the cup stood on the table), within 2 cm of where the simulated hand holds it
    (Pinocchio on the simulated configurations), and the certificate passes."""
    scene = _kitchen_at_the_table()
    spec = compile_actions(list(parse("pick up the cup and hand it to me").actions), talos, scene=scene)
    (g,) = spec.grasps
    target = next(t for t in spec.targets if t.name.endswith("holds the cup out"))
    motion = plan(spec, talos)
    w0, w1 = g.offer_window
    planned = (motion.t >= w0 - 1e-9) & (motion.t <= w1 + 1e-9)
    hand = _frame_positions(talos, motion.q[planned], g.frame)
    assert np.linalg.norm(hand - np.asarray(target.position), axis=1).max() <= target.tolerance + 1e-4
    run = simulate(motion, talos)
    assert run.certificate.ok, run.certificate.summary()
    offer = np.asarray(g.offer)
    cup_start = next(o.position for o in scene.objects if o.name == "cup")
    assert 0.35 <= offer[0] <= 0.45 and offer[2] - cup_start[2] > 0.25, offer
    cup, t = run.objects["cup"], run.t
    window = (t >= w0) & (t <= w1)
    assert np.linalg.norm(cup[window] - offer, axis=1).max() <= OFFER_TOLERANCE
    held = _frame_positions(talos, run.q[window], g.frame, g.offset)
    assert np.linalg.norm(cup[window] - held, axis=1).max() < 0.02


TABLE = SceneObject(name="table", shape="box", size=(0.6, 1.0, 0.72), position=(0.75, 0.0, 0.36))
BOX = SceneObject(name="red box", shape="box", size=(0.15, 0.15, 0.15), position=(0.6, -0.2, 0.795), movable=True,
                  mass=0.5, friction=0.8, aliases=("红色盒子",))
ON_A_TABLE = Scene(name="a box on a table", objects=(TABLE, BOX))


def _push_planned_and_simulated(talos, sentence: str, distance: float) -> None:
    """Plan ``sentence`` (a forward push of the red box by ``distance``) and check the plan, then run it
    in MuJoCo and check what happened to the box (see the tests' docstrings)."""
    spec = compile_actions(list(parse(sentence).actions), talos, scene=ON_A_TABLE)
    motion = plan(spec, talos)
    on = [ft for ft in spec.targets if ft.touch == "red box" and ft.time is not None]
    ks = [int(np.argmin(np.abs(motion.t - ft.time))) for ft in on]
    hand = _frame_positions(talos, motion.q[ks], talos.frame("right_hand"))
    err = np.linalg.norm(hand - np.array([ft.position for ft in on]), axis=1)
    assert (err <= np.array([ft.tolerance for ft in on]) + 1e-4).all(), err
    pushed = [ft for ft in on if "pushes" in ft.name]
    i, j = on.index(pushed[0]) - 1, on.index(pushed[-1])
    assert hand[j, 0] - hand[i, 0] == pytest.approx(distance, abs=0.011)
    # the way in: on the straight line from in front of the box to its face, within the first
    # target's tolerance (a plan that went up over the box's corner and dropped onto the face was 12.6 cm off it)
    pre = next(ft for ft in spec.targets if ft.name.endswith("hand in front of the red box"))
    face = on[i]
    a, b = np.asarray(pre.position), np.asarray(face.position)
    way = (motion.t >= pre.time - 1e-9) & (motion.t <= face.time + 1e-9)
    path = _frame_positions(talos, motion.q[way], talos.frame("right_hand"))
    s = np.clip((path - a) @ (b - a) / ((b - a) @ (b - a)), 0.0, 1.0)
    assert np.linalg.norm(path - (a + s[:, None] * (b - a)), axis=1).max() <= pre.tolerance + 1e-4
    # the plan balances by itself: its full-dynamics ZMP (RNEA) within 5 mm of the support polygon
    assert plan_zmp_excursion(talos, motion) is None, plan_zmp_excursion(talos, motion)
    run = simulate(motion, talos)
    assert run.certificate.ok, run.certificate.summary()
    moved = run.objects["red box"][-1] - np.asarray(BOX.position)
    assert abs(moved[0] - distance) <= PUSH_TOLERANCE and abs(moved[1]) <= PUSH_TOLERANCE and abs(moved[2]) < 0.005, moved
    assert max(run.peak_torque_fractions().values()) <= 0.93, run.peak_torque_fractions()


@pytest.mark.long  # in make test-long: the 2-core suite stays under 10 minutes (~21 s)
@pytest.mark.slow  # ~20 s of CPU (a 13 s plan and its 4 s run)
def test_push_the_red_box_gently_in_mujoco(talos):
    """"push the red box gently" (5 cm): the right hand frame (Pinocchio on the planned configurations)
    is within each target on the box's face of its tolerance at its knot, 5 cm forward in all, and
    comes in to the face within 2 cm of the straight line from in front of it; the plan's own ZMP
    stays in the support polygon; in MuJoCo (no weld: the box slides with its friction) the box's
    body ends within the certificate's 2 cm of 5 cm ahead of where it stood along the heading (+x),
    less than 2 cm across, still on the table (its height within 5 mm), the certificate passes and
    no joint goes beyond 93 % of its torque limit."""
    _push_planned_and_simulated(talos, "push the red box gently", 0.05)


@pytest.mark.long  # ~23 s of CPU (a 16 s plan and its 5 s run); the gentle push above covers the same code
def test_push_the_red_box_10_cm_in_mujoco(talos):
    """"push the red box 10 cm" (the default distance): the same checks, 10 cm."""
    _push_planned_and_simulated(talos, "push the red box 10 cm", 0.1)


@pytest.mark.long  # ~24 s of CPU (a 19 s plan and its 6 s run)
def test_push_the_red_box_20_cm_in_chinese_in_mujoco(talos):
    """把红色盒子往前推20厘米 (push the red box forward 20 cm): the same checks, 20 cm."""
    _push_planned_and_simulated(talos, "把红色盒子往前推20厘米", 0.2)
