"""Grasps in the simulation: the gripper closes on the object, then attaches it, and the checks of it.

talos_reduced's fingers hang from fixed joints in Pinocchio (its ``gripper_*_joint`` moves one drive
link and no finger); in MuJoCo they are hinges coupled to the drive by the URDF's ``<mimic>`` tags
(:func:`sim.model.hand_gripper`). For each :class:`tasks.specs.Grasp` of the spec:

* the grasping hand's links (the link of its frame's joint and every body below it, the links the
  planner's scene rows exempt) do not collide with the grasped object, and do not touch the floor
  (they still touch every other object and every link of a self-collision pair);
* a hand with a closing gripper (one hand per object): from the grasp's ``start`` its drive is
  servoed towards its closed limit (:meth:`GraspRig.drive`, at most :data:`GRIP_FRACTION` of its
  effort limit; the controller's torque for the drive is replaced), and its fingertips collide
  with the object (the linkage and drive links stay exempt, like the palm: talos's inner links
  sit 8 mm inside a cup's rim at the grasp pose); the gripper holds the object when its
  fingertips touch it from opposite sides, or its drive is within :data:`CLOSED_MARGIN` of its
  closed limit; at ``end`` it opens again;
* at the first tick from the grasp's ``start`` on where the gripper holds the object (a hand
  without a gripper, or a box between both hands: at once) and the object's centre is within the
  grasp's ``tolerance`` of where the hand holds it (``offset`` in the hand frame), the hand's
  inactive weld to the object (:func:`sim.model.grasp_weld_name`) engages, at the relative pose
  the two have then (no jump): the named simplification, the fingers' friction is not what
  carries the object; at ``end`` it lets go. The object keeps its mass: its weight loads the arm
  through the weld, and the controller, which does not model it, has to carry it.

Every tick records the movable objects' positions, orientations and tilts (the execution's
object poses: the replay and the motion file show them); :meth:`GraspRig.checks` turns them
into the certificate's lines: the grasp engaged, the object lifted by the asked height and held,
placed within tolerance, held out at a hand-over point, a pushed one moved by the asked distance
(:class:`tasks.specs.Push`), no other object moved by more than :data:`MOVED_LIMIT`, none tipped over.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass
from typing import cast

import mujoco
import numpy as np
import pinocchio as pin

from planner import Check, CheckKind
from robots import Robot
from sim.model import (
    OBJECT_PREFIX,
    OBJECT_ROLE,
    ROBOT_ROLE,
    Gripper,
    SimModel,
    grasp_weld_name,
    hand_gripper,
    subtree,
)
from tasks import Grasp, Push, TaskSpec

WELD = "weld, a simplified gripper"  # how the certificate names the simplification (a hand without a closing gripper)
GRIPPER_WELD = "closed gripper, then a weld: a simplified grip"  # a gripper that closed on the object, then the weld
WELD_BOTH = "welds to both hands, a simplified two-handed squeeze"  # a box held between both hands
LIFT_TOLERANCE = 0.02  # [m] the object may hang this much lower than asked while held
PLACE_TOLERANCE = 0.03  # [m] a placed object's centre within this of where it was put
PUSH_TOLERANCE = 0.02  # [m] a pushed object ends within this of the asked distance along the push, and across it
OFFER_TOLERANCE = 0.03  # [m] a handed-over object's centre within this of the hand-over point while held out
MOVED_LIMIT = 0.01  # [m] an object no hand holds moves at most this much
TIPPED_LIMIT = 0.35  # [rad] an object tilted more than this (20 deg) is knocked over
HAND_BITS = {"left": 16, "right": 32}  # contype bits of each hand's geoms while it grasps
FINGER_BITS = {"left": 64, "right": 128}  # contype bits of the fingers that touch the object they close on
GRIP_FRACTION = 0.9  # the gripper squeezes with this fraction of its drive's effort limit
GRIP_STIFFNESS = 10.0  # [N m/rad] the drive's position servo (saturates at GRIP_FRACTION of the limit)
CLOSED_MARGIN = 0.05  # [rad] a drive this near its closed limit is closed (nothing between the fingers)
PINCH_COSINE = -0.5  # fingers pinch the object when two of their contact normals are this opposed


@dataclass
class _Held:
    grasp: Grasp
    side: str
    eq: int
    hand_body: int
    obj_index: int
    engaged_at: float | None = None
    released_at: float | None = None
    closest: float = math.inf  # [m] best distance of the object's centre to its held place
    drift: float = 0.0  # [m] farthest the object's centre got from its held place while held
    last: float = math.inf  # [m] its distance at the last tick
    gripper: Gripper | None = None  # the hand's closing gripper (None: the weld alone, as for a box in both hands)
    closing_at: float | None = None  # [s] when the gripper started to close on the object
    closed_at: float | None = None  # [s] when it held the object (pinched, or at its closed limit)
    closed_angle: float = math.nan  # [rad] the drive's angle then
    pinched: bool = False  # the fingers touch the object from opposite sides (else the drive reached its limit)
    sunk: tuple[str, ...] = ()  # fingertips already inside the object when the gripper started to close

    @property
    def how(self) -> str:
        """How the certificate names this grasp's simplification."""
        return WELD if self.gripper is None else GRIPPER_WELD


