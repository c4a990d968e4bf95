"""The robot's URDF as MuJoCo reads it: meshes resolved, foreign meshes and visuals dropped,
indefinite inertias repaired, mimic fingers freed, a floating root joint added.

Used by :mod:`sim.model` (which re-exports these names); MuJoCo never reads the URDF file itself.
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from robots import Robot
from sim.exceptions import SimModelError

FOREIGN_MESHES = (".dae",)  # mesh formats MuJoCo 4 cannot read; their triangles come from Pinocchio
ROOT_JOINT = "wbmp_root"


MIN_INERTIA = 1e-8  # [kg m^2] smallest principal inertia MuJoCo gets


def _repair_inertia(link: ET.Element) -> None:
    """Clip a link's principal inertias to >= MIN_INERTIA (some URDFs ship indefinite tensors)."""
    tensor = link.find("inertial/inertia")
    if tensor is None:
        return
    keys = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
    try:
        ixx, ixy, ixz, iyy, iyz, izz = (float(tensor.get(k, "0")) for k in keys)
    except ValueError:
        return
    inertia = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    values, vectors = np.linalg.eigh(inertia)
    if values.min() >= MIN_INERTIA:
        return
    fixed = vectors @ np.diag(np.maximum(values, MIN_INERTIA)) @ vectors.T
    for k, (r, c) in zip(keys, ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)), strict=True):
        tensor.set(k, repr(float(fixed[r, c])))


def _rewrite_urdf(robot: Robot, fingers: bool = False) -> str:
    """The robot's URDF as MuJoCo reads it; ``fingers``: its mimic fingers move
    (:func:`_free_mimic_joints`; only in a scene with something to grasp)."""
    text = Path(robot.urdf_path).read_text(encoding="utf-8")

    def resolve(match: re.Match[str]) -> str:
        rest = match.group(1)
        for directory in robot.package_dirs:
            path = Path(directory) / rest
            if path.is_file():
                return f'filename="{path}"'
        raise SimModelError(
            f"robot {robot.name!r}: mesh 'package://{rest}' not found under {list(robot.package_dirs)}"
        )

    text = re.sub(r'filename="package://([^"]+)"', resolve, text)
    try:
        root = ET.fromstring(text)
    except ET.ParseError as e:
        raise SimModelError(
            f"robot {robot.name!r}: cannot parse URDF {robot.urdf_path}: {e}"
        ) from None
    for old in root.findall("mujoco"):
        root.remove(old)
    if fingers:
        _free_mimic_joints(root)
    for link in root.findall(
        "link"
    ):  # MuJoCo cannot decode these: they are rebuilt from Pinocchio's
        for collision in link.findall("collision"):
            mesh = collision.find("geometry/mesh")
            if mesh is not None and Path(mesh.get("filename", "")).suffix.lower() in FOREIGN_MESHES:
                link.remove(collision)
        for visual in link.findall("visual"):
            link.remove(visual)
        _repair_inertia(link)
    children = {
        child.get("link") for j in root.findall("joint") if (child := j.find("child")) is not None
    }
    roots = [link.get("name") for link in root.findall("link") if link.get("name") not in children]
    if len(roots) != 1 or roots[0] is None:
        raise SimModelError(
            f"robot {robot.name!r}: the URDF must have exactly one root link, found {roots}"
        )
    tag = ET.SubElement(root, "mujoco")
    ET.SubElement(
        tag,
        "compiler",
        discardvisual="true",
        fusestatic="false",
        strippath="false",
        balanceinertia="true",
        boundmass="1e-6",  # massless moving links (Romeo's fingers) get 1 mg
        boundinertia="1e-10",
    )
    ET.SubElement(root, "link", name="world")
    joint = ET.SubElement(root, "joint", name=ROOT_JOINT, type="floating")
    ET.SubElement(joint, "parent", link="world")
    ET.SubElement(joint, "child", link=roots[0])
    return ET.tostring(root, encoding="unicode")


def _free_mimic_joints(root: ET.Element) -> list[str]:
    """Turn each fixed URDF joint that mimics a moving joint into a revolute one (in place); the
    names of the joints turned.

    talos_reduced's fingers hang from such joints (``gripper_*_inner_double_joint``,
    ``*_fingertip_*_joint``, ...: ``type="fixed"`` with their axis, limits and a ``<mimic>`` of
    ``gripper_*_joint``), so in Pinocchio the gripper joint moves one drive link and no finger.
    MuJoCo's URDF import makes a ``<mimic>`` a joint equality (``polycoef`` offset, multiplier),
    so in the simulation the fingers close with the gripper joint (:mod:`sim.grasp`). Pinocchio
    and the planner keep the fixed joints: these joints are MuJoCo's only.
    """
    moving = {j.get("name") for j in root.findall("joint") if j.get("type") in ("revolute", "continuous", "prismatic")}
    turned = []
    for joint in root.findall("joint"):
        mimic = joint.find("mimic")
        if joint.get("type") == "fixed" and mimic is not None and mimic.get("joint") in moving \
                and joint.find("limit") is not None and joint.find("axis") is not None:
            joint.set("type", "revolute")
            turned.append(str(joint.get("name")))
    return turned
