"""What the closed loop records at each controller tick, and the typed record of a whole run.

:class:`Recorder` fills preallocated arrays one tick at a time (state, torques, CoM, which soles
and which other bodies touch the floor, the net floor force on each sole); :meth:`Recorder.finish`
turns them into a :class:`RunRecord`, the certificate's only input.

Collisions: at every tick the MuJoCo contacts between two links of the collision model (their
depth, < 0) and between the robot and a scene object; every ``collision_sample_period`` the
closest link pair and the closest robot-object distance (``mujoco.mj_geomDistance`` on the same
geoms, within ``self_distance_horizon`` / ``scene_distance_horizon``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import mujoco
import numpy as np

from planner import PlanReference
from robots import Robot
from sim.model import OBJECT_ROLE, ROBOT_ROLE, SimModel
from sim.settings import SimSettings

#: MuJoCo body of the floating base (body 0 is the world).
BASE_BODY = 1
#: Bits of :meth:`Recorder._contact_codes` for the contacts the record keeps beyond the soles: a robot
#: geom other than a sole on the floor; a collision pair in contact or a robot-object touch not planned.
_ON_FLOOR = 1 << 40
_COLLISION = 1 << 41


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
        collision_pairs: The collision model's link pairs (the indices below refer to them).
        rest_overlap: Pairs MuJoCo does not collide (their hulls overlap at rest), see
            :class:`sim.model.SimModel`.
        self_contacts: MuJoCo contacts between the two links of a pair: tick, pair index,
            distance [m] (< 0: penetration depth) and normal force [N], (K, 4).
        self_samples: Every ``collision_sample_period``: tick, closest pair index (-1: none within
            the horizon) and its distance [m] (inf: none), (S, 3).
        object_names: The scene's objects.
        scene_contacts: ``(tick, link, object, distance [m])`` of every robot-object contact but the
            planned ones (a grasping hand and its object: a closed gripper's fingers on it).
        scene_samples: Every ``collision_sample_period``: ``(tick, link, object, distance [m])`` of
            the closest robot-object pair within the horizon (none when there is no object).
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
    collision_pairs: tuple[tuple[str, str], ...] = ()
    rest_overlap: dict[tuple[str, str], float] | None = None
    self_contacts: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))
    self_samples: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    object_names: tuple[str, ...] = ()
    scene_contacts: tuple[tuple[int, str, str, float], ...] = ()
    scene_samples: tuple[tuple[int, str, str, float], ...] = ()

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

    def __init__(self, sm: SimModel, robot: Robot, n_ticks: int, settings: SimSettings | None = None, *,
                 exempt: set[tuple[int, int]] | None = None) -> None:
        m = sm.model
        s = settings if settings is not None else SimSettings()
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
        if len(sm.geom_role):  # an object on the floor is not the robot touching it
            self._geom_label[:-1][sm.geom_role == OBJECT_ROLE] = -2
        self._collisions = _CollisionRecorder(sm, s, exempt or set())
        self._codes = self._contact_codes(sm)

    def _contact_codes(self, sm: SimModel) -> np.ndarray:
        """(ngeom, ngeom) table of what a contact between two geoms means for the record: bit ``j``
        for sole ``j`` on the floor, :data:`_ON_FLOOR` for another robot geom on the floor,
        :data:`_COLLISION` for a collision pair or a robot-object touch that is not planned, 0 for
        what it ignores (an object on the floor, a planned touch). A tick's contacts cost one
        look-up; the array operations of the floor's other contacts and of the collisions run only
        on the ticks that have them (the stairs: a sole on a tread is a robot-object touch)."""
        ngeom = sm.model.ngeom
        geoms = np.arange(ngeom)
        other = np.full((ngeom, ngeom), -1)  # the geom touching the floor, -1: no floor in the pair
        other[self._floor, :] = geoms
        other[:, self._floor] = geoms
        other[self._floor, self._floor] = -1
        labels = self._geom_label[other]  # sole j -> j, another robot geom -> -1, no floor -> -2
        codes = np.where(labels >= 0, np.left_shift(1, np.maximum(labels, 0)), 0).astype(np.int64)
        c = self._collisions
        a, b = geoms[:, None], geoms[None, :]
        touch = ((c._is_object[a] & c._is_robot[b]) | (c._is_robot[a] & c._is_object[b])) & ~c._planned[a, b]
        codes[labels == -1] |= _ON_FLOOR
        codes[(c._pair_of[:ngeom, :ngeom] >= 0) | touch] |= _COLLISION
        return codes

    @property
    def collisions(self) -> _CollisionRecorder:
        """The self- and scene-collision part of the record."""
        return self._collisions

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
            geom = d.contact.geom
            seen = int(np.bitwise_or.reduce(self._codes[geom[:, 0], geom[:, 1]]))
            for j in range(self._n_soles):  # the soles on the floor
                self.contact_flags[j, i] = bool(seen >> j & 1)
            if seen & _ON_FLOOR:
                self._record_floor_contacts(t, d)
            mujoco.mj_rnePostConstraint(self._model, d)  # net contact force per body in cfrc_ext
            self.forces[:, i] = d.cfrc_ext[self._foot_bodies, 3:]
            if seen & _COLLISION:
                self._collisions.contacts(i, d)
        self._collisions.sample(i, t, d)
        self.n = i + 1

    def _record_floor_contacts(self, t: float, d: mujoco.MjData) -> None:
        """The robot's geoms other than the soles on the floor at time ``t``."""
        geom = d.contact.geom
        g1, g2 = geom[:, 0], geom[:, 1]
        other = np.where(g1 == self._floor, g2, np.where(g2 == self._floor, g1, -1))
        labels = self._geom_label[other]  # what touches the floor: sole j -> j, another robot geom -> -1, no floor -> -2
        for g in other[labels == -1].tolist():
            self.other_contacts.append((t, self._body_names[g]))

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
            fall_height=fall_height, max_tilt=max_tilt, **self._collisions.finish(),
        )


