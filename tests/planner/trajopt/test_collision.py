"""Self-collision avoidance in the planner (planner/trajopt/collision.py): the CasADi rows against
numpy and finite differences, and plans checked independently with coal on the URDF meshes."""

from __future__ import annotations

import itertools
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from planner import CacheSettings, CollisionSettings, PlannerSettings, SolverSettings, plan
from planner.trajopt.collision import (
    Rows,
    pair_distances,
    select,
    sphere_sets,
    with_collision_terms,
)
from planner.trajopt.layout import make_layout
from planner.trajopt.terms import stage_function
from robots.collision import collision_model, mesh_distances
from tests.planner.trajopt.fd import check_stage_rows

ROOT = Path(__file__).resolve().parents[3]


def _reach_spec(robot, sentence):
    from language import parse
    from tasks.compose import compile_actions

    return compile_actions(parse(sentence).actions, robot)


def _pairs_apart_at_rest(robot) -> list[tuple[str, str]]:
    """Every link pair on joints that are neither the same nor parent and child, whose meshes are
    apart in the standing posture (what a plan must keep apart, independently of the capsules)."""
    cm = collision_model(robot)
    model = robot.model
    out = []
    for a, b in itertools.combinations(sorted(cm.links), 2):
        ja, jb = cm.capsules_of(a)[0].joint, cm.capsules_of(b)[0].joint
        if ja == jb or model.parents[ja] == jb or model.parents[jb] == ja:
            continue
        out.append((a, b))
    rest = mesh_distances(robot, robot.q_standing, out)
    return [p for p in out if rest[p] > 0.0]


def _closest_mesh_pair(robot, q: np.ndarray, pairs) -> tuple[float, tuple[str, str], int]:
    worst = (np.inf, ("", ""), -1)
    for k, qk in enumerate(q):
        d = mesh_distances(robot, qk, pairs)
        pair = min(d, key=d.get)
        if d[pair] < worst[0]:
            worst = (d[pair], pair, k)
    return worst


def test_collision_rows_match_numpy_and_finite_differences(talos):
    """The stage function's collision rows equal |c_i - c_j|^2 from Pinocchio's placements, and their
    Jacobian matches central finite differences, at random chart displacements."""
    spec = _reach_spec(talos, "reach right with your left hand 40 cm")
    lay = make_layout(spec, talos).with_terms([])
    sets = sphere_sets(talos)
    pairs = {("arm_left_5_link", "base_link"), ("gripper_left_base_link", "leg_right_3_link")}
    index = [i for i, p in enumerate(sets.pair_names) if p in pairs]
    assert len(index) == 2
    spheres = {}
    for pi in index:
        n = (sets.starts[pi + 1] if pi + 1 < len(sets.starts) else len(sets.sa)) - sets.starts[pi]
        spheres[pi] = set(range(n))
    rows = Rows(spheres, {pi: {5} for pi in index})
    lay = with_collision_terms(lay, sets, rows, index, 0.01)
    fn = stage_function(lay, list(range(len(lay.terms))), "collision_stage")
    p = np.concatenate([t.params for t in lay.terms])
    def reference(q):
        data = talos.model.createData()
        pin.forwardKinematics(talos.model, data, q)
        expected = []
        for t in lay.terms:
            _, ja, jb, na, nb, chosen = t.structure
            a, b = (int(x) for x in sets.pairs[sets.pair_names.index(t.item)])
            wa = sets.centres[a] @ data.oMi[ja].rotation.T + data.oMi[ja].translation
            wb = sets.centres[b] @ data.oMi[jb].rotation.T + data.oMi[jb].translation
            expected += [float(np.sum((wa[i] - wb[j]) ** 2)) for i, j in chosen]
        assert len(expected) > 10
        return expected

    check_stage_rows(fn, talos, p, reference, seed=7, atol=1e-12)


