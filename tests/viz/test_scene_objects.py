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
