"""The legs' rules of a retarget (tasks.mocap.legs): a swinging foot lands no faster than
LAND_SPEED, quick low swings on the spot are no steps, and a travelling jump's flights become steps
(synthetic swings and labels: no robot, no solver; milliseconds)."""

from __future__ import annotations

import numpy as np
import pytest

from tasks.mocap.legs import (
    BODY,
    HIGH_SWING,
    LAND_SPEED,
    QUICK_LIFT,
    STEP_GAP,
    no_higher_than_standing,
    quick_shuffles,
    steps_for_flights,
)
from tasks.mocap.source import HumanMotion, segments

DT = 0.08


def _stamp(n: int = 16, lift: float = 0.25) -> tuple[np.ndarray, np.ndarray]:
    """A march's swing on the knot grid: the source's foot up to ``lift`` and stamped down from
    0.2 m in its last knot (2.5 m/s), landing where it left (marching on the spot: its
    placements at knots 0 and n are the same; held: NaN in the swing)."""
    src = np.zeros((n + 1, 3))
    src[:, 0] = 0.1 + 0.05 * np.sin(np.linspace(0.0, np.pi, n + 1))  # the knee raised forward
    src[1:n, 2] = lift * np.sin(np.linspace(0.0, np.pi, n + 1)[1:n]) ** 0.3
    src[n - 1, 2], src[n - 2, 2] = 0.2, 0.24
    held = np.full((n + 2, 3), np.nan)
    held[0] = held[n] = held[n + 1] = [0.1, 0.1, 0.0]
    return src, held


def _path(src: np.ndarray, held: np.ndarray, monkeypatch, soft: bool) -> np.ndarray:
    from tasks.mocap import retarget as rt

    monkeypatch.setattr(rt, "LAND_SOFTLY", soft)
    return np.array([rt.swing_target(src, held, k, np.zeros(3), DT) for k in range(1, len(src) - 1)])


def test_a_stamping_foot_comes_onto_its_placement_no_faster_than_the_landing_speed(monkeypatch):
    """A march stamps down at 2.5 m/s: without the rule the target is 0.2 m above its placement a
    knot before touch-down; with it, every knot's target is within LAND_SPEED x the time to
    touch-down (or from lift-off, whichever is less) of the placement (the distance measured here,
    not read from the rule), its lift kept where that allows."""
    src, held = _stamp()
    n = len(src) - 1
    hard = _path(src, held, monkeypatch, soft=False)
    soft = _path(src, held, monkeypatch, soft=True)
    k = np.arange(1, n)
    # time to touch-down (or from lift-off) per knot; a swing higher than HIGH_SWING is down on its
    # placement a knot early (the simulated foot lags its plan)
    assert src[:, 2].max() > HIGH_SWING
    left = np.minimum(n - 1 - k, k) * DT
    hard_d = np.linalg.norm(hard - held[n], axis=1)
    soft_d = np.linalg.norm(soft - held[n], axis=1)
    assert hard_d[-1] > 0.15 and np.any(hard_d > 1.5 * LAND_SPEED * left)  # the stamp, unruled
    assert np.all(soft_d <= LAND_SPEED * left + 1e-9)
    assert np.allclose(soft[-1], held[n])  # down a knot early
    # where the source is within that (early in the swing, far from touch-down) its lift is kept
    keep = hard_d <= LAND_SPEED * left
    assert keep.sum() >= 1 and np.allclose(soft[keep], hard[keep]) and soft[:, 2].max() > 0.2


def test_a_swing_that_lands_slowly_is_not_changed(monkeypatch):
    """A walk's swing (a 3 cm lift ending on the floor a knot early) is the same target with or
    without the rule: the rule leaves what is already slow enough."""
    src, held = _stamp(lift=0.0)
    src[1:-1, 2] = 0.03 * np.sin(np.linspace(0.0, np.pi, len(src))[1:-1])
    src[-2, 2] = 0.005
    assert np.array_equal(_path(src, held, monkeypatch, False), _path(src, held, monkeypatch, True))


def _motion(n: int, ft: float = 0.01) -> HumanMotion:
    pts = {k: np.zeros((n, 3)) for k in ("left_ankle", "left_toe", "right_ankle", "right_toe", *BODY)}
    for side, y in (("left", 0.1), ("right", -0.1)):
        pts[f"{side}_ankle"][:, 1] = pts[f"{side}_toe"][:, 1] = y
        pts[f"{side}_toe"][:, 0] = 0.2
    pts["pelvis"][:, 2] = 0.9
    return HumanMotion(t=np.arange(n) * ft, points=pts, skeleton=None)  # type: ignore[arg-type]