@pytest.mark.parametrize("name", ["talos", "g1", "romeo", "icub"])
def test_reference_posture_has_no_pair_within_the_margin(name):
    """In the reference (standing) posture, every pair that can get rows is at least the margin
    apart in the planner's sphere model, so a motion that stays near it carries no active row; the
    model is conservative there (coal on the URDF meshes: never closer than the sphere sets). On
    Talos the forearms and the pelvis, the hips and the ankles (the pairs every bench task
    brought to the margin, docs/collisions.md) are more than 1.5 cm apart in the model."""
    from robots import load_robot

    robot = load_robot(name)
    sets = sphere_sets(robot)
    margin = PlannerSettings().collision.margin
    d = pair_distances(robot, sets, robot.q_standing[None])[0]
    names = sets.pair_names
    mesh = mesh_distances(robot, robot.q_standing, names)
    assert len(names) > 100
    for pi, pair in enumerate(names):
        assert d[pi] >= margin, (pair, d[pi])
        assert mesh[pair] >= d[pi] - 1e-6, (pair, mesh[pair], d[pi])
    if name == "talos":
        assert d.min() > margin + 0.005
        screened = {names[pi] for pi in np.flatnonzero(d < PlannerSettings().collision.screening)}
        assert not any("arm" in a or "arm" in b for a, b in screened), screened


def test_screening_selects_only_close_pairs(talos):
    """On the standing posture repeated, no pair is within the screening distance but those that
    are at rest; a pair pushed through the body is selected on its knots only."""
    spec = _reach_spec(talos, "reach right with your left hand 40 cm")
    lay = make_layout(spec, talos)
    sets = sphere_sets(talos)
    q = np.repeat(talos.q_standing[None], lay.N + 1, axis=0)
    d = pair_distances(talos, sets, q)
    assert d.min() >= 0.01 - 1e-9  # pairs closer at rest are skipped by the collision model
    from planner.trajopt.collision import sphere_pair_distances

    far = select(lay, sets, sphere_pair_distances(talos, sets, q), 0.0)
    assert not far.spheres


def test_broad_phase_skips_only_pairs_farther_than_asked(talos):
    """With ``within``, the sphere-pair distances computed are the full computation's (every pair
    written out with Pinocchio's placements), the ones skipped are at least ``within`` apart, most
    are skipped, and the screening selects the same rows and the report the same closest pair."""
    from planner.trajopt.collision import closest, sphere_pair_distances

    spec = _reach_spec(talos, "reach right with your left hand 40 cm")
    lay = make_layout(spec, talos)
    sets = sphere_sets(talos)
    rng = np.random.default_rng(11)
    q = np.repeat(talos.q_standing[None], 12, axis=0)
    q[:, 7:] += rng.normal(scale=0.4, size=q[:, 7:].shape)  # arms and legs through each other
    data = talos.model.createData()
    full = np.empty((len(q), len(sets.sa)))
    for k, qk in enumerate(q):
        pin.forwardKinematics(talos.model, data, qk)
        M = [data.oMi[int(j)] for j in sets.joints[sets.pair_owner]]
        world = np.array([m.rotation @ c + m.translation for m, c in zip(M, sets.pair_local, strict=True)])
        full[k] = (np.linalg.norm(world[sets.sa] - world[sets.sb], axis=1)
                   - sets.pair_radius[sets.sa] - sets.pair_radius[sets.sb])
    part = sphere_pair_distances(talos, sets, q, within=0.03)
    done = np.isfinite(part)
    np.testing.assert_allclose(part[done], full[done], atol=1e-12, rtol=0)
    assert full[~done].min() >= 0.03
    assert (full < 0.0).any() and 0.0 < done.mean() < 0.2
    a, b = select(lay, sets, part, 0.03), select(lay, sets, full, 0.03)
    assert a.spheres == b.spheres and a.knots == b.knots and a.spheres
    d, _, pair = closest(talos, sets, q, np.arange(len(q)) * 0.1)
    k, pi = np.unravel_index(int(np.argmin(np.minimum.reduceat(full, sets.starts, axis=1))), (len(q), len(sets.pairs)))
    assert d == pytest.approx(np.minimum.reduceat(full, sets.starts, axis=1)[k, pi], abs=1e-12)
    assert pair == sets.pair_names[pi]


