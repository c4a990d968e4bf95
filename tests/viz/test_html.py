"""The standalone HTML replay: self-contained, complete, atomic."""

from __future__ import annotations

import html.parser
import re

import numpy as np
import pytest

from tests.viz.conftest import SQUAT_DEPTH
from viz import html as vh
from viz import scene
from viz._meshcat import umsgpack

URL_ATTRS = {"src", "href", "data", "poster", "action", "formaction", "srcset", "background"}


class _Refs(html.parser.HTMLParser):
    """Every URL-valued attribute, and the text of each script element."""

    def __init__(self) -> None:
        super().__init__()
        self.refs: list[tuple[str, str, str]] = []
        self.scripts: list[str] = []
        self._in_script = False

    def handle_starttag(self, tag, attrs):
        for name, value in attrs:
            if name in URL_ATTRS and value is not None:
                self.refs.append((tag, name, value))
        if tag == "script":
            self._in_script = True
            self.scripts.append("")

    def handle_endtag(self, tag):
        if tag == "script":
            self._in_script = False

    def handle_data(self, data):
        if self._in_script:
            self.scripts[-1] += data


@pytest.fixture(scope="module")
def page(tmp_path_factory, talos, synth_plan, synth_execution):
    path = tmp_path_factory.mktemp("html") / "motion.html"
    out = vh.write_html(path, talos, synth_plan, execution=synth_execution, title="synthetic <squat>")
    return out, out.read_text(encoding="utf-8")


def _data(text: str) -> dict:
    return vh.unpack_data(text)


def _floats(values) -> np.ndarray:
    """A track's numbers: a float32 typed array (msgpack extension 0x17) in the replay."""
    if isinstance(values, umsgpack.Ext):
        assert values.type == 0x17
        return np.frombuffer(values.data, dtype="<f4").astype(float)
    return np.asarray(values, dtype=float)


def test_written_atomically_and_nothing_left_behind(page):
    path, text = page
    assert path.is_file() and path.stat().st_size > 1_000_000  # the meshes are inside
    assert [p.name for p in path.parent.iterdir()] == ["motion.html"]  # no temporary file left
    assert "<title>synthetic &lt;squat&gt;</title>" in text


def test_no_external_resource(page):
    """No attribute points outside the file, and no script of ours can fetch anything.

    "External URL" here means anything the page would load: src/href-like attributes must be
    absent or data: URIs, CSS must have no url(...), and our own code (everything except
    meshcat's bundle) must not contain http(s):// or protocol-relative //host, nor call
    fetch/XMLHttpRequest/WebSocket/import(). The bundle's only URL strings are XML namespaces
    ("http://www.w3.org/1999/xhtml"), which name and never load anything.
    """
    _, text = page
    parser = _Refs()
    parser.feed(text)
    bad = [r for r in parser.refs if not r[2].startswith("data:")]
    assert bad == [], f"external references: {bad}"
    assert not re.search(r"url\(\s*['\"]?(?!data:)", text.split("<script", 1)[0]), "CSS url() in the head"
    bundle = vh.meshcat_bundle()
    ours = [s for s in parser.scripts if s.strip() != bundle.strip()]
    assert len(ours) == len(parser.scripts) - 1, "the meshcat bundle is embedded exactly once"
    own_code = "\n".join(ours) + text.split("<script", 1)[0]
    for pattern in (r"https?://", r"(?<![:\w])//[\w-]+\.[\w.-]+", r"\bfetch\(", r"XMLHttpRequest",
                    r"new WebSocket", r"\bimport\("):
        assert not re.search(pattern, own_code), f"our code matches {pattern!r}"
    bundle_urls = set(re.findall(r"https?://[^\s\"')]+", bundle))
    assert bundle_urls <= {"http://www.w3.org/1999/xhtml"}, bundle_urls


