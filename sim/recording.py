"""What the closed loop records at each controller tick, and the typed record of a whole run.

:class:`Recorder` fills preallocated arrays one tick at a time (state, torques, CoM, which soles
and which other bodies touch the floor, the net floor force on each sole); :meth:`Recorder.finish`
turns them into a :class:`RunRecord`, the certificate's only input.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from planner.wbc.reference import PlanReference
from robots.model import Robot
from sim.model import SimModel
from sim.settings import SimSettings

#: MuJoCo body of the floating base (body 0 is the world).
BASE_BODY = 1


def tilt(quat_xyzw: np.ndarray) -> np.ndarray:
    """Angle between the base z axis and the vertical [rad], for (N, 4) quaternions."""
    x, y = quat_xyzw[..., 0], quat_xyzw[..., 1]
    zz = 1.0 - 2.0 * (x * x + y * y)
    return np.arccos(np.clip(zz, -1.0, 1.0))


def tilt_of(q: np.ndarray) -> float:
    """Angle between the base z axis and the vertical [rad] of one configuration (scalar math)."""
    x, y = q[3:5].tolist()
    return math.acos(min(1.0, max(-1.0, 1.0 - 2.0 * (x * x + y * y))))


def torque_fraction(taus: np.ndarray, limits: np.ndarray) -> np.ndarray:
    """|tau| / limit per sample and joint; joints without a usable limit (0 or inf) count as 0."""
    usable = (limits > 0) & np.isfinite(limits)
    safe = np.where(usable, limits, 1.0)
    return np.where(usable, np.abs(taus) / safe, 0.0)


@dataclass(frozen=True, eq=False, kw_only=True)
class RunRecord:
    """A finished closed-loop run: what was simulated and what was recorded, one row per tick.

    Attributes:
        robot: The robot.
        ref: The plan as the controller tracked it.
        settings: The simulation and certificate options.
        t: Tick times (T',) [s].
        q: Configurations (T', nq), Pinocchio order.
        v: Velocities (T', nv).
        tau: Applied actuated torques (T', nv - 6) [N m].
        com: Centre of mass (T', 3) [m].
        tick_times: Controller tick durations (T',) [s].
        foot_frames: The sole frames recorded (``left_foot``, ``right_foot`` roles the model has).
        forces: Net floor force on each of them (len(foot_frames), T', 3) in the world [N].
        contact_flags: Whether each of them touches the floor (len(foot_frames), T').
        other_contacts: ``(time [s], body)`` of every tick a body other than a sole touched the floor.
        qp_failure_times: Ticks whose controller QP failed [s].
        torque_limits: Actuated joint torque limits (nv - 6,) [N m].
        fall_height: A base below this height is a fall [m].
        max_tilt: A base tilted more than this is a fall [rad].
    """

    robot: Robot
    ref: PlanReference
    settings: SimSettings
    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    tau: np.ndarray
    com: np.ndarray
    tick_times: np.ndarray
    foot_frames: tuple[str, ...]
    forces: np.ndarray
    contact_flags: np.ndarray
    other_contacts: tuple[tuple[float, str], ...]
    qp_failure_times: tuple[float, ...]
    torque_limits: np.ndarray
    fall_height: float
    max_tilt: float

    @property
    def n_ticks(self) -> int:
        """Controller ticks run."""
        return len(self.t)


class Recorder:
    """Preallocated per-tick arrays of a run of at most ``n_ticks`` ticks.

    Args:
        sm: The MuJoCo model.
        robot: The robot.
        n_ticks: Largest number of ticks.
    """

    def __init__(self, sm: SimModel, robot: Robot, n_ticks: int) -> None:
        m = sm.model
        self.t = np.empty(n_ticks)
        self.q = np.empty((n_ticks, robot.nq))
        self.v = np.empty((n_ticks, robot.nv))
        self.tau = np.empty((n_ticks, robot.nv - 6))
        self.com = np.empty((n_ticks, 3))
        self.tick_times = np.empty(n_ticks)
        foot_roles = [role for role in ("left_foot", "right_foot") if role in sm.sole_geoms]
        self.foot_frames = tuple(robot.frame(role) for role in foot_roles)
        self.forces = np.zeros((len(foot_roles), n_ticks, 3))
        self.contact_flags = np.zeros((len(foot_roles), n_ticks), dtype=bool)
        self.other_contacts: list[tuple[float, str]] = []
        self.n = 0  # ticks recorded
        sole_ids = np.array([sm.sole_geoms[role] for role in foot_roles], dtype=int)
        self._foot_bodies = np.array([m.geom_bodyid[g] for g in sole_ids], dtype=int)
        self._model = m
        self._floor = sm.floor_geom
        self._body_names = sm.geom_body_names
        self._n_soles = len(sole_ids)
        self._geom_label = np.full(m.ngeom + 1, -1, dtype=int)  # index -1 (no floor in the pair) -> -2
        self._geom_label[-1] = -2
        self._geom_label[sole_ids] = np.arange(self._n_soles)

    def record(self, i: int, t: float, q: np.ndarray, v: np.ndarray, tau: np.ndarray, d: mujoco.MjData,
               tick_time: float) -> None:
        """Record tick ``i`` at time ``t`` [s]: the state, the torques, the CoM and the floor contacts."""
        self.tick_times[i] = tick_time
        self.t[i] = t
        self.q[i] = q
        self.v[i] = v
        self.tau[i] = tau
        self.com[i] = d.subtree_com[BASE_BODY]
        if d.ncon:
            self._record_contacts(i, t, d)
        self.n = i + 1

    def _record_contacts(self, i: int, t: float, d: mujoco.MjData) -> None:
        """Contacts of the current state (vectorized: a Python loop over contacts costs ~0.2 ms)."""
        geom = d.contact.geom
        g1, g2 = geom[:, 0], geom[:, 1]
        other = np.where(g1 == self._floor, g2, np.where(g2 == self._floor, g1, -1))
        # what touches the floor: sole j -> j, another robot geom -> -1, no floor -> -2
        labels = self._geom_label[other]
        touching = set(labels.tolist())
        for j in range(self._n_soles):
            self.contact_flags[j, i] = j in touching
        if -1 in touching:
            for g in other[labels == -1].tolist():
                self.other_contacts.append((t, self._body_names[g]))
        mujoco.mj_rnePostConstraint(self._model, d)  # net contact force per body in cfrc_ext
        self.forces[:, i] = d.cfrc_ext[self._foot_bodies, 3:]

    def finish(self, *, robot: Robot, ref: PlanReference, settings: SimSettings,
               qp_failure_times: list[float], torque_limits: np.ndarray, fall_height: float,
               max_tilt: float) -> RunRecord:
        """The record of the ticks run so far."""
        sl = slice(0, self.n)
        return RunRecord(
            robot=robot, ref=ref, settings=settings,
            t=self.t[sl], q=self.q[sl], v=self.v[sl], tau=self.tau[sl], com=self.com[sl],
            tick_times=self.tick_times[sl], foot_frames=self.foot_frames, forces=self.forces[:, sl],
            contact_flags=self.contact_flags[:, sl], other_contacts=tuple(self.other_contacts),
            qp_failure_times=tuple(qp_failure_times), torque_limits=torque_limits,
            fall_height=fall_height, max_tilt=max_tilt,
        )