def test_idle_pairs_get_no_rows_until_the_guess_brings_them_closer(talos):
    """Talos's ankles and hips are within the screening distance at rest; a guess that keeps them
    there (the squat's nominal motion) gives them no rows (the pairs are left to the check after the
    solve), and a guess that swings the legs' ankles closer gives the ankle pair its rows again."""
    from planner.trajopt.api import (
        _formulation,
        _guess_configurations,
        add_screened_collision_terms,
    )
    from planner.trajopt.collision import IDLE_TOLERANCE, idle_pairs, sphere_pair_distances

    settings = PlannerSettings(cache=CacheSettings(compile=False))
    sets = sphere_sets(talos)
    ankles = sets.pair_names.index(("leg_left_5_link", "leg_right_5_link"))
    rest = pair_distances(talos, sets, talos.q_standing[None])[0]
    near = {sets.pair_names[pi] for pi in np.flatnonzero(rest < settings.collision.screening)}
    assert ("leg_left_5_link", "leg_right_5_link") in near and len(near) >= 3
    lay, settings = _formulation(_reach_spec(talos, "squat down 10 cm"), talos, settings)
    x0 = lay.initial_guess(settings)
    lay, deferred = add_screened_collision_terms(lay, settings, x0)
    assert not [t for t in lay.terms if t.kind == "collision"]
    assert {sets.pair_names[pi] for pi in deferred.spheres} == near
    q = _guess_configurations(lay, x0)
    model = talos.model
    for side, sign in (("left", -1.0), ("right", 1.0)):  # hip roll: the legs swing towards each other
        q[5:lay.N - 5, model.joints[model.getJointId(f"leg_{side}_2_joint")].idx_q] += sign * 0.008
    d = sphere_pair_distances(talos, sets, q, within=settings.collision.screening)
    moved = np.minimum.reduceat(d, sets.starts, axis=1)[:, ankles]
    assert moved[2:lay.N].min() < rest[ankles] - IDLE_TOLERANCE - 1e-3
    idle = idle_pairs(lay, sets, d, settings.collision.margin)
    assert not idle[ankles]
    assert ankles in select(lay, sets, d, settings.collision.screening).spheres


def test_a_solve_that_fails_without_the_idle_rows_is_solved_again_with_them(talos):
    """When the solve without the idle pairs' rows runs out of iterations, the problem is solved
    again from the same guess with every row screening selects (what the planner did before idle
    pairs), and the stats add up both solves."""
    spec = _reach_spec(talos, "squat down 10 cm")
    settings = PlannerSettings(cache=CacheSettings(compile=False), solver=SolverSettings(max_iterations=3),
                               diagnose=False)
    said: list[str] = []
    failed = plan(spec, talos, settings=settings, throw=False, progress=said.append)
    assert not failed.ok
    assert any("idle pairs' rows" in m for m in said), said
    assert failed.stats.iterations == 6
    bare = plan(spec, talos,
                settings=PlannerSettings(cache=CacheSettings(compile=False),
                                         solver=SolverSettings(max_iterations=3), diagnose=False,
                                         collision=CollisionSettings(self_collision=False)),
                throw=False)
    assert failed.stats.n_constraints > bare.stats.n_constraints + 300  # the ankles' and hips' rows


@pytest.mark.long  # in make test-long: the 2-core suite stays under 10 minutes (~65 s)
@pytest.mark.slow
@pytest.mark.parametrize(("sentence", "moving"), [
    ("reach right with your left hand 40 cm", "left"),
    ("reach left with your right hand 30 cm", "right"),
])
def test_talos_cross_body_reaches_plan_without_penetration(talos, sentence, moving):
    """Issue 15: the forearm went through the pelvis, the gripper into the thigh. Now every pair of
    links apart at rest stays apart (coal on the URDF meshes) at every knot."""
    spec = _reach_spec(talos, sentence)
    result = plan(spec, talos, settings=PlannerSettings(cache=CacheSettings(compile=False)))
    assert result.ok
    check = next(c for c in result.checks if c.kind.value == "self_collision")
    assert check.ok and "closest" in check.name
    d, pair, k = _closest_mesh_pair(talos, result.q, _pairs_apart_at_rest(talos))
    assert d > 1e-3, f"{pair} at t = {result.t[k]:.2f} s: {d:.4f} m"
    assert all(c.ok for c in result.checks)  # the hand target is met too (within its tolerance)
    assert spec.targets[0].frame == talos.frame(f"{moving}_hand")


