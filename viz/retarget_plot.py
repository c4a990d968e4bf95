"""A PNG of a retargeted motion against its source: ``wbmp retarget --plot``.

One row per tracked body (pelvis, torso, head, hands, feet): its x, y and z over time, the scaled
source keypoint (dashed) against the robot's (solid: the executed motion when simulated, else the
plan), and their distance (the tracking error; a foot's only while it swings). The largest error
is marked and written in the title, the number the report prints as the tracking error's max. A
last row shows each foot's lowest sole point above the floor, with its labelled contacts shaded.

Takes the figures' own samples (:class:`KeypointPlot` around :func:`tasks.mocap.figures.tracks`'
:class:`~tasks.mocap.figures.Tracks`), so what is drawn is what the figures are made of.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib

matplotlib.use("Agg")  # no display; harmless when already set

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from viz.files import atomic_write

if TYPE_CHECKING:
    from tasks import Tracks

DPI = 90
ROBOT_COLOR = "#c1121f"
SOURCE_COLOR = "#1d4ed8"
ERROR_COLOR = "#6b7280"
CONTACT_FACE = "#9bd3a8"
BODY_LABELS = {"base": "pelvis", "torso": "torso", "head": "head", "left_hand": "left hand",
               "right_hand": "right hand", "left_foot": "left foot", "right_foot": "right foot"}


@dataclass(frozen=True, eq=False)
class KeypointPlot:
    """What the plot draws.

    Attributes:
        tracks: The robot's keypoints beside the scaled source, their tracking error and the soles
            (:class:`tasks.mocap.figures.Tracks`, at the samples drawn): what the report's figures
            are computed from.
        contact: Foot side -> labelled contact at each sample (T,) bool.
        title: The first title line (clip, robot, which motion).
    """

    tracks: Tracks
    contact: dict[str, np.ndarray]
    title: str = ""

    @property
    def t(self) -> np.ndarray:
        """Sample times (T,) [s]."""
        return self.tracks.t

    @property
    def robot(self) -> dict[str, np.ndarray]:
        """Body role -> the robot's keypoint (T, 3) [m]."""
        return self.tracks.robot

    @property
    def source(self) -> dict[str, np.ndarray]:
        """Body role -> the scaled source keypoint (T, 3) [m]."""
        return self.tracks.source

    @property
    def error(self) -> dict[str, np.ndarray]:
        """Body role -> tracking error (T,) [m] (NaN where not counted)."""
        return self.tracks.error

    @property
    def foot_height(self) -> dict[str, np.ndarray]:
        """Foot side -> the lowest sole point's height (T,) [m]."""
        return self.tracks.foot_heights()

    def worst(self) -> tuple[str, float, float]:
        """(body role, time [s], error [m]) of the largest tracking error drawn (the report's)."""
        role, i, err = self.tracks.worst()
        return role, float(self.t[i]) if err >= 0 else 0.0, err

    def annotation(self) -> str:
        """The title's second line: ``max tracking error 0.141 m: left hand at 2.40 s``."""
        role, time, err = self.worst()
        if err < 0:
            return "no tracked keypoint"
        mean = float(np.nanmean(np.concatenate([e for e in self.error.values()])))
        return (f"tracking error: max {err:.3f} m ({BODY_LABELS.get(role, role)} at {time:.2f} s), "
                f"mean {mean:.3f} m")


def plot_keypoints(path: str | os.PathLike, data: KeypointPlot) -> Path:
    """Write the PNG (atomically) to ``path``; returns it."""
    roles = list(data.robot)
    fig = Figure(figsize=(13.0, 2.0 * (len(roles) + 1)))
    FigureCanvasAgg(fig)
    axes = fig.subplots(len(roles) + 1, 4, sharex=True, squeeze=False)
    w_role, w_time, w_err = data.worst()
    for r, role in enumerate(roles):
        for c, axis in enumerate("xyz"):
            ax = axes[r][c]
            ax.plot(data.t, data.source[role][:, c], "--", color=SOURCE_COLOR, lw=1.2, label="source (scaled)")
            ax.plot(data.t, data.robot[role][:, c], "-", color=ROBOT_COLOR, lw=1.2, label="robot")
            ax.set_ylabel(f"{BODY_LABELS.get(role, role)}\n{axis} [m]" if c == 0 else f"{axis} [m]", fontsize=8)
            ax.tick_params(labelsize=7)
        ax = axes[r][3]
        ax.plot(data.t, data.error[role], color=ERROR_COLOR, lw=1.2)
        ax.set_ylabel("error [m]", fontsize=8)
        ax.tick_params(labelsize=7)
        if role == w_role:
            ax.plot([w_time], [w_err], "o", color=ROBOT_COLOR)
            ax.annotate(f"max {w_err:.3f} m", (w_time, w_err), fontsize=8, xytext=(4, -10),
                        textcoords="offset points")
    axes[0][0].legend(fontsize=7, loc="best")
    _feet(axes[-1], data)
    for c in range(4):
        axes[-1][c].set_xlabel("t [s]", fontsize=8)
    fig.suptitle(f"{data.title}\n{data.annotation()}", fontsize=10)
    fig.tight_layout(rect=(0, 0, 1, 0.97))
    out = Path(path)

    def write(fh) -> None:
        fig.savefig(fh, dpi=DPI, format="png")

    return atomic_write(out, write)


def _feet(row, data: KeypointPlot) -> None:
    """The last row: each foot's height with its contacts shaded (two panels), the rest hidden."""
    for ax, side in zip(row[:2], ("left", "right"), strict=False):
        h = data.foot_height.get(side)
        if h is None:
            ax.set_visible(False)
            continue
        on = np.asarray(data.contact[side], dtype=bool)
        ax.fill_between(data.t, 0.0, 1.0, where=on, color=CONTACT_FACE, alpha=0.6, step="mid",
                        transform=ax.get_xaxis_transform(), label="labelled contact")
        ax.plot(data.t, 1000.0 * h, color=ROBOT_COLOR, lw=1.2)
        ax.axhline(0.0, color="k", lw=0.6)
        ax.set_ylabel(f"{side} sole\nheight [mm]", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.legend(fontsize=7, loc="upper right")
    for ax in row[2:]:
        ax.set_visible(False)
