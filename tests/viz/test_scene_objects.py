"""Scene objects in every viewer: meshcat nodes, the HTML replay's payload, the plots' top view."""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin
import pytest

from tasks.scene import Scene, SceneObject, load_scene
from tests.tasks.test_scene import SCENES
from viz import html as vh
from viz import scene as vs
from viz._meshcat import umsgpack

OBJECTS = (
    SceneObject(name="table", shape="box", size=(0.6, 1.2, 0.62), position=(0.65, 0.0, 0.31), rpy=(0.0, 0.0, 0.5),
                colour=(0.55, 0.38, 0.22, 1.0)),
    SceneObject(name="bin", shape="cylinder", size=(0.15, 0.5), position=(-0.5, 0.6, 0.25),
                colour=(0.1, 0.5, 0.3, 0.5)),
    SceneObject(name="ball", shape="sphere", size=(0.11,), position=(0.2, -0.7, 0.11), movable=True, mass=0.45),
)
SCENE = Scene(name="test room", objects=OBJECTS)


@pytest.fixture(scope="module")
def scene_plan(synth_plan):
    return dataclasses.replace(synth_plan, spec=dataclasses.replace(synth_plan.spec, scene=SCENE))


def _commands(vis_window) -> list[dict]:
    return [umsgpack.unpackb(c) for c in vis_window.commands]


def test_meshcat_scene_has_a_node_per_object_at_its_pose():
    from viz._meshcat import meshcat

    window = vh.RecordingWindow()
    vis = meshcat.Visualizer(window=window)
    assert vs.add_scene(vis, SCENE) == ["wbmp/scene/table", "wbmp/scene/bin", "wbmp/scene/ball"]
    cmds = _commands(window)
    objects = {c["path"]: c["object"] for c in cmds if c["type"] == "set_object"}
    poses = {c["path"]: np.asarray(c["matrix"]).reshape(4, 4).T for c in cmds if c["type"] == "set_transform"}
    for obj in OBJECTS:
        node = f"/meshcat/wbmp/scene/{vs.node_name(obj.name)}"
        T = poses[node]
        assert np.allclose(T[:3, 3], obj.position)
        assert np.allclose(T[:3, :3], pin.rpy.rpyToMatrix(*obj.rpy))
        geometry = objects[f"{node}/shape"]["geometries"][0]
        material = objects[f"{node}/shape"]["materials"][0]
        assert material["color"] == vs._rgb_int(obj.colour[:3])
        assert material["opacity"] == pytest.approx(obj.colour[3])
        if obj.shape == "box":
            assert geometry["type"] == "BoxGeometry"
            assert [geometry["width"], geometry["height"], geometry["depth"]] == pytest.approx(obj.size)
        elif obj.shape == "cylinder":  # meshcat's cylinder runs along y: the shape node turns it to z
            assert geometry["type"] == "CylinderGeometry"
            assert geometry["height"] == pytest.approx(obj.size[1])
            assert geometry["radiusTop"] == pytest.approx(obj.size[0])
            turn = poses[f"{node}/shape"][:3, :3]
            assert np.allclose(turn @ [0.0, 1.0, 0.0], [0.0, 0.0, 1.0])
        else:
            assert geometry["type"] == "SphereGeometry"
            assert geometry["radius"] == pytest.approx(obj.size[0])
    assert vs.add_scene(vis, None) == []


def test_html_payload_holds_the_objects_with_their_poses(tmp_path, talos, scene_plan, synth_plan):
    page = vh.build_page(talos, scene_plan)
    assert "· scene: table, bin, ball" in page  # the subtitle names the objects
    data = vh.unpack_data(page)
    cmds = [umsgpack.unpackb(c) for c in data["scene"]]
    poses = {c["path"]: np.asarray(c["matrix"]).reshape(4, 4).T for c in cmds if c["type"] == "set_transform"}
    shapes = {c["path"] for c in cmds if c["type"] == "set_object"}
    for obj in OBJECTS:
        node = f"/meshcat/wbmp/scene/{vs.node_name(obj.name)}"
        assert f"{node}/shape" in shapes
        assert np.allclose(poses[node][:3, 3], obj.position)
    plain = vh.unpack_data(vh.build_page(talos, synth_plan))
    extra = sum(map(len, data["scene"])) - sum(map(len, plain["scene"]))
    assert 0 < extra < 1500 * len(OBJECTS)  # a primitive is ~1 kB of commands: the page stays compact
    assert not any("/wbmp/scene/" in umsgpack.unpackb(c).get("path", "") for c in plain["scene"])