@pytest.mark.long  # in make test-long: the 2-core suite stays under 10 minutes (~55 s)
@pytest.mark.slow
def test_hand_target_inside_the_torso_is_refused_naming_the_pair(talos, tmp_path):
    """A spec whose right-hand target is the middle of the chest (the centre of the torso's upper
    capsule), the CoM held within 2 cm of where it stands and the chest held in place (else the
    robot leans out of the way: the target is a point in the world): exit 4 through the CLI,
    naming the hand and the torso."""
    import dataclasses

    from robots.collision import collision_model
    from tasks.serialize import spec_to_json
    from tasks.specs import CoMBounds, FrameTarget

    spec = _reach_spec(talos, "reach left with your right hand 30 cm")
    data = talos.data()
    pin.forwardKinematics(talos.model, data, talos.q_standing)
    pin.updateFramePlacements(talos.model, data)
    torso = talos.frame("torso")
    chest = max(collision_model(talos).capsules_of(torso),
                key=lambda c: (data.oMi[c.joint] * c.placement).translation[2])
    inside = data.oMi[chest.joint].act(chest.placement.translation)
    com = pin.centerOfMass(talos.model, talos.data(), talos.q_standing)
    held = CoMBounds(name="held", lower=tuple(float(c - 0.02) for c in com), upper=tuple(float(c + 0.02) for c in com))
    M = data.oMf[talos.model.getFrameId(torso)]
    still = FrameTarget(name="chest held", frame=torso, position=tuple(float(x) for x in M.translation),
                        rpy=tuple(float(x) for x in pin.rpy.matrixToRpy(M.rotation)),
                        window=(0.0, spec.horizon), tolerance=0.005)
    targets = tuple(dataclasses.replace(t, position=tuple(float(x) for x in inside)) if t.priority.name == "HARD"
                    else t for t in spec.targets)
    spec = dataclasses.replace(spec, targets=(*targets, still), com_bounds=(*spec.com_bounds, held))
    path = tmp_path / "inside.json"
    path.write_text(spec_to_json(spec))
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    out = subprocess.run([sys.executable, "-c", "import sys; from wbmp.cli import run; sys.exit(run())",
                          "solve", "--spec", str(path), "--no-sim"],
                         capture_output=True, text=True, env=env, cwd=tmp_path, timeout=900)
    assert out.returncode == 4, out.stderr
    assert re.search(r"right (hand|forearm) would pass through the torso", out.stderr), out.stderr
    assert "torso_2_link" in out.stderr and "reach less far" in out.stderr


@pytest.mark.long  # in make test-long: the 2-core suite stays under 10 minutes (~20 s)
@pytest.mark.slow
def test_g1_reach_plans_without_penetration(g1):
    spec = _reach_spec(g1, "reach right with your left hand 30 cm")
    result = plan(spec, g1, settings=PlannerSettings(cache=CacheSettings(compile=False)))
    assert result.ok and all(c.ok for c in result.checks)
    d, pair, k = _closest_mesh_pair(g1, result.q, _pairs_apart_at_rest(g1))
    assert d > 1e-3, f"{pair} at t = {result.t[k]:.2f} s: {d:.4f} m"


@pytest.mark.slow
def test_dynamic_two_steps_still_plan_with_collision_rows(talos):
    from tasks.actions import Action
    from tasks.compose import compile_actions

    spec = compile_actions([Action(name="step", params={"direction": "forward", "length": 0.15, "count": 2})],
                           talos, dt=0.075)
    assert spec.dynamic
    result = plan(spec, talos, settings=PlannerSettings(cache=CacheSettings(compile=False)))
    assert result.ok
    assert any(c.kind.value == "self_collision" and c.ok for c in result.checks)


def test_settings_validate_the_margin():
    from planner.exceptions import PlannerError

    with pytest.raises(PlannerError, match=r"collision\.margin"):
        PlannerSettings(collision=CollisionSettings(margin=-0.01))
    with pytest.raises(PlannerError, match=r"collision\.rounds"):
        PlannerSettings(collision=CollisionSettings(rounds=-1))
    assert PlannerSettings().collision.margin == 0.01



