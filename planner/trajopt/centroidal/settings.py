"""Weights and options of the centroidal terms (:class:`CentroidalSettings`)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True, slots=True, kw_only=True)
class CentroidalSettings:
    """Weights and options of the centroidal terms.

    Attributes:
        force_weight: Cost on the squared weight-normalized corner forces (spreads the load over
            the corners, centres the CoP) [-].
        angular_momentum_weight: Cost on :math:`|\\dot L / (m g)|^2` [1/m^2].
        inner_pyramid: Use the contact model's pyramid (:mod:`robots.contact`: inscribed in the
            Coulomb cone, :math:`\\mu/\\sqrt 2` per axis). False: the outer pyramid (:math:`\\mu`
            per axis), an experiment outside the model that the controller does not share.
        friction_edges: Parametrize each point force by non-negative weights on the 4 edges of
            its friction pyramid (:func:`pyramid_edges`; friction and unilaterality become
            variable bounds, no constraint rows). Off: 3 force components per point and 5
            pyramid rows (:func:`friction_pyramid`).
        whole_body_momentum: Euler's law for the whole body: the rate of the centroidal angular
            momentum :math:`A_g(q) v` (Pinocchio's centroidal momentum matrix) equals the moment
            of the contact forces about the CoM, as constraint rows linearized about an iterate
            (:mod:`planner.trajopt.centroidal.momentum`). Off: only the moment of the forces is
            penalized (``angular_momentum_weight``), the older centroidal-only model.
        lifted_moment: With ``whole_body_momentum`` and a positive ``angular_momentum_weight``, the
            moment of the contact forces about the CoM at each dynamics knot, :math:`\\dot L_k`, is
            3 NLP variables (units m x body weights) with 3 rows :math:`\\dot L_k = \\sum_i (p_i - c_k)
            \\times f_i`, and the momentum rows read :math:`\\dot h_k = \\dot L_k`: the cost
            :math:`|\\dot L_k|^2` is then diagonal in them, instead of a dense rank-3 block over the
            knot's 32 edge weights and its CoM (the same optimum; Talos 4 steps: Hessian 107 k ->
            81 k nonzeros, serialized solver 137 -> 88 MB, 19 -> 18 iterations; docs/performance.md).
            Off: the cost on the forces' moment itself, as before.
        momentum_iterations: Re-linearizations of those rows at most: after a solve whose
            Euler residual with the exact :math:`A_g` exceeds ``momentum_tolerance``, the rows
            are linearized again at the solution and the NLP is solved again from it [-].
        momentum_tolerance: That residual divided by the body weight (a CoP shift) [m]. 5 mm,
            the CoP margin (``cop_margin``): the planned CoP keeps that far inside the soles, so
            a residual within it keeps the full-dynamics ZMP in them (3 mm before: the G1 walks
            and side steps, 4.3-4.7 mm after the first solve, were solved twice; without the
            re-solve their ZMP stays in the soles and the MuJoCo certificate passes).
        zmp_tolerance: Accepted distance of the plan's full-dynamics ZMP (recomputed with
            Pinocchio's RNEA on the planned motion) outside the support polygon of the contacts
            it holds [m].
        cop_margin: Inward margin of the sole rectangle for the CoP [m].
        ankle_torque_margin: Per stance sole and knot, the moment of the sole's corner forces about
            each ankle joint axis (:func:`~planner.trajopt.centroidal.contacts.ankle_axes`: pitch
            and roll, found from the kinematic chain) stays within this fraction of the joint's
            effort limit (2 linear rows per sole and knot; the foot's own inertia neglected). The
            sole rectangle alone let G1 plans put a foot's whole load on the toe, 0.12 m ahead of
            an ankle that gives 0.107 x its weight; with Talos's stronger ankles the rows do not
            bind. None: no such rows [-].
        torque_joints: One-dof joints (names) whose torques the plan keeps within ``torque_margin``
            of their limits (:mod:`planner.trajopt.centroidal.torque`): rows of the gravity torque
            plus the rest of RNEA frozen at the last solution, added only after a solve whose
            RNEA torques exceed the margin. For joints no contact force passes through (arms):
            the rows do not count the contact forces. Empty (the default): no rows.
        torque_margin: That fraction of each joint's effort limit [-].
        torque_trigger: The rows come only after a solve whose RNEA torque of one of those joints
            exceeds this fraction of its limit (1.0: a plan asking more than the actuator gives;
            once there, they are re-linearized while it exceeds ``torque_margin + 0.02``) [-].
        torque_rounds: Solves with the rows re-linearized at most (after the solve that added
            them, each re-solve freezes the RNEA rest again) [-].
        max_force: Upper bound of one corner's normal force, in body weights [-].
        force_tolerance: Accepted violation of the force checks in the report, as a fraction of
            the body weight [-].
        ipopt_options: IPOPT options of dynamic plans, ``(name, value)`` pairs. Zero initial
            constraint multipliers (``constr_mult_init_max 0``: IPOPT's least-squares estimate
            made the first Hessians indefinite, and each inertia correction costs a
            factorization) and a first Hessian perturbation of 10 (instead of 1e-4, raised 100x
            per try) cut the 4-step Talos solve from 26 to ~19 factorizations. IPOPT's warm start
            (``warm_start_init_point``): the re-solve after a re-linearization of the momentum
            rows starts from the solution *and its multipliers* (:func:`planner.trajopt.api.plan`),
            7 iterations instead of 12-18; a first solve gets zero multipliers, as before (the
            bound multipliers start at 1e-3 instead of 1: 17-20 iterations as before, +-1). The
            barrier parameter stops at 1e-9 (``mu_min``; IPOPT's default 1e-11): below it the
            kitchen pick-up's solves spent 10-14 iterations each on short steps at an objective
            already converged to 8 digits (58 -> 49 iterations in its first solve; the solution
            within 1e-8 of the objective).
        tracking_guess: Start a spec that tracks a motion (a soft frame target at most knots: a
            retarget) from each knot's pose for its own targets, and linearize the momentum rows
            about it (:mod:`planner.trajopt.centroidal.tracking`), instead of the heading guess
            (the joints at standing). g1's squat: 74 + 32 iterations in two solves -> 27 + 46.
    """

    force_weight: float = 1e-2
    angular_momentum_weight: float = 1.0
    inner_pyramid: bool = True
    friction_edges: bool = True
    whole_body_momentum: bool = True
    lifted_moment: bool = True
    momentum_iterations: int = 1
    momentum_tolerance: float = 0.005
    zmp_tolerance: float = 0.01
    cop_margin: float = 0.005
    ankle_torque_margin: float | None = 0.9
    torque_joints: tuple[str, ...] = ()
    torque_margin: float = 0.85
    torque_trigger: float = 1.0
    torque_rounds: int = 3
    max_force: float = 10.0
    force_tolerance: float = 1e-3
    ipopt_options: tuple[tuple[str, float | int | str], ...] = (
        ("constr_mult_init_max", 0.0), ("first_hessian_perturbation", 10.0), ("warm_start_init_point", "yes"),
        ("mu_min", 1e-9))
    tracking_guess: bool = False

    @property
    def lifts_moment(self) -> bool:
        """The forces' moment is lifted to variables (:attr:`lifted_moment` applies)."""
        return self.lifted_moment and self.whole_body_momentum and self.angular_momentum_weight > 0.0