def test_scene_has_every_mesh_and_the_markers(page, talos, synth_plan):
    _, text = page
    data = _data(text)
    cmds = [umsgpack.unpackb(c) for c in data["scene"]]
    objects = {c["path"] for c in cmds if c["type"] == "set_object"}
    for g in talos.visual_model.geometryObjects:
        assert f"/meshcat/wbmp/robot/planned/{scene.node_name(g.name)}/mesh" in objects
    for path in ("/meshcat/wbmp/contacts/left_foot/0/sole", "/meshcat/wbmp/contacts/right_foot/0/sole", "/meshcat/wbmp/support/0",
                 "/meshcat/wbmp/targets/right_hand_mark", "/meshcat/wbmp/com/path",
                 "/meshcat/wbmp/paths/right_hand"):
        assert path in objects, path
    # the 13 mirrored Talos meshes have their mirror baked into the packed vertices (winding
    # restored): every static mesh transform is a positive scale back from 16-bit integers
    scales = [np.asarray(c["matrix"]).reshape(4, 4).T[:3, :3] for c in cmds
              if c["type"] == "set_transform" and c["path"].endswith("/mesh")]
    assert len(scales) >= len(talos.visual_model.geometryObjects) - 6  # the 6 boxes/cylinders need none
    assert all(np.linalg.det(s) > 0 for s in scales)
    target = next(c for c in cmds if c["type"] == "set_transform" and c["path"].endswith("right_hand_mark"))
    np.testing.assert_allclose(np.asarray(target["matrix"]).reshape(4, 4).T[:3, 3], (0.35, -0.35, 1.1))


