"""Draw the terrain motions on talos: a side view of the stairs climb, the slope walk and the sit.

Each sentence is planned in its example scene (no simulation) and drawn from the side (x forward,
z up): the scene objects' outlines (their x-z projection), the floor, and the robot's stick figure
at a few instants over them, later ones darker. The README's table shows these pictures::

    python examples/terrain_pictures.py                 # into docs/images/terrain
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # run from a checkout without installing
    sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402
from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.patches import Polygon  # noqa: E402
from scipy.spatial import ConvexHull  # noqa: E402

from tasks.scene import load_scene, rotation  # noqa: E402
from viz.plots import skeleton_segments  # noqa: E402
from wbmp.pipeline import SolveRequest, solve  # noqa: E402

PICTURES = {  # name: sentence, scene file, the drawing's x range [m]
    "stairs": ("walk up the stairs", "stairs.json", (-0.5, 1.5)),
    "slope": ("walk up the slope", "slope.json", (-0.5, 1.5)),
    "chair": ("sit down, then stand up", "chair.json", (-1.0, 1.0)),
}
INSTANTS = 6


def outline(obj) -> np.ndarray:
    """The x-z outline of a box (the convex hull of its corners' projection) [m]."""
    R = np.array(rotation(obj.rpy))
    h = np.asarray(obj.size) / 2
    corners = np.array([R @ (h * [a, b, c]) + np.asarray(obj.position)
                        for a in (-1, 1) for b in (-1, 1) for c in (-1, 1)])[:, [0, 2]]
    return corners[ConvexHull(corners).vertices]


def draw(name: str, out: Path) -> Path:
    sentence, file, xlim = PICTURES[name]
    path = ROOT / "examples" / "scenes" / file
    scene = load_scene(path)
    result = solve(SolveRequest(instruction=sentence, robot="talos", scene_path=str(path), simulate=False))
    robot, plan = result.model(), result.plan
    fig = Figure(figsize=(7.5, 4.2))
    ax = fig.subplots()
    for obj in scene.objects:
        ax.add_patch(Polygon(outline(obj), closed=True, facecolor=obj.colour[:3], edgecolor="#555", lw=0.8, zorder=1))
    ax.axhspan(-0.2, 0.0, color="#ddd", zorder=1.5)  # over the part of a ramp under the floor
    ks = np.unique(np.linspace(0, len(plan.t) - 1, INSTANTS).round().astype(int))
    for i, k in enumerate(ks):
        shade = 0.75 - 0.6 * i / max(len(ks) - 1, 1)
        for p0, p1 in skeleton_segments(robot, np.asarray(plan.q[k])):
            ax.plot([p0[0], p1[0]], [p0[2], p1[2]], color=(shade * 0.4, shade * 0.6, shade), lw=1.6,
                    solid_capstyle="round", zorder=2 + i)
    ax.set_aspect("equal")
    ax.set_xlim(*xlim)
    ax.set_ylim(-0.1, 1.9)
    ax.set_title(f'"{sentence}" (talos, {file}): side view, t = 0 to {plan.t[-1]:.1f} s', fontsize=10)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("z [m]")
    FigureCanvasAgg(fig)
    target = out / f"{name}.png"
    fig.savefig(target, dpi=80, bbox_inches="tight")
    return target


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", default=str(ROOT / "docs" / "images" / "terrain"), help="output folder")
    parser.add_argument("names", nargs="*", help=f"the pictures to draw, of {', '.join(PICTURES)} (default: all)")
    args = parser.parse_args(argv)
    unknown = [n for n in args.names if n not in PICTURES]
    if unknown:
        parser.error(f"no picture called {', '.join(unknown)}; choose among {', '.join(PICTURES)}")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for name in args.names or PICTURES:
        print(draw(name, out), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
