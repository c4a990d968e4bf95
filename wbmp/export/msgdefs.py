"""ROS 2 message definitions (``.msg`` text) of the messages a wbmp bag holds.

MCAP's ``ros2msg`` schema encoding stores a type's own definition followed by every type it
uses, each after a line of 80 ``=`` and a ``MSG: pkg/Type`` line, as rosbag2 writes them. The
fields are those of ROS 2 Humble (and every later distribution: these types have not changed);
``tests/wbmp/test_export_mcap.py`` compares them with an independent typestore's.
"""

from __future__ import annotations

# type -> its own definition (fields only; comments dropped). Nested types of the same package
# are named with the package, which every parser resolves.
DEFINITIONS: dict[str, str] = {
    "builtin_interfaces/msg/Time": "int32 sec\nuint32 nanosec\n",
    "builtin_interfaces/msg/Duration": "int32 sec\nuint32 nanosec\n",
    "std_msgs/msg/Header": "builtin_interfaces/Time stamp\nstring frame_id\n",
    "std_msgs/msg/String": "string data\n",
    "geometry_msgs/msg/Vector3": "float64 x\nfloat64 y\nfloat64 z\n",
    "geometry_msgs/msg/Quaternion": "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n",
    "geometry_msgs/msg/Transform": "geometry_msgs/Vector3 translation\ngeometry_msgs/Quaternion rotation\n",
    "geometry_msgs/msg/TransformStamped": ("std_msgs/Header header\nstring child_frame_id\n"
                                           "geometry_msgs/Transform transform\n"),
    "tf2_msgs/msg/TFMessage": "geometry_msgs/TransformStamped[] transforms\n",
    "sensor_msgs/msg/JointState": ("std_msgs/Header header\n\nstring[] name\nfloat64[] position\n"
                                   "float64[] velocity\nfloat64[] effort\n"),
    "trajectory_msgs/msg/JointTrajectoryPoint": ("float64[] positions\nfloat64[] velocities\n"
                                                 "float64[] accelerations\nfloat64[] effort\n"
                                                 "builtin_interfaces/Duration time_from_start\n"),
    "trajectory_msgs/msg/JointTrajectory": ("std_msgs/Header header\nstring[] joint_names\n"
                                            "trajectory_msgs/JointTrajectoryPoint[] points\n"),
}

SEPARATOR = "=" * 80


def _short(name: str) -> str:
    """``pkg/msg/Type`` -> ``pkg/Type`` (the form used inside definitions)."""
    pkg, _, typ = name.split("/")
    return f"{pkg}/{typ}"


def _uses(name: str) -> list[str]:
    """The message types a definition's fields name, in field order (full ``pkg/msg/Type`` names)."""
    out = []
    for line in DEFINITIONS[name].splitlines():
        if not line.strip():
            continue
        typ = line.split()[0].split("[")[0]
        if "/" in typ:
            pkg, short = typ.split("/")
            out.append(f"{pkg}/msg/{short}")
    return out


def schema_text(name: str) -> str:
    """The full ``ros2msg`` schema of ``name`` (``pkg/msg/Type``): its definition, then every
    type it depends on (depth first, each once)."""
    order: list[str] = []

    def visit(n: str) -> None:
        for dep in _uses(n):
            if dep not in order:
                order.append(dep)
                visit(dep)

    visit(name)
    parts = [DEFINITIONS[name]]
    for dep in order:
        parts.append(f"{SEPARATOR}\nMSG: {_short(dep)}\n{DEFINITIONS[dep]}")
    return "\n".join(parts)