class _CollisionRecorder:
    """The collision part of a run's record (see the module docstring)."""

    def __init__(self, sm: SimModel, s: SimSettings, exempt: set[tuple[int, int]]) -> None:
        m = sm.model
        self._m = m
        self._s = s
        self._sm = sm
        ngeom = m.ngeom
        role = sm.geom_role if len(sm.geom_role) else np.full(ngeom, ROBOT_ROLE)
        self._pair_of = np.full((ngeom + 1, ngeom + 1), -1, dtype=int)  # index -1: none
        g1, g2 = np.asarray(m.pair_geom1, dtype=int), np.asarray(m.pair_geom2, dtype=int)
        self._pair_of[g1, g2] = sm.pair_index
        self._pair_of[g2, g1] = sm.pair_index
        self._is_object = np.zeros(ngeom + 1, dtype=bool)
        self._is_object[:-1] = role == OBJECT_ROLE
        self._is_robot = np.zeros(ngeom + 1, dtype=bool)
        self._is_robot[:-1] = role == ROBOT_ROLE
        self._g1, self._g2 = g1, g2
        self._pair_links = sm.pair_index
        self._robot_geoms = np.nonzero(role == ROBOT_ROLE)[0]
        self._object_geoms = np.nonzero(role == OBJECT_ROLE)[0]
        # planned contacts (a hand and the object it grasps, sim.grasp) are no collisions
        self._exempt = np.array([[(int(r), int(o)) in exempt for o in self._object_geoms] for r in self._robot_geoms],
                                dtype=bool).reshape(len(self._robot_geoms), len(self._object_geoms))
        self._planned = np.zeros((ngeom + 1, ngeom + 1), dtype=bool)  # the same pairs, by geom (a closed gripper's fingers)
        for r, o in exempt:
            self._planned[r, o] = self._planned[o, r] = True
        self._rbound = np.asarray(m.geom_rbound, dtype=float)
        self._fromto = np.zeros(6)
        self._wrench = np.zeros(6)
        self._next_sample = 0.0
        self._self_contacts: list[np.ndarray] = []
        self._self_samples: list[tuple[int, int, float]] = []
        self._scene_contacts: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = []  # a tick's contacts
        self._scene_samples: list[tuple[int, str, str, float]] = []

    def contacts(self, i: int, d: mujoco.MjData) -> None:
        """Tick ``i``'s contacts between two links of a pair, and between the robot and an object."""
        geom = d.contact.geom
        a, b = geom[:, 0], geom[:, 1]
        k = self._pair_of[a, b]
        hit = k >= 0
        if hit.any():
            rows = np.nonzero(hit)[0]
            force = np.empty(len(rows))
            for j, c in enumerate(rows.tolist()):
                mujoco.mj_contactForce(self._m, d, c, self._wrench)
                force[j] = self._wrench[0]
            self._self_contacts.append(np.column_stack([np.full(len(rows), i), k[hit], d.contact.dist[hit], force]))
        touch = ((self._is_object[a] & self._is_robot[b]) | (self._is_robot[a] & self._is_object[b])) & ~self._planned[a, b]
        if touch.any():  # named in finish(): a Python loop here cost ~0.1 ms a tick on the stairs
            ta, tb = a[touch], b[touch]
            robot_a = self._is_robot[ta]
            self._scene_contacts.append((np.full(len(ta), i), np.where(robot_a, ta, tb), np.where(robot_a, tb, ta),
                                         d.contact.dist[touch]))

    def sample(self, i: int, t: float, d: mujoco.MjData) -> None:
        """Every ``collision_sample_period``: the closest pair and the closest robot-object distance."""
        if t < self._next_sample - 1e-9:
            return
        self._next_sample = t + self._s.collision_sample_period
        m, xpos = self._m, d.geom_xpos
        if len(self._g1):
            horizon = self._s.self_distance_horizon
            # bounding spheres first: only pairs that may be within the horizon cost a distance
            lower = (np.linalg.norm(xpos[self._g1] - xpos[self._g2], axis=1)
                     - self._rbound[self._g1] - self._rbound[self._g2])
            best, best_k = np.inf, -1
            for p in np.nonzero(lower < horizon)[0].tolist():
                dist = mujoco.mj_geomDistance(m, d, int(self._g1[p]), int(self._g2[p]), horizon, self._fromto)
                if dist < best and dist < horizon:
                    best, best_k = float(dist), int(self._pair_links[p])
            self._self_samples.append((i, best_k, best))
        if len(self._object_geoms):
            horizon = self._s.scene_distance_horizon
            rg, og = self._robot_geoms, self._object_geoms
            lower = (np.linalg.norm(xpos[rg][:, None] - xpos[og][None], axis=2)
                     - self._rbound[rg][:, None] - self._rbound[og][None])
            lower[self._exempt] = np.inf
            best, best_pair = np.inf, (-1, -1)
            for flat in np.argsort(lower, axis=None).tolist():
                r, o = divmod(flat, len(og))
                if lower[r, o] >= min(best, horizon):
                    break
                dist = mujoco.mj_geomDistance(m, d, int(rg[r]), int(og[o]), horizon, self._fromto)
                if dist < best and dist < horizon:
                    best, best_pair = float(dist), (int(rg[r]), int(og[o]))
            if best_pair[0] >= 0:
                obj = self._sm.object_names[int(self._sm.geom_object[best_pair[1]])]
                self._scene_samples.append((i, self._sm.geom_body_names[best_pair[0]], obj, best))

    def _named_scene_contacts(self) -> tuple[tuple[int, str, str, float], ...]:
        """``(tick, link, object, distance)`` of every recorded robot-object contact, in order."""
        if not self._scene_contacts:
            return ()
        ticks, robot_g, obj_g, dist = (np.concatenate(c) for c in zip(*self._scene_contacts, strict=True))
        names, objects = self._sm.geom_body_names, self._sm.object_names
        obj_names = [objects[k] if k >= 0 else "" for k in self._sm.geom_object.tolist()]
        return tuple(zip(ticks.tolist(), [names[g] for g in robot_g.tolist()], [obj_names[g] for g in obj_g.tolist()],
                         dist.tolist(), strict=True))

    def finish(self) -> dict:
        """The collision fields of :class:`RunRecord`."""
        return {
            "collision_pairs": self._sm.collision_pairs,
            "rest_overlap": dict(self._sm.rest_overlap),
            "self_contacts": np.concatenate(self._self_contacts) if self._self_contacts else np.zeros((0, 4)),
            "self_samples": np.array(self._self_samples, dtype=float).reshape(-1, 3),
            "object_names": self._sm.object_names,
            "scene_contacts": self._named_scene_contacts(),
            "scene_samples": tuple(self._scene_samples),
        }
