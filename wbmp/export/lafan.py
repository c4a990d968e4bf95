"""A motion as the Unitree/LAFAN1 retargeting CSV that RL motion trackers train from.

The convention of the retargeted LAFAN1 data set, which BeyondMimic's ``csv_to_npz.py`` reads
(``--input_fps``, 30 by default there): a headerless, comma-separated text file, one row per
frame at a uniform rate, each row ``x, y, z`` (root position in the world [m]), ``qx, qy, qz,
qw`` (root orientation, unit quaternion, **x, y, z, w**), then one position per joint [rad] in
the robot's joint order (the motion file's ``joint_names``: URDF names, Pinocchio order; for
the G1 that is the Unitree SDK's 29-joint order). The file states neither the rate nor the
order; ``docs/export.md`` does, and ``wbmp export`` prints both.

Frames are the tracker export's samples (:func:`wbmp.export.tracker.resample`): ``t0 + j / fps``
up to the last knot, positions linearly interpolated and the quaternion slerped (shorter arc),
consecutive quaternions on one hemisphere.
"""

from __future__ import annotations

from typing import IO

import numpy as np

from wbmp.export.tracker import resample, source_columns

LAFAN_FPS = 30.0  # [Hz] the LAFAN1 retargeting data set's rate, BeyondMimic's default input rate
ROOT_COLUMNS = ("root_x", "root_y", "root_z", "root_qx", "root_qy", "root_qz", "root_qw")


def lafan_rows(motion, fps: float = LAFAN_FPS, source: str = "plan") -> tuple[np.ndarray, list[str]]:
    """The rows (N, 7 + n) of ``motion``'s plan or execution at ``fps`` [Hz] and the n joint names
    (the order of the joint columns).

    Raises:
        CliError (exit 2): the file names no joints (or not one per column), or
            ``source="execution"`` and the file holds no simulated execution.
        ValueError: a bad ``fps`` or ``source``.
    """
    names, cols = source_columns(motion, fps, source)
    samples = resample(cols, fps)
    rows = np.hstack([samples["root_pos"], samples["root_rot"], samples["joint_pos"]])
    return rows, names


def write_lafan(fh: IO[bytes], rows: np.ndarray) -> None:
    """Write ``rows`` as headerless CSV, numbers in Python's ``repr`` (read back exactly)."""
    for row in rows:
        fh.write((",".join(repr(float(x)) for x in row) + "\n").encode("ascii"))
