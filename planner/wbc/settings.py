"""Settings of the whole-body controller (:class:`WbcSettings`) and its configuration error."""

from __future__ import annotations

import math
from dataclasses import dataclass

from planner.exceptions import ControllerError


@dataclass(frozen=True, slots=True, kw_only=True)
class WbcSettings:
    """Weights, gains and solver options of the whole-body controller.

    Gains are stiffnesses [1/s^2]; each damping is :math:`2\\sqrt{K_p}` (critical).

    Attributes:
        backend: ``"proxsuite"`` (persistent dense solver, warm-started) or a ``qpsolvers``
            solver name (``"proxqp"``, ``"daqp"``, ``"quadprog"``, ``"osqp"``...).
        dt: Controller period [s]; the reference is sampled on this grid.
        com_weight, hand_weight, foot_weight, base_weight, posture_weight: Task weights [-].
            ``com_weight`` is 50, five times the swing soles' 10 and fifty times the hands' 1:
            when a push takes the centre of pressure to a sole's edge (talos's 90° turn, pushed
            20 N s outward in single support), the CoM is brought back with the whole body
            before the hands are held on their paths (53 mm off the plan with 10, 43 mm with 50).
        orientation_factor: Orientation rows of frame tasks get ``weight * orientation_factor``.
        force_weight: Regularization of corner forces [1/N^2].
        acceleration_weight: Regularization of accelerations [-].
        com_kp, frame_kp, foot_kp, base_kp, posture_kp: PD stiffnesses [1/s^2].
        contact_kp: Baumgarte stiffness on stance-sole drift [1/s^2].
        friction_scale: Fraction of the friction coefficient the controller may use [-]. 1.0 by
            default: the controller enforces the contact model of :mod:`robots.contact` (the
            pyramid inscribed in the Coulomb cone, ``|fx|, |fy| <= mu fz / sqrt(2)``),
            the same pyramid the planner plans with; below 1 shrinks that pyramid.
        cop_margin: The corner forces act this far inside the sole rectangle, which keeps the centre
            of pressure off the sole's edges [m].
        torque_scale: Fraction of each torque limit the controller may use [-]. 0.97 by
            default: the certificate flags torques above 98 % of the limit as saturation, and a
            jump's push-off uses every newton-metre the QP allows (100 % with 1.0).
        com_drift: Include the CoM velocity-product term (one extra Pinocchio call, ~7 us).
        eps_abs: QP absolute tolerance. max_iter, max_iter_in: proxsuite outer / inner iteration caps
            (they bound the cost of a failing tick).
        dense_backend: proxsuite dense factorization: ``Automatic``, ``PrimalDualLDLT`` or ``PrimalLDLT``.
        friction_compensation: Fraction of the URDF's joint damping and Coulomb friction added as a
            feed-forward torque (:mod:`planner.wbc.friction`) [-]; 0 disables. 0.8 by default: a
            light link (Talos's head, 0.0045 kg m^2 of yaw inertia against 1 N m of friction)
            otherwise never breaks its static friction, and the 20 % left unknown to the
            controller is still tested by the certificate.
        fast_path: First solve the QP without its inequalities (a reduced KKT system, see
            :mod:`planner.wbc.kernel`); when that solution meets every inequality it is the QP's
            exact solution and proxsuite is not called. Only with the ``proxsuite`` backend.
        momentum_weight: Weight of the centroidal angular-momentum task [-]: its rows are
            :math:`A_g(q)/m` (angular rows of Pinocchio's centroidal momentum matrix divided by
            the robot's mass, so that they are of the CoM rows' size), with the desired rate
            :math:`\\dot h_{ref} + K (h_{ref} - h) - \\dot A_g v`. 0 turns the task off.
        momentum_kp: Gain :math:`K` of that task on the momentum error [1/s].
        early_touchdown: In a flight of the plan (no contact), a sole that reaches its landing
            height (within 0.5 mm, not rising) after the flight's first quarter becomes a stance
            sole at once instead of at the planned touch-down, and the CoM reference brakes from
            the measured CoM from then on (:mod:`planner.wbc.controller`). G1's hopping foot
            landed ~65 ms early; as a swing foot until the planned time, then braked at once,
            it slid 12.6 mm (0.8 mm with this). The soles' references in a flight also start
            when the controller's flight does (the plan's path from the lift-off knot, replayed
            over the flight half a knot shorter): G1's 5 cm forward hop no longer falls.
        flight_foot_kp: Sole stiffness in a flight in which a landing sole travels (a forward hop;
            controller ``FLIGHT_TRAVEL``) [1/s^2]: the real flight is a third of the planned one.
        flight_momentum_weight: The angular-momentum task's weight around such a flight
            (``FLIGHT_WINDOW`` before it and after its touch-down) [-]: with ``momentum_weight``
            the waist sat at its torque cap in the push and the landing sole pitched toe-up
            (docs/control.md, "Flight soles retimed").
        flight_com_weight: The CoM task's weight around every flight (``FLIGHT_WINDOW`` before it
            and after its touch-down) [-]: G1's 5 cm jump falls at its push-off with ``com_weight``
            50 and passes with 10.
        active_set_iterations: When that solution violates friction or torque rows, this many
            active-set iterations on the same reduced system (violated rows held as equalities,
            rows with wrong-signed multipliers released) before proxsuite is called; a result is
            accepted only when the full QP's KKT conditions hold. 0 disables it.
    """

    backend: str = "proxsuite"
    dt: float = 0.001
    com_weight: float = 50.0
    hand_weight: float = 1.0
    foot_weight: float = 10.0
    base_weight: float = 1.0
    posture_weight: float = 1e-3
    orientation_factor: float = 0.1
    force_weight: float = 1e-7
    acceleration_weight: float = 1e-6
    com_kp: float = 100.0
    frame_kp: float = 400.0
    foot_kp: float = 200.0
    base_kp: float = 100.0
    posture_kp: float = 100.0
    contact_kp: float = 10.0
    friction_scale: float = 1.0
    cop_margin: float = 0.0
    torque_scale: float = 0.97
    com_drift: bool = True
    eps_abs: float = 1e-6
    max_iter: int = 50
    max_iter_in: int = 1500
    dense_backend: str = "Automatic"
    friction_compensation: float = 0.8
    fast_path: bool = True
    active_set_iterations: int = 8
    momentum_weight: float = 100.0
    momentum_kp: float = 10.0
    early_touchdown: bool = True
    flight_foot_kp: float = 800.0
    flight_momentum_weight: float = 10.0
    flight_com_weight: float = 10.0

    def __post_init__(self) -> None:
        for name in (
            "com_weight",
            "hand_weight",
            "foot_weight",
            "base_weight",
            "posture_weight",
            "orientation_factor",
            "force_weight",
            "acceleration_weight",
            "com_kp",
            "frame_kp",
            "foot_kp",
            "base_kp",
            "posture_kp",
            "contact_kp",
            "friction_compensation",
            "momentum_weight",
            "momentum_kp",
            "flight_foot_kp",
            "flight_momentum_weight",
            "flight_com_weight",
        ):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise ControllerError(
                    f"WbcSettings.{name} must be a finite number >= 0, got {value!r}"
                )
        if not (self.force_weight > 0 and self.acceleration_weight > 0):
            raise ControllerError("WbcSettings: force_weight and acceleration_weight must be > 0")
        if not 0 < self.friction_scale <= 1 or not 0 < self.torque_scale:
            raise ControllerError(
                "WbcSettings: friction_scale must be in (0, 1] and torque_scale > 0"
            )
        if not self.dt > 0:
            raise ControllerError(f"WbcSettings.dt must be > 0 s, got {self.dt!r}")
