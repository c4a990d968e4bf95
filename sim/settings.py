"""Options of the simulation and of its certificate."""

from __future__ import annotations

from dataclasses import dataclass, field

from planner import WbcSettings
from sim.exceptions import SimError


@dataclass(frozen=True, slots=True, kw_only=True)
class SimSettings:
    """Simulation and certificate options.

    Attributes:
        timestep: MuJoCo step [s]; the controller runs every ``control_every`` steps.
        control_every: Steps per controller tick (1 = controller at the physics rate).
        settle_time: Simulated time after the plan's end [s].
        joint_friction: Keep the URDF joint damping and friction in MuJoCo.
        wbc: Controller settings (its ``dt`` is set to ``timestep * control_every``).
        fall_height_margin: A fall is the base this far below its lowest planned height [m].
        max_tilt: A fall is the base tilted this much more than planned [rad].
        slip_limit: Largest horizontal sole displacement during a stance [m].
        placement_limit: Largest horizontal distance of a stance sole from the plan's [m].
        torque_fraction_limit: Largest |tau| / limit [-].
        com_error_limit: Largest CoM tracking error [m].
        hand_error_limit: Largest hand tracking error [m].
        target_margin: Execution tolerance added to each spec target's tolerance [m].
        qp_failure_limit: Largest fraction of controller ticks whose QP failed [-].
        stop_after_fall: Simulated time kept after a fall before stopping [s].
        stop_after_qp_failure: Stop when the controller QP has failed on every tick for this long [s].
        self_penetration_limit: Deepest accepted penetration of two links of the collision model
            into each other [m] (MuJoCo's contact depth, confirmed on the URDF meshes by coal).
        self_contact_force_limit: Largest accepted normal force between two links of the
            collision model [N] (MuJoCo resists penetration: a plan through the body shows as
            links pressed together, confirmed on the URDF meshes by coal).
        collision_sample_period: How often the closest distances (self and scene) are measured
            for the certificate [s]; penetrations are seen at every controller tick.
        self_distance_horizon: Self distances beyond this are not measured [m] (the line then
            reports "> horizon").
        scene_distance_horizon: Robot-object distances beyond this are not measured [m].
        floor_timeconst: Time constant of the floor's and the soles' contact (MuJoCo ``solref``
            ``(timeconst, 1)``: critically damped) [s]; None keeps MuJoCo's default (0.02 s).
            Stiffer is a harder floor: a loaded sole sinks and creeps less (talos's squat:
            3.3 mm deep and 13.8 mm of stance slip with 0.02 s, 0.4 and 3.1 mm with 0.005 s;
            docs/retarget.md). At least two timesteps (MuJoCo's stability rule).
    """

    timestep: float = 0.001
    control_every: int = 1
    settle_time: float = 0.5
    joint_friction: bool = True
    wbc: WbcSettings = field(default_factory=WbcSettings)
    fall_height_margin: float = 0.25
    max_tilt: float = 0.6
    slip_limit: float = 0.01
    placement_limit: float = 0.02
    torque_fraction_limit: float = 0.98
    com_error_limit: float = 0.05
    hand_error_limit: float = 0.05
    target_margin: float = 0.03
    qp_failure_limit: float = 0.01
    stop_after_fall: float = 0.3
    stop_after_qp_failure: float = 0.5
    self_penetration_limit: float = 0.005
    self_contact_force_limit: float = 10.0
    collision_sample_period: float = 0.02
    self_distance_horizon: float = 0.1
    scene_distance_horizon: float = 5.0
    floor_timeconst: float | None = None

    def __post_init__(self) -> None:
        if not (self.timestep > 0 and self.control_every >= 1 and self.settle_time >= 0):
            raise SimError(
                "SimSettings: timestep must be > 0, control_every >= 1, settle_time >= 0"
            )
        if self.floor_timeconst is not None and not self.floor_timeconst >= 2 * self.timestep:
            raise SimError(
                f"SimSettings: floor_timeconst must be at least two timesteps ({2 * self.timestep:g} s), "
                f"got {self.floor_timeconst!r}"
            )
        if not (self.self_penetration_limit >= 0 and self.self_contact_force_limit >= 0
                and self.collision_sample_period > 0
                and self.self_distance_horizon > 0 and self.scene_distance_horizon > 0):
            raise SimError(
                "SimSettings: self_penetration_limit and self_contact_force_limit must be >= 0 and "
                "collision_sample_period, "
                "self_distance_horizon, scene_distance_horizon > 0"
            )