def test_planned_and_simulated_animations(page, talos, synth_plan, synth_execution):
    _, text = page
    data = _data(text)
    assert set(data["motions"]) == {"planned", "simulated"}
    assert data["durations"]["planned"] == pytest.approx(synth_plan.t[-1])
    assert data["durations"]["simulated"] == pytest.approx(synth_execution.t[-1])
    anim = umsgpack.unpackb(data["motions"]["planned"])
    assert anim["type"] == "set_animation"
    by_path = {a["path"]: a["clip"]["tracks"] for a in anim["animations"]}
    n_geoms = len(talos.visual_model.geometryObjects)
    robot_clips = [p for p in by_path if p.startswith("/meshcat/wbmp/robot/planned/")]
    assert len(robot_clips) == n_geoms
    for p in robot_clips:
        quat = _floats(by_path[p][1]["values"]).reshape(-1, 4)
        np.testing.assert_allclose(np.linalg.norm(quat, axis=1), 1.0, atol=1e-6)  # float32 in the page
    # the CoM marker follows the planned CoM: keys at 30 fps, first and last equal plan.com
    com = _floats(by_path["/meshcat/wbmp/com/point"][0]["values"]).reshape(-1, 3)
    np.testing.assert_allclose(com[0], synth_plan.com[0], atol=1e-6)  # float32: ~1e-7 m at 1 m
    np.testing.assert_allclose(com[-1], synth_plan.com[-1], atol=1e-6)
    assert len(com) == int(round(synth_plan.t[-1] * vh.FPS)) + 1
    # the base link goes down by the squat depth at mid-motion
    base_node = scene.node_name(talos.visual_model.geometryObjects[0].name)
    base = _floats(by_path[f"/meshcat/wbmp/robot/planned/{base_node}"][0]["values"]).reshape(-1, 3)
    assert base[0, 2] - base[len(base) // 2, 2] == pytest.approx(SQUAT_DEPTH, abs=1e-3)


def test_bad_plan_shape_is_a_clear_error(tmp_path, talos, synth_plan):
    import dataclasses

    bad = dataclasses.replace(synth_plan, q=synth_plan.q[:, :10])
    from viz import VizInputError

    with pytest.raises(VizInputError, match=r"plan: q must be a non-empty \(T, 39\) array"):
        vh.write_html(tmp_path / "bad.html", talos, bad)
    assert list(tmp_path.iterdir()) == []


def test_every_robot_gets_every_mesh(any_robot):
    """STL (Talos, G1) and Collada (Romeo, iCub) meshes all become scene objects."""
    from tests.viz.conftest import synthetic_plan

    text = vh.build_page(any_robot, synthetic_plan(any_robot, duration=1.0, dt=0.25))
    cmds = [umsgpack.unpackb(c) for c in _data(text)["scene"]]
    meshes = [c for c in cmds if c["type"] == "set_object" and "/wbmp/robot/planned/" in c["path"]]
    assert len(meshes) == len(any_robot.visual_model.geometryObjects)
    kinds = {c["object"]["geometries"][0]["type"] for c in meshes}
    assert kinds <= {"_meshfile_geometry", "BufferGeometry", "BoxGeometry", "CylinderGeometry", "SphereGeometry"}


def test_contact_visibility_follows_the_phases(talos):
    """A sole that lifts in the middle phase is hidden during it and shown again after."""
    from planner import Plan, SolverStats, SolveStatus
    from tasks.specs import Contact, Phase, Pose, TaskSpec
    from viz._meshcat import meshcat

    left = Contact(frame=talos.frame("left_foot"), placement=Pose(position=(0.0, 0.1, 0.0)))
    right = Contact(frame=talos.frame("right_foot"), placement=Pose(position=(0.0, -0.1, 0.0)))
    spec = TaskSpec(robot="talos", phases=(Phase(name="a", duration=1.0, contacts=(left, right)),
                                           Phase(name="b", duration=0.5, contacts=(left,)),
                                           Phase(name="c", duration=1.0, contacts=(left, right))))
    t = np.linspace(0.0, 2.5, 11)
    q = np.tile(talos.q_standing, (len(t), 1))
    plan = Plan(robot="talos", spec=spec, t=t, q=q, v=np.zeros((11, talos.nv)), a=np.zeros((11, talos.nv)),
                com=np.zeros((11, 3)), stats=SolverStats(status=SolveStatus.SOLVED))
    vis = meshcat.Visualizer(window=vh.RecordingWindow())
    schedule = scene.add_markers(vis, talos, plan)
    rf, lf = "right_foot", "left_foot"
    assert schedule[f"wbmp/contacts/{rf}/0"] == [(0.0, True), (1.0, False), (1.5, True)]
    assert schedule[f"wbmp/contacts/{lf}/0"] == [(0.0, True)]  # never lifted, merged into one interval
    assert schedule["wbmp/support/1"] == [(0.0, False), (1.0, True), (1.5, False)]
    clips = scene.visibility_animations(vis, schedule, 2.5)
    track = next(c["clip"]["tracks"][0] for c in clips if c["path"].endswith(f"contacts/{rf}/0"))
    assert track["times"] == [0.0, 1.0, 1.5, 2.5] and track["values"] == [True, False, True, True]


# The Talos replay was 12.8 MB before issue 18 (STL files as they are, animation numbers as
# float64 msgpack lists, base64 in JSON); with decimated 16-bit meshes, float32 tracks and the
# data deflated it is ~2.6 MB for the 3.2 s squat of `wbmp solve "squat down 12 cm"` with its
# simulation (meshcat's bundle alone is 0.85 MB). The bound leaves room above that figure.
HTML_BYTES_BOUND = 3_500_000


def test_talos_replay_is_compact(page):
    path, _ = page
    size = path.stat().st_size
    assert size < HTML_BYTES_BOUND, f"the Talos replay is {size / 1e6:.2f} MB"


def _signed_volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    a, b, c = (vertices[faces[:, k]] for k in range(3))
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def test_compact_meshes_keep_shape_size_and_winding(talos):
    """Every packed Talos mesh, scaled back by its node, spans the original's bounding box
    within one clustering cell and keeps its signed volume (so its outward side: the 13
    mirrored meshes too) within 25 % (the worst, base_link, loses 14 %, most under 3 %); and it
    is at least 20 % lighter than the STL file."""
    checked = mirrored = 0
    for geom in talos.visual_model.geometryObjects:
        tris = scene.stl_triangles(geom.meshPath or "")
        if tris is None:
            continue
        scale = np.asarray(geom.meshScale, dtype=float)
        original = tris * scale
        mirror = np.prod(np.sign(scale)) < 0
        mirrored += bool(mirror)
        if mirror:
            original = original[:, [0, 2, 1]]
        packed, static = scene._compact_geometry(geom)
        positions = packed.positions.astype(float) @ static[:3, :3].T + static[:3, 3]
        faces = packed.faces.astype(np.int64)
        cell = min(scene.COMPACT_MAX_CELL, float(np.ptp(original.reshape(-1, 3), axis=0).max()) / scene.COMPACT_CELLS)
        np.testing.assert_allclose(positions.min(axis=0), original.reshape(-1, 3).min(axis=0), atol=cell)
        np.testing.assert_allclose(positions.max(axis=0), original.reshape(-1, 3).max(axis=0), atol=cell)
        v0 = _signed_volume(original.reshape(-1, 3), np.arange(3 * len(original)).reshape(-1, 3))
        v1 = _signed_volume(positions, faces)
        if abs(v0) > 1e-6:  # [m^3] closed parts of some size
            assert v1 == pytest.approx(v0, rel=0.25), geom.name  # worst: base_link, -14 %
        assert packed.positions.nbytes + packed.faces.nbytes < 0.8 * (84 + 50 * len(tris)), geom.name
        checked += 1
    assert checked >= 40 and mirrored == 13
