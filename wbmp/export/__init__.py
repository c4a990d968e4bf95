"""Exports of a motion file for other tools: a ROS 2 bag (MCAP) and a tracker file (``.npz``).

The JSON and CSV exports (:mod:`wbmp.export.files`, with ``export_motion``, the entry point of
every format) hold the motion file's keys as they are; the other formats convert: ROS 2 messages with stamps and frames
(:mod:`wbmp.export.rosbag`), and a uniform-rate resampling for motion trackers
(:mod:`wbmp.export.tracker`). ``docs/export.md`` states every convention.
"""

from wbmp.export.columns import (
    MotionColumns,
    execution_columns,
    joint_names,
    object_frame_ids,
    plan_columns,
)
from wbmp.export.rosbag import BagOptions, write_bag
from wbmp.export.tracker import DEFAULT_FPS, TRACKER_FORMAT, resample, tracker_arrays

__all__ = ["DEFAULT_FPS", "TRACKER_FORMAT", "BagOptions", "MotionColumns", "execution_columns",
           "joint_names", "object_frame_ids", "plan_columns", "resample",
           "tracker_arrays", "write_bag"]