def test_a_planned_self_contact_leaves_the_two_hands_pairs_out_around_it(talos):
    """A target whose frame ``meets`` another (a clap) exempts exactly the checked pairs between
    the links on the two hands' joints and below them (Pinocchio's subtrees, independently), on
    the knots within MEET_PADDING of its time: screening gives them no rows there even when their
    sphere sets overlap, and rows elsewhere stop short of those knots; the plan's check leaves them
    out there too."""
    import dataclasses

    from planner.trajopt.collision import MEET_PADDING, exempt_distances, meet_exemptions
    from tasks.specs import FrameTarget

    spec = _reach_spec(talos, "reach right with your left hand 40 cm")
    left, right = talos.frame("left_hand"), talos.frame("right_hand")
    clap = FrameTarget(name="clap", frame=left, position=(0.3, 0.0, 1.1), time=1.0, meets=right)
    spec = dataclasses.replace(spec, targets=(*spec.targets, clap))
    lay = make_layout(spec, talos)
    sets = sphere_sets(talos)
    model = talos.model

    def under(frame):
        return set(model.subtrees[model.frames[talos.frame_id(frame)].parentJoint])

    link_joint = {model.frames[o.parentFrame].name: o.parentJoint for o in talos.collision_model.geometryObjects}
    want = {i for i, (a, b) in enumerate(sets.pair_names)
            if {link_joint[a] in under(left), link_joint[b] in under(right)} == {True}
            or {link_joint[a] in under(right), link_joint[b] in under(left)} == {True}}
    assert len(want) >= 20  # Talos's grippers: 11 links each
    ex = meet_exemptions(lay, sets)
    t = np.asarray(lay.t)
    k0 = int(np.argmin(np.abs(t - 1.0)))  # the target's knot
    near = np.abs(t - t[k0]) <= MEET_PADDING + 1e-9
    assert set(np.flatnonzero(ex.any(axis=0))) == want
    assert np.array_equal(ex[:, sorted(want)], np.repeat(near[:, None], len(want), axis=1))

    q = np.repeat(talos.q_standing[None], lay.N + 1, axis=0)
    d = np.full((len(q), len(sets.sa)), 1.0)
    sizes = np.diff(np.append(sets.starts, len(sets.sa)))
    pi = min(want)
    block = slice(sets.starts[pi], sets.starts[pi] + sizes[pi])
    d[near, block] = -0.01  # the hands' sphere sets overlap only where they meet
    assert not select(lay, sets, d, 0.03).spheres
    assert np.isinf(exempt_distances(lay, sets, d)[near, block]).all()
    k = int(np.flatnonzero(near)[0]) - 1  # and once just before: rows there, padded, but not into the window
    d[k, block] = -0.01
    rows = select(lay, sets, d, 0.03)
    assert list(rows.spheres) == [pi] and k in rows.knots[pi]
    assert not rows.knots[pi] & set(np.flatnonzero(near).tolist())


def test_g1s_planned_self_contacts_leave_out_its_wrists_and_only_its_head_link(g1):
    """G1's ``[collisions] meet_joints`` = 2: a clap exempts the checked pairs between the two
    arms' wrist roll, pitch and yaw links (by name, from the URDF: the roll and pitch links sit
    above the hand frame's joint, 1 cm apart in the sphere model at a clap); a hand meeting the
    head (fixed on the torso, whose joint carries both arms) exempts the head link's pairs with
    that hand's wrist links only, not the torso's nor the other arm's."""
    import dataclasses

    from planner.trajopt.collision import meet_exemptions
    from tasks.specs import FrameTarget

    spec = _reach_spec(g1, "reach right with your left hand 20 cm")
    left, right, head = g1.frame("left_hand"), g1.frame("right_hand"), g1.frame("head")
    wrists = {s: {f"{s}_wrist_{j}_link" for j in ("roll", "pitch", "yaw")} for s in ("left", "right")}
    sets = sphere_sets(g1)
    for target, a, b in ((FrameTarget(name="clap", frame=left, position=(0.3, 0.0, 0.9), time=1.0, meets=right),
                          wrists["left"], wrists["right"]),
                         (FrameTarget(name="salute", frame=right, position=(0.1, -0.05, 1.2), time=1.0, meets=head),
                          wrists["right"], {"head_link"})):
        lay = make_layout(dataclasses.replace(spec, targets=(*spec.targets, target)), g1)
        want = {i for i, (x, y) in enumerate(sets.pair_names) if (x in a and y in b) or (x in b and y in a)}
        assert {tuple(sorted(sets.pair_names[i])) for i in want} == {tuple(sorted((x, y))) for x in a for y in b}
        assert set(np.flatnonzero(meet_exemptions(lay, sets).any(axis=0))) == want
