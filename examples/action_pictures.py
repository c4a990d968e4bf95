"""Draw what every registered action looks like on a robot: one keyframe strip per action.

Each action is planned (no simulation) from one plain sentence and drawn as side and front
stick figures at five instants (:func:`viz.plots.plot_keyframes`), then stored as a small
palette PNG. ``docs/primitives.md`` and the README's action table show these pictures::

    python examples/action_pictures.py                  # every action, talos, into docs/images/actions
    python examples/action_pictures.py kick punch --robot g1 --out /tmp/pictures

An action that the robot cannot do is reported and skipped; the exit code is 1 when any failed.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # run from a checkout without installing
    sys.path.insert(0, str(ROOT))

from PIL import Image  # noqa: E402

from tasks.actions import REGISTRY  # noqa: E402
from viz.files import atomic_write  # noqa: E402
from viz.plots import plot_keyframes  # noqa: E402
from wbmp.errors import classify  # noqa: E402
from wbmp.pipeline import SolveRequest, solve  # noqa: E402

# One plain sentence per action; an action missing here is asked for by its name.
SENTENCES = {
    "stand": "stand still for two seconds",
    "squat": "squat",
    "wave": "wave your right hand",
    "reach": "reach forward with your right hand",
    "raise_arms": "raise both arms",
    "bow": "bow",
    "turn_head": "look to the left",
    "lean": "lean to the left",
    "balance": "stand on your left foot",
    "step": "take a step forward",
    "walk": "walk forward half a meter",
    "turn": "turn left 90 degrees",
    "jump": "jump",
    "kick": "kick with your right leg",
    "march": "march in place",
    "walk_arc": "walk in a circle",
    "hop": "hop on your left foot",
    "lunge": "lunge forward with your right leg",
    "stomp": "stomp your right foot",
    "jog": "jog in place",
    "punch": "punch with your right hand",
    "clap": "clap your hands",
    "touch": "touch your head with your right hand",
    "hands_on_hips": "put your hands on your hips",
    "cross_arms": "cross your arms",
    "arms_out": "stretch your arms out to the sides",
    "point": "point forward with your right hand",
    "salute": "salute",
    "arm_circles": "make circles with your arms",
    "shrug": "shrug",
    "stretch": "stretch your arms up",
    "nod": "nod",
    "shake_head": "shake your head",
}
MAX_COLOURS = 48  # palette size of the stored PNG (stick figures need few colours)
SCALE = 0.55  # stored size relative to the plot


def sentence(action: str) -> str:
    """The sentence that asks for ``action``."""
    return SENTENCES.get(action, action.replace("_", " "))


def picture(action: str, robot: str, out: Path) -> tuple[Path, float]:
    """Plan ``action`` on ``robot`` and write its keyframe strip to ``out/<action>.png``."""
    start = time.perf_counter()
    result = solve(SolveRequest(instruction=sentence(action), robot=robot, simulate=False))
    with tempfile.TemporaryDirectory() as tmp:
        raw = plot_keyframes(Path(tmp) / "keyframes.png", result.model(), result.plan, count=5)
        with Image.open(raw) as img:
            small = img.convert("RGB").resize((int(img.width * SCALE), int(img.height * SCALE)), Image.LANCZOS)
            small = small.quantize(colors=MAX_COLOURS)
            target = out / f"{action}.png"
            atomic_write(target, lambda fh: small.save(fh, format="PNG", optimize=True))
    return target, time.perf_counter() - start


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("actions", nargs="*", help="actions to draw (default: every registered action)")
    parser.add_argument("--robot", default="talos", help="robot name or profile (default: talos)")
    parser.add_argument("--out", default=str(ROOT / "docs" / "images" / "actions"), help="output folder")
    args = parser.parse_args(argv)
    names = args.actions or list(REGISTRY)
    unknown = [a for a in names if a not in REGISTRY]
    if unknown:
        parser.error(f"unknown action(s) {', '.join(unknown)}; known: {', '.join(REGISTRY)}")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    failed = 0
    for i, action in enumerate(names, 1):
        try:
            path, seconds = picture(action, args.robot, out)
        except Exception as exc:  # a robot that cannot do an action: report and go on
            if classify(exc) is None:
                raise  # a bug, not a refusal
            failed += 1
            print(f"[{i}/{len(names)}] {action}: skipped: {exc}", flush=True)
            continue
        print(f"[{i}/{len(names)}] {action}: {path} ({path.stat().st_size / 1024:.0f} KiB, {seconds:.1f} s)",
              flush=True)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