def test_footprints_match_the_shapes():
    table, bin_, ball = OBJECTS
    outline = vs.footprint(table)
    assert len(outline) == 4
    c, s = np.cos(0.5), np.sin(0.5)
    expected = {(0.65 + sx * 0.3 * c - sy * 0.6 * s, sx * 0.3 * s + sy * 0.6 * c) for sx in (-1, 1) for sy in (-1, 1)}
    for corner in expected:
        assert np.min(np.linalg.norm(outline - corner, axis=1)) < 1e-9
    ring = vs.footprint(bin_)
    assert np.allclose(np.linalg.norm(ring - [-0.5, 0.6], axis=1), 0.15)
    tilted = dataclasses.replace(bin_, rpy=(np.pi / 2, 0.0, 0.0))  # lying along y: a 0.3 x 0.5 rectangle
    span = np.ptp(vs.footprint(tilted), axis=0)
    assert span == pytest.approx([0.3, 0.5], abs=1e-3)
    assert np.allclose(np.linalg.norm(vs.footprint(ball) - [0.2, -0.7], axis=1), 0.11)


def test_plot_top_view_draws_each_object_where_it_is(tmp_path, talos, scene_plan, monkeypatch):
    from matplotlib.figure import Figure

    from viz import plots

    captured: list[Figure] = []
    original = plots._save

    def keep(fig, path):
        captured.append(fig)
        return original(fig, path)

    monkeypatch.setattr(plots, "_save", keep)
    out = plots.plot_com_support(tmp_path / "com_support.png", talos, scene_plan)
    assert out.is_file()
    ax_top = captured[0].axes[0]
    patches = {p.get_gid(): p for p in ax_top.patches if p.get_gid()}
    assert set(patches) == {f"scene/{o.name}" for o in OBJECTS}
    for obj in OBJECTS:
        xy = patches[f"scene/{obj.name}"].get_xy()
        assert np.allclose(xy[:-1].mean(axis=0) if len(xy) > 4 else xy.mean(axis=0), obj.position[:2], atol=0.02)
        texts = [t for t in ax_top.texts if t.get_text() == obj.name]
        assert len(texts) == 1
    # the view reaches the farthest object (the bin at x = -0.65)
    assert ax_top.get_xlim()[0] <= -0.65


def test_example_scenes_draw(talos):
    from viz._meshcat import meshcat

    for path in sorted(SCENES.glob("*.json")):
        window = vh.RecordingWindow()
        scene = load_scene(path)
        assert len(vs.add_scene(meshcat.Visualizer(window=window), scene)) == len(scene.objects), path.name


# -- objects that move: the planned track, the replay's and the viewer's tracks ------------------

def _track_values(track) -> np.ndarray:
    """A track's numbers (a float32 typed array in the HTML replay, a list in the live viewer)."""
    if isinstance(track, umsgpack.Ext):
        assert track.type == 0x17
        return np.frombuffer(track.data, dtype="<f4").astype(float)
    return np.asarray(track, dtype=float)


def object_clip_at(animation: dict, name: str, t: float) -> np.ndarray:
    """The pose (7,) that an animation command's clip of object ``name`` holds at its key frame
    nearest ``t`` [s], and that key frame's time (position, quaternion x, y, z, w)."""
    (clip,) = [a["clip"] for a in animation["animations"] if a["path"] == f"/meshcat/wbmp/scene/{vs.node_name(name)}"]
    tracks = {tr["name"]: tr for tr in clip["tracks"]}
    times = _track_values(tracks[".position"]["times"])
    k = int(np.argmin(np.abs(times - t)))
    p = _track_values(tracks[".position"]["values"]).reshape(-1, 3)[k]
    quat = _track_values(tracks[".quaternion"]["values"]).reshape(-1, 4)[k]
    return np.concatenate([p, quat]), float(times[k])


