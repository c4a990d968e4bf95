"""Faults a simulated motion is put through: pushes, model errors, sensor noise, control delay.

A faults file is JSON, every key optional, unknown keys refused (docs/safety.md)::

    {"pushes": [{"t": 1.5, "impulse": 20, "direction": [1, 0, 0], "body": "base"}],
     "friction_scale": 0.7, "mass_scale": {"base": 1.1}, "joint_noise": 0.001, "delay_ticks": 2,
     "floor_step": 0.01, "seed": 0}

SI units: s, N s, rad, m. :func:`load_faults` reads and checks a file, :func:`faults_from_dict` a
dict; :func:`apply_to_model` changes a (copied) MuJoCo model, and the loop applies the rest.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from robots import safeio
from sim.exceptions import FaultsError

#: Longest push [s]; a push lasts 0.1 s unless it says otherwise.
MAX_PUSH_DURATION = 1.0
#: Largest impulse [N s] (Talos, 90 kg, would get 5.5 m/s).
MAX_IMPULSE = 500.0
#: Ranges of the scalar faults.
FRICTION_RANGE = (0.05, 2.0)
MASS_RANGE = (0.2, 5.0)
MAX_JOINT_NOISE = 0.1  # [rad]
MAX_DELAY_TICKS = 50
MAX_FLOOR_STEP = 0.1  # [m]
_KEYS = ("pushes", "friction_scale", "mass_scale", "joint_noise", "delay_ticks", "floor_step", "seed")
_PUSH_KEYS = ("t", "impulse", "direction", "body", "duration")
#: The floating base's MuJoCo body may be called ``base`` in a faults file.
BASE_ALIAS = "base"


@dataclass(frozen=True, slots=True, kw_only=True)
class FaultPush:
    """An impulse on a body: ``impulse / duration`` newtons from ``t`` for ``duration``.

    Attributes:
        t: Start [s].
        impulse: Magnitude [N s].
        direction: Direction in the world (normalized on use).
        body: MuJoCo body (a URDF link name) or ``base``.
        duration: Length [s].
    """

    t: float
    impulse: float
    direction: tuple[float, float, float] = (1.0, 0.0, 0.0)
    body: str = BASE_ALIAS
    duration: float = 0.1

    def force(self) -> np.ndarray:
        """The force vector [N] while the push lasts."""
        d = np.asarray(self.direction, dtype=float)
        return self.impulse / self.duration * d / np.linalg.norm(d)


@dataclass(frozen=True, slots=True, kw_only=True)
class Faults:
    """What goes wrong during a simulated motion (all optional; the defaults change nothing).

    Attributes:
        pushes: Impulses on bodies.
        friction_scale: Every contact's sliding friction times this [-] (the plan assumed 1).
        mass_scale: Body -> factor on its mass and inertia [-] (``base``: the floating base).
        joint_noise: Standard deviation of the Gaussian noise on every measured joint angle [rad].
        delay_ticks: Controller ticks between a torque's computation and its application [-].
        floor_step: Height of a floor step under the left sole that the plan does not know [m]
            (the sole box is raised by it: the left foot stands that much higher).
        seed: Seed of the noise.
    """

    pushes: tuple[FaultPush, ...] = ()
    friction_scale: float = 1.0
    mass_scale: dict[str, float] = field(default_factory=dict)
    joint_noise: float = 0.0
    delay_ticks: int = 0
    floor_step: float = 0.0
    seed: int = 0

    @property
    def changes_model(self) -> bool:
        """The MuJoCo model itself changes (friction, masses, floor)."""
        return self.friction_scale != 1.0 or bool(self.mass_scale) or self.floor_step != 0.0

    def describe(self) -> str:
        """The faults in words (empty when there is none)."""
        parts = [f"{p.impulse:g} N s on {p.body} at t = {p.t:g} s" for p in self.pushes]
        if self.friction_scale != 1.0:
            parts.append(f"friction x {self.friction_scale:g}")
        parts += [f"{b} mass x {s:g}" for b, s in self.mass_scale.items()]
        if self.joint_noise:
            parts.append(f"joint noise {self.joint_noise:g} rad")
        if self.delay_ticks:
            parts.append(f"delay {self.delay_ticks} ticks")
        if self.floor_step:
            parts.append(f"floor step {1000 * self.floor_step:g} mm")
        return ", ".join(parts)

    def to_dict(self) -> dict[str, Any]:
        """The JSON form (what :func:`faults_from_dict` reads)."""
        return {"pushes": [{"t": p.t, "impulse": p.impulse, "direction": list(p.direction), "body": p.body,
                            "duration": p.duration} for p in self.pushes],
                "friction_scale": self.friction_scale, "mass_scale": dict(self.mass_scale),
                "joint_noise": self.joint_noise, "delay_ticks": self.delay_ticks, "floor_step": self.floor_step,
                "seed": self.seed}


def _number(where: str, x: object, lo: float, hi: float, unit: str = "") -> float:
    if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(float(x)) \
            or not lo <= float(x) <= hi:
        raise FaultsError(f"faults: {where} must be a number from {lo:g} to {hi:g}{unit}, got {json.dumps(x)[:40]}")
    return float(x)


def _push(i: int, p: object) -> FaultPush:
    where = f"pushes[{i}]"
    if not isinstance(p, dict):
        raise FaultsError(f"faults: {where} must be an object like {{\"t\": 1.5, \"impulse\": 20}}, got {json.dumps(p)[:40]}")
    unknown = sorted(set(p) - set(_PUSH_KEYS))
    if unknown:
        raise FaultsError(f"faults: {where} has unknown key {unknown[0]!r}; the keys are {', '.join(_PUSH_KEYS)}")
    for key in ("t", "impulse"):
        if key not in p:
            raise FaultsError(f"faults: {where} needs {key!r} ({'start time [s]' if key == 't' else 'impulse [N s]'})")
    t = _number(f"{where}.t", p["t"], 0.0, 3600.0, " s")
    impulse = _number(f"{where}.impulse", p["impulse"], 0.0, MAX_IMPULSE, " N s")
    duration = _number(f"{where}.duration", p.get("duration", 0.1), 1e-3, MAX_PUSH_DURATION, " s")
    direction = p.get("direction", [1, 0, 0])
    if not (isinstance(direction, list) and len(direction) == 3
            and all(isinstance(c, (int, float)) and not isinstance(c, bool) and math.isfinite(c) for c in direction)
            and any(c != 0 for c in direction)):
        raise FaultsError(f"faults: {where}.direction must be a non-zero 3-vector like [1, 0, 0], "
                          f"got {json.dumps(direction)[:40]}")
    body = p.get("body", BASE_ALIAS)
    if not isinstance(body, str) or not body:
        raise FaultsError(f"faults: {where}.body must be a body name such as \"base\", got {json.dumps(body)[:40]}")
    return FaultPush(t=t, impulse=impulse, direction=(float(direction[0]), float(direction[1]), float(direction[2])),
                     body=body, duration=duration)


def faults_from_dict(raw: object) -> Faults:
    """Check a faults object (one-line :class:`FaultsError` naming the key and the range)."""
    if not isinstance(raw, dict):
        raise FaultsError(f"faults: the file must hold a JSON object such as {{\"friction_scale\": 0.7}}, "
                          f"got {type(raw).__name__}")
    unknown = sorted(set(raw) - set(_KEYS))
    if unknown:
        raise FaultsError(f"faults: unknown key {unknown[0]!r}; the keys are {', '.join(_KEYS)}")
    pushes = raw.get("pushes", [])
    if not isinstance(pushes, list):
        raise FaultsError("faults: pushes must be a list of {\"t\", \"impulse\", \"direction\", \"body\"} objects")
    mass = raw.get("mass_scale", {})
    if not isinstance(mass, dict):
        raise FaultsError("faults: mass_scale must be an object of body -> factor, e.g. {\"base\": 1.1}")
    masses = {str(b): _number(f"mass_scale[{b!r}]", s, *MASS_RANGE) for b, s in mass.items()}
    delay = raw.get("delay_ticks", 0)
    if isinstance(delay, bool) or not isinstance(delay, int) or not 0 <= delay <= MAX_DELAY_TICKS:
        raise FaultsError(f"faults: delay_ticks must be a whole number from 0 to {MAX_DELAY_TICKS}, "
                          f"got {json.dumps(delay)[:40]}")
    seed = raw.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise FaultsError(f"faults: seed must be a whole number >= 0, got {json.dumps(seed)[:40]}")
    return Faults(
        pushes=tuple(_push(i, p) for i, p in enumerate(pushes)),
        friction_scale=_number("friction_scale", raw.get("friction_scale", 1.0), *FRICTION_RANGE),
        mass_scale=masses,
        joint_noise=_number("joint_noise", raw.get("joint_noise", 0.0), 0.0, MAX_JOINT_NOISE, " rad"),
        delay_ticks=int(delay),
        floor_step=_number("floor_step", raw.get("floor_step", 0.0), 0.0, MAX_FLOOR_STEP, " m"),
        seed=int(seed),
    )


def load_faults(path: str | Path) -> Faults:
    """Read and check a faults file (one-line :class:`FaultsError`: missing, unreadable, not JSON, a bad key)."""
    p = Path(path)
    try:
        if not p.exists():
            raise FaultsError(f"faults file {str(path)!r}: no such file (give a JSON file, docs/safety.md)")
        text = safeio.read_text(p, "record")  # a regular file (a FIFO never blocks), at most 1 MiB
    except safeio.NotRegularFile:
        raise FaultsError(f"faults file {str(path)!r} is not a regular file; give a JSON file") from None
    except safeio.FileTooLarge:
        raise FaultsError(f"faults file {str(path)!r}: larger than 1 MiB; a faults file is a few lines of JSON") from None
    except (OSError, UnicodeDecodeError) as e:
        raise FaultsError(f"faults file {str(path)!r} cannot be read: {type(e).__name__}") from None
    try:
        raw = json.loads(text)
    except json.JSONDecodeError as e:
        raise FaultsError(f"faults file {str(path)!r} is not JSON: {e.msg} at line {e.lineno}") from None
    try:
        return faults_from_dict(raw)
    except FaultsError as e:
        raise FaultsError(f"faults file {str(path)!r}: {str(e).removeprefix('faults: ')}") from None


def body_id(model: mujoco.MjModel, name: str, base_body: int) -> int:
    """MuJoCo body id of ``name`` (``base``: the floating base), or :class:`FaultsError` naming a few bodies."""
    if name == BASE_ALIAS:
        return base_body
    bid = int(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name))
    if bid <= 0:
        names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) for b in range(1, min(model.nbody, 8))]
        raise FaultsError(f"faults: the robot has no body {name!r}; use \"base\" or a link name such as "
                          f"{', '.join(repr(n) for n in names)}")
    return bid


def apply_to_model(faults: Faults, model: mujoco.MjModel, *, base_body: int, floor_geom: int,
                   left_sole_geom: int | None) -> None:
    """Change ``model`` in place (give a copy): friction, masses and inertias, the floor step."""
    if faults.friction_scale != 1.0:
        model.geom_friction[:, 0] *= faults.friction_scale
        model.pair_friction[:, :2] *= faults.friction_scale
    for name, s in faults.mass_scale.items():
        b = body_id(model, name, base_body)
        model.body_mass[b] *= s
        model.body_inertia[b] *= s
    if faults.floor_step and left_sole_geom is not None:
        # the left sole box stands on a step: its bottom face is raised by the step's height
        model.geom_pos[left_sole_geom, 2] -= faults.floor_step