def _swing(m: HumanMotion, side: str, a: int, b: int, lift: float, step: float) -> None:
    for key in (f"{side}_ankle", f"{side}_toe"):
        p = m.points[key]
        p[a:b, 2] = lift * np.sin(np.linspace(0.0, np.pi, b - a + 2)[1:-1])
        p[b:, 0] += step
        p[a:b, 0] += np.linspace(0.0, step, b - a)


@pytest.mark.parametrize(("frames", "lift", "step", "stays_down"), [
    (11, 0.07, 0.02, True),  # the kick's 0.11 s, 7 cm swing on the spot: no step
    (11, 1.5 * QUICK_LIFT, 0.02, False),  # as quick but high: a step
    (11, 0.07, 0.30, False),  # as quick but far: a step
    (90, 0.07, 0.02, False),  # low and on the spot but not quick (the robot's step: 0.8 s): kept
])
def test_quick_low_swings_on_the_spot_are_no_steps(frames, lift, step, stays_down):
    """A swing quicker than the robot's step (which would slow the whole clip for it), lower than
    QUICK_LIFT and landing less than the shuffle step from where it left keeps the foot down; the
    other foot and every other swing are untouched."""
    n = 300
    m = _motion(n)
    _swing(m, "right", 100, 100 + frames, lift, step)
    labels = {"left": np.ones(n, dtype=bool), "right": np.ones(n, dtype=bool)}
    labels["right"][100:100 + frames] = False
    out = quick_shuffles(m, labels, scale=1.0, least_swing=0.8, step=0.08)
    assert out["left"].all()
    assert out["right"].all() == stays_down
    if not stays_down:
        assert np.array_equal(out["right"], labels["right"])


def _swings(lab: np.ndarray) -> list[tuple[int, int]]:
    return [(a, b) for a, b, down in segments(lab) if not down]


def test_a_two_footed_jump_becomes_a_step_of_each_foot():
    """Both feet up over frames 300-345 (0.45 s), the right leaving 3 frames early, both landing
    together: afterwards no frame has both feet up, each foot makes one swing at least as long as
    the flight, the right's first, with STEP_GAP of double support between them."""
    n, ft = 900, 0.01
    labels = {"left": np.ones(n, dtype=bool), "right": np.ones(n, dtype=bool)}
    labels["left"][300:345] = False
    labels["right"][297:345] = False
    out, seconds = steps_for_flights(labels, ft)
    assert seconds == pytest.approx(45 * ft)
    assert not np.any(~out["left"] & ~out["right"])
    (r0, r1), = _swings(out["right"])
    (l0, l1), = _swings(out["left"])
    assert r1 - r0 >= 45 and l1 - l0 >= 45  # no quicker than the jump
    assert l0 - r1 == pytest.approx(STEP_GAP / ft, abs=1)  # a double support between the steps
    assert r0 < 300 < 345 < l1  # moved into the double supports around the flight


def test_a_running_step_keeps_the_last_foot_down_until_the_flight_ends():
    """The kick's leap: the left up over 235-280, the right leaving at 259 (kicking) and landing at
    333: the right stays down until 280 and then kicks; the left's swing is untouched."""
    n = 490
    labels = {"left": np.ones(n, dtype=bool), "right": np.ones(n, dtype=bool)}
    labels["left"][235:280] = False
    labels["right"][259:333] = False
    out, seconds = steps_for_flights(labels, 0.01)
    assert seconds == pytest.approx(0.21)
    assert _swings(out["left"]) == [(235, 280)] and _swings(out["right"]) == [(280, 333)]


def test_a_jump_made_as_steps_does_not_rise_into_its_flight():
    """The body (pelvis, torso, head, shoulders, hands) is lowered wherever the pelvis is above its
    median height with both feet down, by that excess; the feet are not moved."""
    n = 200
    m = _motion(n)
    rise = np.zeros(n)
    rise[80:120] = 0.3 * np.sin(np.linspace(0.0, np.pi, 40))
    for k in BODY:
        m.points[k][:, 2] += rise
    labels = {"left": np.ones(n, dtype=bool), "right": np.ones(n, dtype=bool)}
    labels["left"][80:120] = labels["right"][80:120] = False
    out = no_higher_than_standing(m, labels)
    assert np.allclose(out.points["pelvis"][:, 2], 0.9)
    assert np.allclose(out.points["left_hand"][:, 2], 0.0)
    assert np.array_equal(out.points["left_toe"], m.points["left_toe"])


