"""``balance(foot, duration [s])``: stand on one foot, then put the other one down again.

Three phases: shift the weight onto the stance foot (both feet down, ``SHIFT_TIME``), stand on
one foot (``duration``; only the stance sole in contact; a HARD CoM target holds the CoM over
the stance sole's centre through the whole phase: in a dynamic plan the support-polygon bound
applies only at rest, and without the hold the CoM already left the sole by 2 cm towards the
other foot before it touched down;
the free foot ``CLEARANCE`` above the ground over the middle ``LIFTED_FRACTION`` of the phase,
HARD, tolerance ``CLEARANCE_TOLERANCE``), and shift back (both feet down, ``SHIFT_TIME``; the CoM
back over its standing point). Dynamic (contact forces and the centroidal dynamics): planned
kinematically, the shift ended with the CoM still moving, and on G1 the plan's ZMP left the
stance sole by 0.16 m as the other foot lifted (the simulated CoM stopped 5.2 cm from the sole's
centre).
"""

from __future__ import annotations

from robots import Robot
from tasks.primitives.arms import hold_upper_arms
from tasks.primitives.base import Fragment, FragmentBuilder, Primitive

SHIFT_TIME = 1.0  # [s] weight shift before and after the one-foot stance
CLEARANCE = 0.05  # [m] height of the lifted sole
CLEARANCE_TOLERANCE = 0.02  # [m]
LIFTED_FRACTION = 0.5  # middle part of the one-foot phase with the foot held up
COM_TOLERANCE = 0.01  # [m]
PARTS = frozenset({"legs", "com"})
OTHER = {"left": "right", "right": "left"}


def nominal_duration(params: dict, robot: Robot) -> float:
    """Shift, one-foot stance, shift back [s]."""
    return SHIFT_TIME + params["duration"] + SHIFT_TIME


def build(b: FragmentBuilder) -> Fragment:
    """Shift, lift, hold, put down, shift back."""
    stance, free = b.params["foot"], OTHER[b.params["foot"]]
    D = b.params["duration"]
    g = b.geometry
    sole = b.world(g.sole_centers[stance])
    b.com_target(f"CoM over the {stance} sole", (sole[0], sole[1], None), window=(SHIFT_TIME, SHIFT_TIME + D),
                 tolerance=COM_TOLERANCE)
    lift0 = SHIFT_TIME + 0.5 * (1.0 - LIFTED_FRACTION) * D
    lift1 = SHIFT_TIME + 0.5 * (1.0 + LIFTED_FRACTION) * D
    free_sole = b.world(g.position(f"{free}_foot"))
    b.frame_target(f"{free} foot lifted", f"{free}_foot",
                   position=(free_sole[0], free_sole[1], free_sole[2] + CLEARANCE), axes=(False, False, True),
                   window=(lift0, lift1), tolerance=CLEARANCE_TOLERANCE)
    home = b.world(g.com)
    b.com_target("CoM back between the feet", (home[0], home[1], None), time=nominal_duration(b.params, b.robot),
                 tolerance=COM_TOLERANCE)
    b.phase(f"shift onto the {stance} foot", SHIFT_TIME)
    b.phase(f"stand on the {stance} foot", SHIFT_TIME + D, b.contacts((stance,)), swing_height=CLEARANCE)
    b.phase("both feet down", nominal_duration(b.params, b.robot))
    hold_upper_arms(b, b.nominal, ("left", "right"))  # G1's right upper arm went into the torso's meshes
    return b.finish(PARTS, dynamic=True)


PRIMITIVE = Primitive(name="balance", nominal_duration=nominal_duration, build=build, parts=lambda p: PARTS,
                      dynamic=True)