class GraspRig:
    """The spec's grasps on a copy of the MuJoCo model (its welds and contact bits) and the record
    of the movable objects over the run.

    Args:
        sm: The MuJoCo model (not modified).
        robot: The robot.
        spec: The planned spec (its scene and grasps).
        n_ticks: The most ticks the run records.
    """

    def __init__(self, sm: SimModel, robot: Robot, spec: TaskSpec, n_ticks: int) -> None:
        self.sm = sm
        self.model = copy.deepcopy(sm.model) if spec.grasps else sm.model
        m = self.model
        self.names = [o.name for o in spec.scene.objects if o.movable] if spec.scene is not None else []
        self.bodies = np.array([mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, OBJECT_PREFIX + n) for n in self.names],
                               dtype=int)
        self.held: list[_Held] = []
        self.exempt: set[tuple[int, int]] = set()  # (robot geom, object geom) pairs that may touch
        frames = {robot.frame(f"{s}_hand"): s for s in ("left", "right") if robot.has_role(f"{s}_hand")}
        for g in spec.grasps:
            side = frames.get(g.frame)
            eq = -1 if side is None else mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_EQUALITY, grasp_weld_name(side, g.object))
            if side is None or eq < 0:
                continue  # no weld for this frame: the grasp's check fails (never engaged)
            self.held.append(_Held(grasp=g, side=side, eq=eq, hand_body=int(m.eq_obj1id[eq]),
                                   obj_index=self.names.index(g.object)))
        grippers = {side: hand_gripper(sm, side) for side in {h.side for h in self.held}}
        for h in self.held:  # one hand closes its gripper; a box between both hands is squeezed by the arms
            both = any(o is not h and o.grasp.object == h.grasp.object and abs(o.grasp.start - h.grasp.start) < 1e-9
                       for o in self.held)
            h.gripper = None if both else grippers[h.side]
        self.grippers = {h.side: h.gripper for h in self.held if h.gripper is not None}
        self.angles = np.zeros((n_ticks, len(self.grippers)))  # [rad] each gripper's drive angle per tick
        self.object_geoms = np.array([mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, OBJECT_PREFIX + n)
                                      for n in self.names], dtype=int)
        self.pushes = [p for p in spec.pushes if p.object in self.names]
        self._bits(sm, robot)
        self.pos = np.zeros((n_ticks, len(self.names), 3))
        self.quat = np.zeros((n_ticks, len(self.names), 4))  # (x, y, z, w), as the robot's base in q
        self.tilt = np.zeros((n_ticks, len(self.names)))
        self.t = np.zeros(n_ticks)
        self.n = 0

    def _bits(self, sm: SimModel, robot: Robot) -> None:
        """The grasping hands' geoms collide with no object they grasp (and no longer with the floor).
        A hand is, as for the planner's scene rows, the link of its frame's joint and every body below
        it (talos: the wrist's last link, arm_*_7_link, with the gripper)."""
        m = self.model
        if not self.held:
            return
        role = sm.geom_role
        geom_body = np.asarray(m.geom_bodyid, dtype=int)
        for side in {h.side for h in self.held}:
            bit = HAND_BITS[side]
            weld = next(h.hand_body for h in self.held if h.side == side)
            joint = robot.model.frames[robot.frame_id(f"{side}_hand")].parentJoint
            link = next((f.name for f in robot.model.frames if f.parentJoint == joint and f.type == pin.FrameType.BODY), "")
            root = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, link) if link else -1
            hand = subtree(m, root if root >= 0 and weld in subtree(m, root) else weld)
            hand_geoms = [g for g in range(m.ngeom) if role[g] == ROBOT_ROLE and int(geom_body[g]) in hand]
            grasped = {h.grasp.object for h in self.held if h.side == side}
            for g in hand_geoms:
                m.geom_contype[g], m.geom_conaffinity[g] = bit, 0
            for g in np.flatnonzero(role == OBJECT_ROLE).tolist():
                name = sm.object_names[int(sm.geom_object[g])]
                if name in grasped:
                    self.exempt.update((hg, g) for hg in hand_geoms)
                else:
                    m.geom_conaffinity[g] |= bit

    def data(self) -> mujoco.MjData:
        """A fresh ``mujoco.MjData`` of the rig's model."""
        return mujoco.MjData(self.model)

    def drive(self, t: float, d: mujoco.MjData, tau: np.ndarray) -> np.ndarray:
        """The actuated torques ``tau`` (nv - 6,) [N m] with each grasping hand's gripper drive servoed:
        closed from its grasp's start to its end, open otherwise, at most :data:`GRIP_FRACTION` of the
        drive's effort limit (the controller's torque for the drive is replaced)."""
        if not self.grippers:
            return tau
        tau = np.array(tau, dtype=float)
        for gr in self.grippers.values():
            closing = any(h.gripper is gr and t >= h.grasp.start - 1e-9 and (h.grasp.end is None or t < h.grasp.end - 1e-9)
                          for h in self.held)
            target = gr.closed_angle if closing else gr.open_angle
            cap = GRIP_FRACTION * gr.effort
            tau[gr.actuated] = float(np.clip(GRIP_STIFFNESS * (target - float(d.qpos[gr.qpos])), -cap, cap))
        return tau

    def _start_closing(self, h: _Held, d: mujoco.MjData) -> None:
        """The fingertips (:attr:`sim.model.Gripper.pad_geoms`) start to touch the object; the other
        finger links (linkage, drive) stay exempt like the palm. Notes the fingertips already inside
        it (MuJoCo's distance between their convex geoms < 0): MuJoCo pushes the object off them."""
        m, gr = self.model, cast(Gripper, h.gripper)
        bit = FINGER_BITS[h.side]
        obj = int(self.object_geoms[h.obj_index])
        for g in gr.pad_geoms:
            m.geom_contype[g] |= bit
        m.geom_conaffinity[obj] |= bit
        h.sunk = tuple(sorted({m.body(int(m.geom_bodyid[g])).name for g in gr.pad_geoms
                               if mujoco.mj_geomDistance(m, d, g, obj, 0.05, None) < 0.0}))

    def _closed(self, h: _Held, d: mujoco.MjData) -> bool:
        """The gripper holds the object: its fingers touch it from opposite sides (two contact normals
        at least :data:`PINCH_COSINE` apart), or its drive is within :data:`CLOSED_MARGIN` of its
        closed limit."""
        gr = cast(Gripper, h.gripper)
        obj = int(self.object_geoms[h.obj_index])
        fingers = set(gr.pad_geoms)
        normals = []
        for c in range(d.ncon):
            g1, g2 = (int(x) for x in d.contact.geom[c])
            if (g1 in fingers and g2 == obj) or (g2 in fingers and g1 == obj):
                n = np.array(d.contact.frame[c, :3])  # from geom1 to geom2
                normals.append(n if g2 == obj else -n)  # from the finger into the object
        h.pinched = any(float(a @ b) <= PINCH_COSINE for i, a in enumerate(normals) for b in normals[i + 1:])
        return h.pinched or abs(float(d.qpos[gr.qpos]) - gr.closed_angle) <= CLOSED_MARGIN

    def poses(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Movable object -> (centre positions (T', 3) [m], orientations (T', 4) as (x, y, z, w)) so far."""
        return {name: (self.pos[: self.n, i], self.quat[: self.n, i]) for i, name in enumerate(self.names)}

    def tick(self, t: float, d: mujoco.MjData) -> None:
        """Close the grippers and engage or release the welds at time ``t`` [s], then record the objects."""
        if not self.held and not len(self.bodies):  # nothing to grasp or record (most runs): only the tick count
            if self.n < len(self.t):
                self.t[self.n] = t
                self.n += 1
            return
        for h in self.held:
            g = h.grasp
            if h.engaged_at is None and h.released_at is None:
                R = d.xmat[h.hand_body].reshape(3, 3)
                at = R @ np.asarray(g.offset) + d.xpos[h.hand_body]
                dist = float(np.linalg.norm(d.xpos[self.bodies[h.obj_index]] - at))
                if t >= g.start - 0.25:
                    h.closest = min(h.closest, dist)
                active = t >= g.start - 1e-9 and (g.end is None or t < g.end)
                if active and h.gripper is not None and h.closing_at is None:
                    self._start_closing(h, d)
                    h.closing_at = t
                closed = h.gripper is None or (active and self._closed(h, d))
                if h.gripper is not None and closed and h.closed_at is None:
                    h.closed_at, h.closed_angle = t, float(d.qpos[h.gripper.qpos])
                if active and closed and dist <= g.tolerance:
                    self._engage(h, d)
                    h.engaged_at = t
            elif h.released_at is None and g.end is not None and t >= g.end - 1e-9:
                d.eq_active[h.eq] = 0
                h.released_at = t
                if h.gripper is not None:  # the fingers open and stop touching the object
                    self.model.geom_conaffinity[int(self.object_geoms[h.obj_index])] &= ~FINGER_BITS[h.side]
            elif h.released_at is None:
                R = d.xmat[h.hand_body].reshape(3, 3)
                h.last = float(np.linalg.norm(d.xpos[self.bodies[h.obj_index]] - R @ np.asarray(g.offset)
                                              - d.xpos[h.hand_body]))
                h.drift = max(h.drift, h.last)
        i = self.n
        if i < len(self.t):
            self.t[i] = t
            self.pos[i] = d.xpos[self.bodies]
            self.quat[i] = d.xquat[self.bodies][:, [1, 2, 3, 0]]  # MuJoCo's (w, x, y, z) -> (x, y, z, w)
            zz = d.xmat[self.bodies][:, 8]
            self.tilt[i] = np.arccos(np.clip(zz, -1.0, 1.0))
            for k, gr in enumerate(self.grippers.values()):
                self.angles[i, k] = d.qpos[gr.qpos]
            self.n = i + 1

    def _engage(self, h: _Held, d: mujoco.MjData) -> None:
        m = self.model
        a, b = h.hand_body, int(self.bodies[h.obj_index])
        R1 = d.xmat[a].reshape(3, 3)
        inv, rel = np.zeros(4), np.zeros(4)
        mujoco.mju_negQuat(inv, d.xquat[a])
        mujoco.mju_mulQuat(rel, inv, d.xquat[b])
        m.eq_data[h.eq, 0:3] = 0.0  # anchor: the object's centre
        m.eq_data[h.eq, 3:6] = R1.T @ (d.xpos[b] - d.xpos[a])  # the object in the hand frame, as it is now
        m.eq_data[h.eq, 6:10] = rel
        d.eq_active[h.eq] = 1

    # -- the certificate's lines ----------------------------------------------------------------
    def checks(self) -> list[Check]:
        """The grasp lines of the certificate (none without grasps and movable objects)."""
        n = self.n
        if n == 0 or not self.names:
            return []
        t, pos, tilt = self.t[:n], self.pos[:n], self.tilt[:n]
        out: list[Check] = []
        seen: set[tuple[str, float]] = set()
        for h in self.held:
            pair = sum(1 for o in self.held if o.grasp.object == h.grasp.object and abs(o.grasp.start - h.grasp.start) < 1e-9
                       and o.grasp.end == h.grasp.end) > 1
            key = (h.grasp.object, round(h.grasp.start, 9))
            out.extend(self._grasp_checks(h, t, pos, two_hands=pair, first=key not in seen))
            seen.add(key)
        for p in self.pushes:
            out.append(self._push_check(p, t, pos))
        held = {h.obj_index for h in self.held} | {self.names.index(p.object) for p in self.pushes}
        others = [i for i in range(len(self.names)) if i not in held]
        if others:
            moved = np.linalg.norm(pos[:, others] - pos[0, others], axis=2)
            k, j = np.unravel_index(int(np.argmax(moved)), moved.shape)
            worst, name = float(moved[k, j]), self.names[others[j]]
            ok = worst <= MOVED_LIMIT
            out.append(Check(
                name=f"objects not held: none moved (most: {name})", kind=CheckKind.OBJECT_MOVED, subject=name,
                value=worst, limit=MOVED_LIMIT, unit="m", ok=ok, time=float(t[k]),
                message="" if ok else f"the {name} moved {worst * 100:.1f} cm (at most {MOVED_LIMIT * 100:g} cm)"))
        tipped = tilt.copy()
        for h in self.held:  # a held object turns with the hand; once let go it must stand
            if h.released_at is None:
                tipped[:, h.obj_index] = 0.0
            else:
                tipped[t < h.released_at + 0.5, h.obj_index] = 0.0
        k, j = np.unravel_index(int(np.argmax(tipped)), tipped.shape)
        worst, name = float(tipped[k, j]), self.names[j]
        ok = worst <= TIPPED_LIMIT
        out.append(Check(
            name="objects: none knocked over", kind=CheckKind.OBJECT_TIPPED, subject=name, value=worst,
            limit=TIPPED_LIMIT, unit="rad", ok=ok, time=float(t[k]),
            message="" if ok else f"the {name} was knocked over (tilted {math.degrees(worst):.0f} deg at t = {t[k]:.2f} s)"))
        return out

    def _grasp_checks(self, h: _Held, t: np.ndarray, pos: np.ndarray, *, two_hands: bool = False,
                      first: bool = True) -> list[Check]:
        g, name = h.grasp, h.grasp.object
        out = []
        ok = h.engaged_at is not None
        how = WELD_BOTH if two_hands else h.how
        what = how if h.gripper is None or not ok else \
            f"gripper closed at {h.closed_angle:.2f} rad{' on it' if h.pinched else ''}, then a weld: a simplified grip"
        if ok:
            message = ""
        elif h.gripper is not None and h.closed_at is None:
            angles = self.angles[:self.n, list(self.grippers).index(h.side)]
            nearest = float(angles[int(np.argmin(np.abs(angles - h.gripper.closed_angle)))]) if len(angles) else math.nan
            message = (f"the {h.side} gripper never closed on the {name}: its drive got to {nearest:.2f} rad (closed: "
                       f"{h.gripper.closed_angle:.2f} rad) and its fingers never touched the {name} from both sides")
        else:
            message = (f"the {h.side} hand never held the {name}: its grasp point came within "
                       f"{h.closest * 100:.1f} cm of it (the grasp needs {g.tolerance * 100:g} cm)")
        out.append(Check(
            name=f"grasp: {h.side} hand holds the {name} ({what})", kind=CheckKind.OBJECT_GRASP, subject=name,
            value=h.closest if math.isfinite(h.closest) else 1.0, limit=g.tolerance, unit="m", ok=ok,
            time=g.start if h.engaged_at is None else h.engaged_at, message=message))
        if not first:
            return out  # the object's own lines: once for the two hands
        z0 = float(pos[0, h.obj_index, 2])
        if g.lift > 0.0 and g.hold is not None:
            mask = (t >= g.hold[0] - 1e-9) & (t <= g.hold[1] + 1e-9)
            if mask.any():
                rise = pos[mask, h.obj_index, 2] - z0
                k = int(np.argmin(rise))
                worst = float(rise[k])
                limit = g.lift - LIFT_TOLERANCE
                ok = worst >= limit
                out.append(Check(
                    name=f"{name} lifted by {g.lift:g} m and held", kind=CheckKind.OBJECT_LIFT, subject=name,
                    value=worst, limit=limit, unit="m", ok=ok, time=float(t[mask][k]), upper=False,
                    message="" if ok else (f"the {name} rose only {worst * 100:.1f} cm while held (asked "
                                           f"{g.lift * 100:g} cm, tolerance {LIFT_TOLERANCE * 100:g} cm)")))
        if g.end is None and h.engaged_at is not None:  # held to the end: still in the hand, still up
            up = float(pos[-1, h.obj_index, 2] - z0)
            limit = g.lift - LIFT_TOLERANCE
            ok = h.drift <= g.tolerance and up >= limit
            out.append(Check(
                name=f"{name} still held at the end ({how})", kind=CheckKind.OBJECT_HELD, subject=name,
                value=h.drift, limit=g.tolerance, unit="m", ok=ok, time=float(t[-1]),
                message="" if ok else (f"the {name} left the {h.side} hand ({h.drift * 100:.1f} cm from its held place)"
                                       if h.drift > g.tolerance else
                                       f"the {name} ended only {up * 100:.1f} cm above where it stood (asked "
                                       f"{g.lift * 100:g} cm, tolerance {LIFT_TOLERANCE * 100:g} cm)")))
        if g.offer is not None and g.offer_window is not None:
            out.append(self._offer_check(h, t, pos))
        if g.place is not None:
            err = float(np.linalg.norm(pos[-1, h.obj_index] - np.asarray(g.place)))
            ok = err <= PLACE_TOLERANCE
            out.append(Check(
                name=f"{name} placed", kind=CheckKind.OBJECT_PLACE, subject=name, value=err, limit=PLACE_TOLERANCE,
                unit="m", ok=ok, time=float(t[-1]),
                message="" if ok else f"the {name} ended {err * 100:.1f} cm from where it was to be put"))
        return out


    def _push_check(self, p: Push, t: np.ndarray, pos: np.ndarray) -> Check:
        """The pushed object moved by the asked distance along the push direction (within
        :data:`PUSH_TOLERANCE`), and no more than :data:`PUSH_TOLERANCE` across it, at the end of the run."""
        i = self.names.index(p.object)
        d = pos[-1, i] - pos[0, i]
        u = np.asarray(p.direction, dtype=float)
        along = float(d @ u)
        across = float(np.linalg.norm(d[:2] - along * u[:2]))
        err = max(abs(along - p.distance), across)
        ok = err <= PUSH_TOLERANCE
        return Check(
            name=f"{p.object} pushed {along:.3f} m of the asked {p.distance:g} m", kind=CheckKind.OBJECT_PUSH,
            subject=p.object, value=err, limit=PUSH_TOLERANCE, unit="m", ok=ok, time=float(t[-1]),
            message="" if ok else (f"the {p.object} moved {along * 100:.1f} cm along the push (asked {p.distance * 100:g} cm) "
                                   f"and {across * 100:.1f} cm across it (at most {PUSH_TOLERANCE * 100:g} cm off)"))

    def _offer_check(self, h: _Held, t: np.ndarray, pos: np.ndarray) -> Check:
        """The object held out at the hand-over point: over the offer window its centre (MuJoCo body)
        stays within :data:`OFFER_TOLERANCE` of the point, and the hand holds it (the weld engaged
        before the window and not let go during it)."""
        g, name = h.grasp, h.grasp.object
        w = cast(tuple[float, float], g.offer_window)
        mask = (t >= w[0] - 1e-9) & (t <= w[1] + 1e-9)
        err = np.linalg.norm(pos[:, h.obj_index] - np.asarray(g.offer), axis=1)
        k = int(np.flatnonzero(mask)[np.argmax(err[mask])]) if mask.any() else len(t) - 1
        worst = float(err[k]) if mask.any() else math.inf
        held = h.engaged_at is not None and h.engaged_at <= w[0] and (h.released_at is None or h.released_at >= w[1])
        ok = held and worst <= OFFER_TOLERANCE
        p = cast(tuple[float, float, float], g.offer)
        return Check(
            name=f"{name} handed over: held out at ({p[0]:.2f}, {p[1]:.2f}, {p[2]:.2f}) m ({h.how})",
            kind=CheckKind.OBJECT_OFFER, subject=name, value=worst if math.isfinite(worst) else 1.0,
            limit=OFFER_TOLERANCE, unit="m", ok=ok, time=float(t[k]),
            message="" if ok else (f"the {h.side} hand did not hold the {name} while holding it out" if not held else
                                   f"the {name} was {worst * 100:.1f} cm from the hand-over point while held out "
                                   f"(at most {OFFER_TOLERANCE * 100:g} cm)"))


__all__ = ["CLOSED_MARGIN", "FINGER_BITS", "GRIPPER_WELD", "GRIP_FRACTION", "LIFT_TOLERANCE", "MOVED_LIMIT",
           "OFFER_TOLERANCE", "PLACE_TOLERANCE", "PUSH_TOLERANCE", "TIPPED_LIMIT", "WELD", "WELD_BOTH", "GraspRig"]