@pytest.fixture(scope="module")
def talos():
    from robots import load_robot

    return load_robot("talos")


@pytest.mark.parametrize("yaw", [0.0, 1.2])
def test_a_raised_foot_swinging_in_beside_the_standing_one_is_kept_apart(talos, yaw):
    """The march's raised right foot 0.17 m ahead and 0.03 m beside the standing left one (talos:
    its shin through the other foot on the meshes): moved out sideways (the hips' frame, ``yaw``)
    to FOOT_GAP x the soles' gap at standing (Pinocchio FK), only sideways; a target a long stride
    ahead is not moved."""
    import pinocchio as pin

    from tasks.mocap.keepout import FOOT_GAP, KNEE_REACH
    from tasks.mocap.legs import apart_from_stance

    model, data = talos.model, talos.model.createData()
    pin.framesForwardKinematics(model, data, np.asarray(talos.q_standing, dtype=float))
    gap = abs(data.oMf[talos.frame_id(talos.frame("left_foot"))].translation[1]
              - data.oMf[talos.frame_id(talos.frame("right_foot"))].translation[1])
    c, s = np.cos(yaw), np.sin(yaw)
    fwd, lat = np.array([c, s, 0.0]), np.array([-s, c, 0.0])
    stance = np.array([0.3, -0.2, 0.0])
    near = stance + 0.17 * fwd - 0.03 * lat + [0.0, 0.0, 0.25]
    moved = apart_from_stance(near, "right", stance, yaw, talos)
    assert float((stance - moved) @ lat) == pytest.approx(FOOT_GAP * gap, abs=1e-6)
    assert float((moved - near) @ fwd) == pytest.approx(0.0, abs=1e-9) and moved[2] == near[2]
    far = stance + 2.5 * KNEE_REACH * 0.3 * fwd - 0.03 * lat
    assert np.array_equal(apart_from_stance(far, "right", stance, yaw, talos), far)


def test_a_high_long_step_is_not_set_down_early(monkeypatch):
    """The same high swing as a 0.45 m step (longer than EARLY_STEP: a forward jump made as steps,
    which scuffed the floor and fell when set down a knot early): a knot before touch-down its
    target is still off the floor (LAND_SPEED x a knot up, the source being higher), not on it;
    being at least LATE_STEP long (talos's 0.45-0.55 m), it leaves a knot late instead."""
    from tasks.mocap.legs import EARLY_STEP, LATE_STEP

    src, held = _stamp()
    n = len(src) - 1
    held[n] = held[n + 1] = held[0] + [0.45, 0.0, 0.0]
    assert 0.45 > LATE_STEP > EARLY_STEP
    soft = _path(src, held, monkeypatch, soft=True)
    assert soft[-1, 2] == pytest.approx(LAND_SPEED * DT, rel=0.05)
    # it leaves a knot late instead: its first swinging knot is still on the placement it leaves
    # (the plan moved such a step's foot 33 mm across between its last stance knot and its first
    # swinging one, which the certificate read as the stance's placement error)
    assert np.allclose(soft[0], held[0]) and soft[1, 2] > 0.0
    assert np.allclose(soft[1, :2], held[0, :2])  # and then only goes up (a knot later than a walk's)


def test_a_high_step_shorter_than_late_step_leaves_its_placement_at_once(monkeypatch):
    """The same high swing as a 0.35 m step (between EARLY_STEP and LATE_STEP: G1's forward jumps made
    as 0.31-0.37 m steps, which fell when their feet left a knot late): neither set down early (a
    knot before touch-down still LAND_SPEED x a knot up) nor left late (its first swinging knot
    already up, its second moving towards the placement it lands on, as a walk's)."""
    from tasks.mocap.legs import EARLY_STEP, LATE_STEP

    src, held = _stamp()
    n = len(src) - 1
    held[n] = held[n + 1] = held[0] + [0.35, 0.0, 0.0]
    assert EARLY_STEP < 0.35 < LATE_STEP
    soft = _path(src, held, monkeypatch, soft=True)
    assert soft[-1, 2] == pytest.approx(LAND_SPEED * DT, rel=0.05)
    # up at its first swinging knot (over the placement it leaves), across from its second
    assert soft[0, 2] > 0.0 and soft[1, 0] - held[0, 0] > 1e-3
    held[n] = held[n + 1] = held[0] + [LATE_STEP + 0.01, 0.0, 0.0]  # a step just over LATE_STEP: late
    late = _path(src, held, monkeypatch, soft=True)
    assert np.allclose(late[0], held[0]) and np.allclose(late[1, :2], held[0, :2])