def _pose_at(t: np.ndarray, positions: np.ndarray, at: float) -> np.ndarray:
    return np.array([np.interp(at, t, positions[:, i]) for i in range(3)])


def test_planned_object_track_moves_with_the_hand(talos, pick_plan):
    """Before the grasp the cup stands where the scene puts it; from the grasp's start on, its pose
    seen from the hand frame (Pinocchio on the plan's q) stays what it was at the start: its centre at
    the grasp's offset, its orientation fixed; it travels more than 10 cm; the box no hand holds stays
    put and the fixed table has no track."""
    from viz import motion as vm

    poses = vm.planned_object_poses(talos, pick_plan.spec, pick_plan.t, pick_plan.q)
    assert set(poses) == {"cup", "box"}
    (g,) = pick_plan.spec.grasps
    cup_obj = pick_plan.spec.scene.get("cup")
    cup = poses["cup"]
    held = pick_plan.t >= g.start - 1e-9
    assert np.allclose(cup[~held, :3], cup_obj.position) and np.allclose(cup[~held, 3:], [0, 0, 0, 1])
    data = talos.data()
    fid = talos.model.getFrameId(g.frame)
    turns = []
    for k in np.flatnonzero(held):
        pin.framesForwardKinematics(talos.model, data, pick_plan.q[k])
        M = data.oMf[fid]
        assert np.linalg.norm(M.actInv(cup[k, :3]) - np.asarray(g.offset)) < 1e-9
        turns.append(M.rotation.T @ pin.Quaternion(cup[k, 6], *cup[k, 3:6]).toRotationMatrix())
    assert max(np.abs(R - turns[0]).max() for R in turns) < 1e-9
    assert np.linalg.norm(cup[0, :3] - cup[np.flatnonzero(held)[0], :3]) < 1e-9  # no jump at the grasp
    assert np.linalg.norm(cup[:, :3] - cup[0, :3], axis=1).max() > 0.1
    assert np.allclose(poses["box"], poses["box"][0])


def test_html_replay_moves_the_held_object(talos, pick_plan, pick_execution):
    """The replay's planned motion moves the cup's node through the planned poses and its simulated
    motion through the execution's (3 cm lower here): the clip's key frame at 2.5 s holds the pose
    at that time (within float32 rounding); the box's clip stays where the box stands; the fixed
    table has no clip."""
    from tests.viz.conftest import SIM_DROP
    from viz import motion as vm

    data = vh.unpack_data(vh.build_page(talos, pick_plan, execution=pick_execution))
    planned = vm.planned_object_poses(talos, pick_plan.spec, pick_plan.t, pick_plan.q)
    expected = {"planned": (pick_plan.t, planned["cup"][:, :3]),
                "simulated": (pick_execution.t, pick_execution.objects["cup"])}
    shown = {}
    for label, (t, positions) in expected.items():
        animation = umsgpack.unpackb(data["motions"][label])
        paths = {a["path"] for a in animation["animations"]}
        assert "/meshcat/wbmp/scene/table" not in paths
        pose, at = object_clip_at(animation, "cup", 2.5)
        assert np.abs(pose[:3] - _pose_at(t, positions, at)).max() < 1e-4, label
        assert abs(np.linalg.norm(pose[3:]) - 1.0) < 1e-5
        box, _ = object_clip_at(animation, "box", 2.5)
        assert np.allclose(box[:3], pick_plan.spec.scene.get("box").position, atol=1e-6)
        shown[label] = pose
    assert shown["planned"][2] - shown["simulated"][2] == pytest.approx(SIM_DROP, abs=1e-4)
