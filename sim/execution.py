"""The result of a closed-loop simulation."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from sim.certificate import Certificate

if TYPE_CHECKING:
    from sim.estop import Stop
    from sim.faults import Faults


@dataclass(frozen=True, slots=True)
class Event:
    """Something that happened during the simulation.

    Attributes:
        time: When [s].
        kind: ``push``, ``qp_failure``, ``unplanned_contact``, ``fall``, ``torque_limit``, ``stopped``,
            ``estop`` (the E-stop fired: :mod:`sim.estop`).
        message: Details in words.
    """

    time: float
    kind: str
    message: str

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly dict (:meth:`from_dict` reads it back)."""
        return {"time": float(self.time), "kind": self.kind, "message": self.message}

    @classmethod
    def from_dict(cls, record: Any) -> Event | None:
        """The event of :meth:`to_dict`'s dict, or None when ``record`` is not one."""
        if not isinstance(record, dict):
            return None
        time, kind, message = record.get("time"), record.get("kind"), record.get("message")
        if isinstance(time, bool) or not isinstance(time, (int, float)) or not isinstance(kind, str) \
                or not isinstance(message, str):
            return None
        return cls(float(time), kind, message)


@dataclass(frozen=True, eq=False, kw_only=True)
class Execution:
    """A simulated motion: a fresh run (:func:`sim.simulate`) or one read back from a motion file.

    The motion file (``docs/formats.md``) keeps ``t``, ``q``, ``v``, ``tau``, the objects' poses,
    the events and the certificate; the other fields are the run's own and keep their empty
    defaults in an execution read from a file (``wbmp.motionfile`` converts both ways, exactly).

    Attributes:
        t: Sample times (T',) [s], one per controller tick.
        q: Configurations (T', nq), Pinocchio order, quaternion (x, y, z, w).
        v: Velocities (T', nv), Pinocchio convention.
        tau: Applied actuated torques (T', nv - 6) [N m], or None (a motion file without them).
        certificate: The verdict with its checks, or None (a motion file that records none).
        com: Centre of mass (T', 3) [m]; (0, 3) when read from a motion file.
        contact_forces: Contact frame -> net floor force on that sole in the world (T', 3) [N];
            empty when read from a motion file.
        events: What happened, in time order.
        wall_time: Wall-clock time of the loop [s].
        realtime_factor: Simulated time / wall time [-].
        tick_times: Controller tick durations [s] (T',).
        timestep: MuJoCo timestep [s].
        joint_names: Actuated joint names, the column order of ``tau``.
        torque_limits: Their torque limits (nv - 6,) [N m].
        objects: Movable scene object -> its centre's position over the run (T', 3) [m] (MuJoCo).
        object_orientations: Movable scene object -> its orientation over the run (T', 4), a unit
            quaternion (x, y, z, w) as the free flyer's in ``q`` (MuJoCo).
        stops: The E-stops of the run (:class:`sim.estop.Stop`).
        faults: The faults the run was put through (:class:`sim.faults.Faults`), or None.
    """

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    tau: np.ndarray | None
    certificate: Certificate | None
    com: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    contact_forces: Mapping[str, np.ndarray] = field(default_factory=dict)
    events: tuple[Event, ...] = ()
    wall_time: float = 0.0
    realtime_factor: float = 0.0
    tick_times: np.ndarray = field(default_factory=lambda: np.zeros(0))
    timestep: float = 0.001
    joint_names: tuple[str, ...] = ()
    torque_limits: np.ndarray = field(default_factory=lambda: np.zeros(0))
    objects: Mapping[str, np.ndarray] = field(default_factory=dict)
    object_orientations: Mapping[str, np.ndarray] = field(default_factory=dict)
    stops: tuple[Stop, ...] = ()
    faults: Faults | None = None

    @property
    def figures(self) -> Mapping[str, float]:
        """The evaluation figures (docs/safety.md), as in the certificate (empty without one)."""
        return {} if self.certificate is None else self.certificate.figures

    def object_poses(self) -> dict[str, np.ndarray]:
        """Movable scene object -> its pose over the run (T', 7): the centre [m] then the unit
        quaternion (x, y, z, w) (identity when ``object_orientations`` lacks the object).

        Raises:
            ValueError: an object's positions or orientations do not have one row per sample.
        """
        n = len(self.t)
        out = {}
        for name, p in self.objects.items():
            turn = self.object_orientations.get(name)
            position = np.asarray(p, dtype=float)
            quat = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1)) if turn is None else np.asarray(turn, dtype=float)
            if position.shape != (n, 3) or quat.shape != (n, 4):
                raise ValueError(f"the {name}'s poses must have {n} rows, got {position.shape} and {quat.shape}")
            out[name] = np.hstack([position, quat])
        return out

    def peak_torque_fractions(self) -> dict[str, float]:
        """Peak |tau| / limit of each actuated joint over the run [-], in joint order."""
        if self.tau is None or not len(self.tau) or not len(self.torque_limits):
            return {}
        usable = (self.torque_limits > 0) & np.isfinite(self.torque_limits)
        safe = np.where(usable, self.torque_limits, 1.0)
        peaks = np.where(usable, np.abs(self.tau).max(axis=0) / safe, 0.0)
        return {name: float(p) for name, p in zip(self.joint_names, peaks, strict=True)}

    @property
    def ok(self) -> bool:
        """The certificate passed (False without a certificate)."""
        return self.certificate is not None and self.certificate.ok

    def summary(self) -> str:
        """The certificate table plus timing."""
        tick = 1e6 * float(np.median(self.tick_times)) if len(self.tick_times) else float("nan")
        return (
            f"simulated {self.t[-1]:.2f} s in {self.wall_time:.2f} s ({self.realtime_factor:.1f}x real time, "
            f"controller tick median {tick:.0f} us)\n"
            + ("certificate: none recorded" if self.certificate is None else self.certificate.summary())
        )
