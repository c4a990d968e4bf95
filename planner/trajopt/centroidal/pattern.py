r"""Centroidal dynamics with contact forces, as CasADi expressions the trajectory NLP adds per knot.

A kinematic plan keeps the centre of mass over the support polygon. A dynamic plan (walking
faster than quasi-statically, jumping) instead lets the contact forces carry the body: at every
knot :math:`k` with a known centre of mass :math:`c_k` (the symbolic CoM of the configuration,
or a CoM state)

.. math::

    m\,(\ddot c_k - g) = \sum_i f_{k,i}, \qquad
    \ddot c_k \approx \frac{c_{k+1} - 2 c_k + c_{k-1}}{\Delta t^2},

where the :math:`f_{k,i}` are 3D forces in the world frame at the corners :math:`p_i` of each
active sole (one point for a point contact). Each corner force lies in a friction pyramid of the
contact frame (normal :math:`n`, tangents :math:`t_1, t_2`):

.. math::

    n^\top f \ge 0, \qquad |t_j^\top f| \le \mu' \, n^\top f, \quad
    \mu' = \mu / \sqrt 2 \text{ (inner pyramid) or } \mu,

so the resultant of one foot's corner forces is a non-negative combination of points of the
sole: the centre of pressure stays inside the sole rectangle without a separate constraint.
By default each corner force is written as :math:`f = E\,\lambda`, a combination of the 4
edges :math:`E` of its pyramid with weights :math:`\lambda \ge 0` (:func:`pyramid_edges`):
the pyramid is then a variable bound and adds no constraint row.
An inactive contact has no force variables at all (forces are zero in flight). The rate of
angular momentum about the CoM that these forces imply,

.. math::

    \dot L_k = \sum_i (p_i - c_k) \times f_{k,i},

is penalized in the cost (the kinematic model does not track the whole-body angular momentum;
keeping its rate small keeps the forces consistent with a body that does not spin).

Scaling: the decision variables are the forces divided by the body weight :math:`m\,|g|`
(dimensionless, ~1 in total when standing) and the dynamics residual is divided by
:math:`m\,|g|` too, which keeps IPOPT's Jacobian entries near one.

Functions here work on CasADi ``SX``/``MX`` (and numpy where stated); :func:`build_centroidal`
assembles them over a knot grid into a :class:`CentroidalTerms` record that the NLP builder
concatenates to its own variables, constraints and cost. Numeric checks on a finished plan
(:func:`friction_violation`, :func:`center_of_pressure`, :func:`cop_violation`) use numpy.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np
import pinocchio as pin

from planner.exceptions import PlannerError
from planner.plan import ConstraintCheck
from robots.model import Robot
from tasks.specs import Contact, Pose, TaskSpec

GRAVITY = np.array([0.0, 0.0, -9.81])  # [m/s^2], world frame (z up)
DYNAMIC_FORMULATION = "lifted-com-2"  # part of a dynamic layout's structure (solver cache key)


# ---------------------------------------------------------------------------------------------
# Contact geometry
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True, kw_only=True)
class ContactGeometry:
    """A contact bound to a robot: where its force points are and how its cone is oriented.

    Attributes:
        frame: Pinocchio frame name of the contact (the key of ``Plan.forces``).
        rotation: Contact frame orientation in the world (3, 3); column 2 is the normal.
        position: Contact frame origin in the world (3,) [m].
        points_in_world: Force application points (n, 3) [m]: the sole corners (n = 4) of a
            foot, the frame origin (n = 1) of a point contact.
        points_in_frame: The same points in the contact frame (n, 3) [m].
        friction_coefficient: Coulomb friction coefficient [-].
    """

    frame: str
    rotation: np.ndarray
    position: np.ndarray
    points_in_world: np.ndarray
    points_in_frame: np.ndarray
    friction_coefficient: float

    @property
    def n_points(self) -> int:
        """Number of force points (4 for a sole, 1 for a point contact)."""
        return int(self.points_in_world.shape[0])

    @property
    def normal(self) -> np.ndarray:
        """Contact normal in the world (3,)."""
        return self.rotation[:, 2]


def contact_geometry(contact: Contact, robot: Robot, *, cop_margin: float = 0.0) -> ContactGeometry:
    """Bind a spec :class:`~tasks.specs.Contact` to ``robot``: frame name, corners, friction.

    A foot frame (the robot's ``left_foot``/``right_foot``) gets the four corners of the profile's
    sole rectangle (mirrored for the right foot), moved inward by ``cop_margin``; any other frame
    is a point contact at its origin.

    Args:
        contact: The spec contact (frame by name or role, placement, optional friction).
        robot: The robot it applies to.
        cop_margin: Inward margin of the sole rectangle that the centre of pressure keeps [m].

    Returns:
        The bound geometry.

    Raises:
        PlannerError: ``cop_margin`` leaves no sole area.
        robots.exceptions.FrameNotFound: the frame does not exist on the robot.
    """
    fid = robot.frame_id(contact.frame)
    frame = robot.model.frames[fid].name
    rotation = pin.rpy.rpyToMatrix(*contact.placement.rpy)
    position = np.asarray(contact.placement.position, dtype=float)
    side = robot.foot_side(frame)
    if side is None:
        local = np.zeros((1, 3))
    else:
        sole = robot.profile.sole
        if 2 * cop_margin >= min(sole.x_max - sole.x_min, sole.y_max - sole.y_min):
            raise PlannerError(
                f"CoP margin {cop_margin:g} m leaves no area of {robot.name}'s "
                f"{sole.x_max - sole.x_min:.3f} x {sole.y_max - sole.y_min:.3f} m sole"
            )
        corners = np.array(sole.corners(side), dtype=float)
        centre = corners.mean(axis=0)
        shrunk = centre + (corners - centre) * (
            1.0 - 2.0 * cop_margin / np.array([sole.x_max - sole.x_min, sole.y_max - sole.y_min])
        )
        local = np.column_stack([shrunk, np.zeros(4)])
    mu = contact.friction_coefficient or robot.profile.friction_coefficient
    return ContactGeometry(
        frame=frame,
        rotation=rotation,
        position=position,
        points_in_world=local @ rotation.T + position,
        points_in_frame=local,
        friction_coefficient=float(mu),
    )


# ---------------------------------------------------------------------------------------------
# Per-knot expressions (CasADi; numpy inputs work too where noted)
# ---------------------------------------------------------------------------------------------


def com_acceleration(c_prev: Any, c: Any, c_next: Any, dt: float) -> Any:
    """Central finite-difference CoM acceleration :math:`(c_{k+1} - 2c_k + c_{k-1})/\\Delta t^2`.

    Args:
        c_prev, c, c_next: CoM at knots k-1, k, k+1 (3,) [m] (CasADi or numpy).
        dt: Knot spacing [s].

    Returns:
        The acceleration (3,) [m/s^2], same type as the inputs.
    """
    return (c_next - 2 * c + c_prev) / (dt * dt)


def com_dynamics_residual(mass: float, com_acc: Any, total_force: Any, gravity: np.ndarray = GRAVITY) -> Any:
    """Newton's law for the centre of mass: :math:`m(\\ddot c - g) - \\sum f` (zero when met) [N].

    Args:
        mass: Total mass [kg].
        com_acc: CoM acceleration (3,) [m/s^2].
        total_force: Sum of the contact forces (3,) in the world [N].
        gravity: Gravity (3,) [m/s^2].

    Returns:
        The residual (3,) [N].
    """
    return mass * (com_acc - gravity) - total_force


def _casadi(x: Any) -> Any:
    return x if isinstance(x, (ca.SX, ca.MX, ca.DM)) else ca.DM(np.asarray(x, dtype=float))


def friction_pyramid(force: Any, rotation: Any, mu: Any, *, inner: bool = True) -> Any:
    """Friction-pyramid rows of one force; every entry must be >= 0 [N].

    Rows: :math:`n^\\top f`, :math:`\\mu' n^\\top f - t_1^\\top f`, :math:`\\mu' n^\\top f + t_1^\\top f`,
    :math:`\\mu' n^\\top f - t_2^\\top f`, :math:`\\mu' n^\\top f + t_2^\\top f`, with
    :math:`\\mu' = \\mu/\\sqrt 2` for the inner pyramid (inside the Coulomb cone) and :math:`\\mu`
    for the outer one.

    Args:
        force: Force (3,) in the world [N] (CasADi or numpy).
        rotation: Contact frame in the world (3, 3), columns t1, t2, n (numpy or CasADi).
        mu: Friction coefficient [-] (number or CasADi).
        inner: Use the inner pyramid (conservative).

    Returns:
        The 5 rows (CasADi column).
    """
    mu_p = mu / math.sqrt(2.0) if inner else mu
    local = ca.mtimes(_casadi(rotation).T, _casadi(force))
    fn = local[2]
    return ca.vertcat(fn, mu_p * fn - local[0], mu_p * fn + local[0], mu_p * fn - local[1], mu_p * fn + local[1])


def pyramid_edges(rotation: Any, mu: Any, *, inner: bool = True) -> Any:
    """The 4 edges of a friction pyramid in the world, as the columns of a (3, 4) matrix.

    In the contact frame the edges are :math:`(\\pm\\mu', \\pm\\mu', 1)` (the corners of the square
    :math:`|f_x|, |f_y| \\le \\mu' f_z` at unit normal force), so the non-negative combinations
    :math:`f = E \\lambda, \\lambda \\ge 0` are exactly the pyramid of :func:`friction_pyramid`.
    With :math:`\\mu' = \\mu/\\sqrt 2` (inner) every edge lies on the Coulomb cone.

    Args:
        rotation: Contact frame in the world (3, 3), columns t1, t2, n (numpy or CasADi).
        mu: Friction coefficient [-] (number or CasADi).
        inner: Use the inner pyramid (conservative).

    Returns:
        The edges (3, 4): numpy when ``rotation`` and ``mu`` are numbers, else CasADi.
    """
    mu_p = mu / math.sqrt(2.0) if inner else mu
    if isinstance(rotation, (ca.SX, ca.MX)) or isinstance(mu, (ca.SX, ca.MX)):
        local = ca.vertcat(ca.horzcat(mu_p, -mu_p, -mu_p, mu_p), ca.horzcat(mu_p, mu_p, -mu_p, -mu_p),
                           ca.DM.ones(1, 4))
        return ca.mtimes(_casadi(rotation), local)
    mu_p = float(mu_p)
    local = np.array([[mu_p, -mu_p, -mu_p, mu_p], [mu_p, mu_p, -mu_p, -mu_p], [1.0, 1.0, 1.0, 1.0]])
    return np.asarray(rotation, dtype=float) @ local


def angular_momentum_rate(com: Any, points: np.ndarray, forces: Sequence[Any]) -> Any:
    """Rate of angular momentum about the CoM implied by point forces, :math:`\\sum (p_i - c) \\times f_i`.

    Args:
        com: CoM (3,) [m] (CasADi).
        points: n application points (3,) in the world [m] (numpy rows or CasADi).
        forces: n forces (3,) in the world [N] (CasADi).

    Returns:
        :math:`\\dot L` (3,) [N m].
    """
    total = ca.DM.zeros(3)
    for p, f in zip(points, forces, strict=True):
        total = total + ca.cross(_casadi(p) - com, f)
    return total


# ---------------------------------------------------------------------------------------------
# Assembly over a knot grid
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True, kw_only=True)
class CentroidalSettings:
    """Weights and options of the centroidal terms.

    Attributes:
        force_weight: Cost on the squared weight-normalized corner forces (spreads the load over
            the corners, centres the CoP) [-].
        angular_momentum_weight: Cost on :math:`|\\dot L / (m g)|^2` [1/m^2].
        inner_pyramid: Use the inner friction pyramid (:math:`\\mu/\\sqrt 2`).
        friction_edges: Parametrize each point force by non-negative weights on the 4 edges of
            its friction pyramid (:func:`pyramid_edges`; friction and unilaterality become
            variable bounds, no constraint rows). Off: 3 force components per point and 5
            pyramid rows (:func:`friction_pyramid`).
        cop_margin: Inward margin of the sole rectangle for the CoP [m].
        max_force: Upper bound of one corner's normal force, in body weights [-].
        force_tolerance: Accepted violation of the force checks in the report, as a fraction of
            the body weight [-].
        ipopt_options: IPOPT options of dynamic plans, ``(name, value)`` pairs. Zero initial
            constraint multipliers (``constr_mult_init_max 0``: IPOPT's least-squares estimate
            made the first Hessians indefinite, and each inertia correction costs a
            factorization) and a first Hessian perturbation of 10 (instead of 1e-4, raised 100x
            per try) cut the 4-step Talos solve from 26 to ~19 factorizations.
    """

    force_weight: float = 1e-2
    angular_momentum_weight: float = 1.0
    inner_pyramid: bool = True
    friction_edges: bool = True
    cop_margin: float = 0.005
    max_force: float = 10.0
    force_tolerance: float = 1e-3
    ipopt_options: tuple[tuple[str, float | int | str], ...] = (
        ("constr_mult_init_max", 0.0), ("first_hessian_perturbation", 10.0))


@dataclass(frozen=True, slots=True, kw_only=True)
class ConstraintBlock:
    """One named group of constraint rows ``lower <= expr <= upper``.

    Attributes:
        name: Group name for reports ("CoM dynamics", "friction left_sole_link").
        knot: Knot index the rows belong to.
        expr: CasADi column.
        lower, upper: Bounds (same length as ``expr``).
    """

    name: str
    knot: int
    expr: Any
    lower: np.ndarray
    upper: np.ndarray


@dataclass(frozen=True, slots=True, kw_only=True)
class CentroidalTerms:
    """Everything the NLP needs to add for CoM dynamics with contact forces.

    The force variables are normalized by the body weight. With friction edges (the default,
    :attr:`CentroidalSettings.friction_edges`) each point force is ``f = weight * E u_p`` with
    ``E`` the (3, 4) pyramid edges and ``u_p >= 0`` its 4 weights; otherwise ``f = weight *
    u_p`` (3 components). The contact geometry (corner points, orientation, friction) enters as
    NLP *parameters*, so that one built solver serves every placement with the same contact
    pattern (:attr:`structure`).

    Attributes:
        variables: All force variables ``u`` (column, length n).
        lower, upper, initial: Bounds and initial guess of ``variables`` (n,).
        parameters: Parameter symbols (column) of the contact geometry.
        parameter_values: Their values (same length).
        constraints: Constraint groups (dynamics; friction rows without friction edges).
        cost: Scalar cost (force regularization + angular momentum rate).
        weight: Body weight :math:`m|g|` [N] (to turn ``u`` into newtons).
        contacts: Per knot, the active contacts' geometry.
        force_index: Per knot, frame -> indices (n_points, b) into ``variables`` (b = 4 edge
            weights, or 3 components).
        generators: Per knot, frame -> (3, b) matrix from one point's variables to its world
            force in body weights (the pyramid edges, or the identity).
        frames: Every contact frame, in order of first activity.
        dynamics_knots: Knots that carry the dynamics equation.
        structure: Hashable description of the NLP graph these terms add (no numbers).
    """

    variables: Any
    lower: np.ndarray
    upper: np.ndarray
    initial: np.ndarray
    parameters: Any
    parameter_values: np.ndarray
    constraints: tuple[ConstraintBlock, ...]
    cost: Any
    weight: float
    contacts: tuple[tuple[ContactGeometry, ...], ...]
    force_index: tuple[Mapping[str, np.ndarray], ...]
    generators: tuple[Mapping[str, np.ndarray], ...]
    frames: tuple[str, ...]
    dynamics_knots: tuple[int, ...]
    structure: tuple

    @property
    def n_variables(self) -> int:
        """Number of force variables."""
        return int(self.lower.shape[0])

    def g(self) -> tuple[Any, np.ndarray, np.ndarray]:
        """All constraint rows stacked: (expr, lower, upper)."""
        if not self.constraints:
            return ca.DM.zeros(0, 1), np.zeros(0), np.zeros(0)
        return (
            ca.vertcat(*[b.expr for b in self.constraints]),
            np.concatenate([b.lower for b in self.constraints]),
            np.concatenate([b.upper for b in self.constraints]),
        )

    def corner_forces(self, values: np.ndarray) -> dict[str, np.ndarray]:
        """Corner forces per frame from a solution ``values`` of :attr:`variables` [N].

        Returns:
            frame -> (T, n_points, 3) world forces, zero at knots where the contact is inactive
            (and at the first and last knot, which carry no dynamics).
        """
        values = np.asarray(values, dtype=float).reshape(-1)
        T = len(self.force_index)
        out: dict[str, np.ndarray] = {}
        for k, index in enumerate(self.force_index):
            for frame, idx in index.items():
                if frame not in out:
                    out[frame] = np.zeros((T, idx.shape[0], 3))
                out[frame][k] = (values[idx] @ self.generators[k][frame].T) * self.weight
        for frame in self.frames:
            out.setdefault(frame, np.zeros((T, 1, 3)))
        return out

    def forces(self, values: np.ndarray) -> dict[str, np.ndarray]:
        """Total force per contact frame (T, 3) in the world [N] (the sum over its corners)."""
        return {f: c.sum(axis=1) for f, c in self.corner_forces(values).items()}


def contacts_per_knot(spec: TaskSpec, robot: Robot, t: Sequence[float], *, cop_margin: float = 0.0) -> tuple[tuple[ContactGeometry, ...], ...]:
    """Active contacts of ``spec`` at each knot time (the later phase at a phase boundary).

    Args:
        spec: The task.
        robot: The robot.
        t: Knot times [s].
        cop_margin: Inward sole margin [m].

    Returns:
        One tuple of bound contacts per knot.
    """
    bound = [tuple(contact_geometry(c, robot, cop_margin=cop_margin) for c in p.contacts) for p in spec.phases]
    return tuple(bound[spec.phase_at(float(tk))] for tk in t)


def _geometry_values(c: ContactGeometry) -> np.ndarray:
    return np.concatenate([c.points_in_world.ravel(), c.rotation.ravel(order="F"), [c.friction_coefficient]])


@dataclass(frozen=True, slots=True, kw_only=True)
class CentroidalPattern:
    """The numbers of :func:`build_centroidal` without any CasADi expression (cheap to make).

    Same variable and row order as the terms; what a cached solver needs for a solve.

    Attributes:
        lower, upper, initial: Bounds and initial guess of the force variables (n,).
        parameter_values: Contact geometry values.
        lbg, ubg: Bounds of the centroidal rows.
        weight, contacts, force_index, generators, frames, dynamics_knots, structure: As in
            :class:`CentroidalTerms`.
    """

    lower: np.ndarray
    upper: np.ndarray
    initial: np.ndarray
    parameter_values: np.ndarray
    lbg: np.ndarray
    ubg: np.ndarray
    weight: float
    contacts: tuple[tuple[ContactGeometry, ...], ...]
    force_index: tuple[Mapping[str, np.ndarray], ...]
    generators: tuple[Mapping[str, np.ndarray], ...]
    frames: tuple[str, ...]
    dynamics_knots: tuple[int, ...]
    structure: tuple

    n_variables = CentroidalTerms.n_variables
    corner_forces = CentroidalTerms.corner_forces
    forces = CentroidalTerms.forces


def _force_box(c: ContactGeometry, n_points: int, settings: CentroidalSettings):
    """Bounds and initial guess of one contact's point-force variables [body weights].

    Friction edges: each of the 4 edge weights per point lies in ``[0, max_force]`` (friction
    and unilaterality as bounds); the guess puts ``1 / n_points`` of the weight on each point
    along the normal (equal weights on its edges). Components: each lies within ``max_force``;
    on flat ground the normal component is also bounded below by 0 (bounds are values); the
    guess is the same force.

    Returns:
        (lower, upper, guess) over the contact's variables.
    """
    m = c.n_points
    share = 1.0 / max(n_points, 1)
    if settings.friction_edges:
        return np.zeros(4 * m), np.full(4 * m, settings.max_force), np.full(4 * m, share / 4.0)
    lo = np.full(3 * m, -settings.max_force)
    hi = np.full(3 * m, settings.max_force)
    if np.allclose(c.normal, [0.0, 0.0, 1.0]):
        lo[2::3] = 0.0
    return lo, hi, np.tile(c.normal * share, m)


def _generator(c: ContactGeometry, settings: CentroidalSettings) -> np.ndarray:
    """(3, b) map from one point's variables to its world force (pyramid edges or identity)."""
    if settings.friction_edges:
        return pyramid_edges(c.rotation, c.friction_coefficient, inner=settings.inner_pyramid)
    return np.eye(3)


def _structure(settings: CentroidalSettings, per_knot: list) -> tuple:
    return (settings.inner_pyramid, settings.angular_momentum_weight > 0.0,
            "edges" if settings.friction_edges else "components", tuple(per_knot))


def centroidal_pattern(contacts: Sequence[Sequence[ContactGeometry]], mass: float, *,
                       settings: CentroidalSettings = CentroidalSettings(),
                       gravity: np.ndarray = GRAVITY) -> CentroidalPattern:
    """Variable/row layout, bounds, initial guess and parameter values of :func:`build_centroidal`.

    Args:
        contacts: Active contacts per knot (T entries).
        mass: Total mass [kg].
        settings: Weights and options.
        gravity: Gravity [m/s^2].

    Returns:
        The pattern (no CasADi).
    """
    T = len(contacts)
    weight = float(mass * np.linalg.norm(gravity))
    lower, upper, initial, pvals, lbg, ubg = [], [], [], [], [], []
    index: list[dict[str, np.ndarray]] = [{} for _ in range(T)]
    gens: list[dict[str, np.ndarray]] = [{} for _ in range(T)]
    frames: list[str] = []
    structure = []
    b = 4 if settings.friction_edges else 3
    n = 0
    for k in range(1, T - 1):
        active = contacts[k]
        n_points = sum(c.n_points for c in active)
        structure.append((k, tuple((c.frame, c.n_points) for c in active)))
        for c in active:
            if c.frame not in frames:
                frames.append(c.frame)
            m = c.n_points
            index[k][c.frame] = np.arange(n, n + b * m).reshape(m, b)
            gens[k][c.frame] = _generator(c, settings)
            n += b * m
            lo, hi, guess = _force_box(c, n_points, settings)
            lower.append(lo)
            upper.append(hi)
            initial.append(guess)
            pvals.append(_geometry_values(c))
            if not settings.friction_edges:
                lbg.append(np.zeros(5 * m))
                ubg.append(np.full(5 * m, np.inf))
        lbg.append(np.zeros(3))
        ubg.append(np.zeros(3))
    cat = (lambda xs: np.concatenate(xs) if xs else np.zeros(0))
    return CentroidalPattern(
        lower=cat(lower), upper=cat(upper), initial=cat(initial), parameter_values=cat(pvals),
        lbg=cat(lbg), ubg=cat(ubg), weight=weight, contacts=tuple(tuple(c) for c in contacts),
        force_index=tuple(index), generators=tuple(gens), frames=tuple(frames),
        dynamics_knots=tuple(range(1, T - 1)), structure=_structure(settings, structure),
    )


def build_centroidal(
    com: Sequence[Any],
    dt: Any,
    contacts: Sequence[Sequence[ContactGeometry]],
    mass: float,
    *,
    settings: CentroidalSettings = CentroidalSettings(),
    gravity: np.ndarray = GRAVITY,
    symbol: type = ca.SX,
) -> CentroidalTerms:
    """Force variables, CoM dynamics, friction pyramids and the angular-momentum cost on a grid.

    The dynamics hold at the interior knots ``1 .. T-2`` (a central difference needs both
    neighbours); force variables exist there for every active contact point. The first and the
    last knot carry no forces: the NLP fixes or bounds their velocities itself.

    Args:
        com: CoM per knot (T entries, each (3,) CasADi) [m].
        dt: Knot spacing [s] (a number or a CasADi parameter).
        contacts: Active contacts per knot (T entries); empty = flight.
        mass: Total mass [kg].
        settings: Weights and options.
        gravity: Gravity in the world [m/s^2].
        symbol: ``casadi.SX`` or ``casadi.MX`` for the new variables and parameters.

    Returns:
        The terms to add to the NLP.

    Raises:
        PlannerError: ``com`` and ``contacts`` differ in length, or fewer than 3 knots.
    """
    T = len(com)
    if len(contacts) != T:
        raise PlannerError(f"centroidal terms: {T} CoM knots but {len(contacts)} contact sets")
    if T < 3:
        raise PlannerError(f"centroidal terms: need at least 3 knots for CoM accelerations, got {T}")
    g_norm = float(np.linalg.norm(gravity))
    weight = float(mass * g_norm)
    g_unit = np.asarray(gravity, dtype=float) / g_norm
    syms: list[Any] = []
    psyms: list[Any] = []
    pvals: list[np.ndarray] = []
    lower: list[np.ndarray] = []
    upper: list[np.ndarray] = []
    initial: list[np.ndarray] = []
    blocks: list[ConstraintBlock] = []
    index: list[dict[str, np.ndarray]] = [{} for _ in range(T)]
    gens: list[dict[str, np.ndarray]] = [{} for _ in range(T)]
    frames: list[str] = []
    structure: list[tuple] = []
    cost = 0
    n = 0
    dyn_knots = []
    edges = settings.friction_edges
    b = 4 if edges else 3
    # edges: 4 |u_p|^2 equals |f|^2 for a force along the normal split evenly over the edges
    force_weight = settings.force_weight * (4.0 if edges else 1.0)
    for k in range(1, T - 1):
        active = contacts[k]
        n_points = sum(c.n_points for c in active)
        structure.append((k, tuple((c.frame, c.n_points) for c in active)))
        total = ca.DM.zeros(3)
        points, forces = [], []
        for c in active:
            if c.frame not in frames:
                frames.append(c.frame)
            m = c.n_points
            u = symbol.sym(f"u_{c.frame}_{k}", b * m)
            prm = symbol.sym(f"contact_{c.frame}_{k}", 3 * m + 10)
            syms.append(u)
            psyms.append(prm)
            pvals.append(_geometry_values(c))
            index[k][c.frame] = np.arange(n, n + b * m).reshape(m, b)
            gens[k][c.frame] = _generator(c, settings)
            n += b * m
            lo, hi, guess = _force_box(c, n_points, settings)
            lower.append(lo)
            upper.append(hi)
            initial.append(guess)
            R = ca.reshape(prm[3 * m : 3 * m + 9], 3, 3)
            E = pyramid_edges(R, prm[3 * m + 9], inner=settings.inner_pyramid) if edges else None
            rows = []
            for i in range(m):
                if edges:
                    f_i = ca.mtimes(E, u[4 * i : 4 * i + 4])
                else:
                    f_i = u[3 * i : 3 * i + 3]
                    rows.append(friction_pyramid(f_i, R, prm[3 * m + 9], inner=settings.inner_pyramid))
                total = total + f_i
                points.append(prm[3 * i : 3 * i + 3])
                forces.append(f_i)
            if rows:
                expr = ca.vertcat(*rows)
                blocks.append(ConstraintBlock(
                    name=f"friction {c.frame}", knot=k, expr=expr,
                    lower=np.zeros(expr.shape[0]), upper=np.full(expr.shape[0], np.inf),
                ))
            cost = cost + force_weight * dt * ca.sumsqr(u)
        acc = com_acceleration(com[k - 1], com[k], com[k + 1], dt)
        residual = (acc / g_norm - ca.DM(g_unit)) - total  # normalized Newton: (c'' - g)/|g| = sum u
        blocks.append(ConstraintBlock(name="CoM dynamics", knot=k, expr=residual, lower=np.zeros(3), upper=np.zeros(3)))
        dyn_knots.append(k)
        if forces and settings.angular_momentum_weight > 0.0:
            ldot = angular_momentum_rate(com[k], points, forces)  # [m x body weights]
            cost = cost + settings.angular_momentum_weight * dt * ca.sumsqr(ldot)
    cat = (lambda xs: np.concatenate(xs) if xs else np.zeros(0))
    return CentroidalTerms(
        variables=ca.vertcat(*syms) if syms else symbol(0, 1),
        lower=cat(lower),
        upper=cat(upper),
        initial=cat(initial),
        parameters=ca.vertcat(*psyms) if psyms else symbol(0, 1),
        parameter_values=cat(pvals),
        constraints=tuple(blocks),
        cost=cost,
        weight=weight,
        contacts=tuple(tuple(c) for c in contacts),
        force_index=tuple(index),
        generators=tuple(gens),
        frames=tuple(frames),
        dynamics_knots=tuple(dyn_knots),
        structure=_structure(settings, structure),
    )


def build_centroidal_for_spec(
    spec: TaskSpec,
    robot: Robot,
    t: Sequence[float],
    com: Sequence[Any],
    *,
    settings: CentroidalSettings = CentroidalSettings(),
    symbol: type = ca.SX,
) -> CentroidalTerms:
    """:func:`build_centroidal` for a spec on a uniform knot grid ``t``.

    Args:
        spec: The task (its phases give the contact sets, the later phase at a boundary).
        robot: The robot (mass, soles, friction).
        t: Knot times (T,) [s], uniformly spaced.
        com: Symbolic CoM per knot (T entries) [m].
        settings: Weights and options.
        symbol: ``casadi.SX`` or ``casadi.MX``.

    Returns:
        The terms to add to the NLP.

    Raises:
        PlannerError: the grid is not uniform or too short.
    """
    t = np.asarray(t, dtype=float)
    if t.size < 3:
        raise PlannerError(f"dynamic plan: need at least 3 knots, got {t.size}")
    steps = np.diff(t)
    if np.ptp(steps) > 1e-9 * max(1.0, float(t[-1])):
        raise PlannerError("dynamic plan: the knot grid must be uniform")
    contacts = contacts_per_knot(spec, robot, t, cop_margin=settings.cop_margin)
    return build_centroidal(com, float(steps[0]), contacts, robot.mass, settings=settings, symbol=symbol)


# ---------------------------------------------------------------------------------------------
# Integration with the trajectory NLP (planner.trajopt)
# ---------------------------------------------------------------------------------------------


def layout_contacts(lay: Any, *, cop_margin: float = 0.0) -> tuple[tuple[ContactGeometry, ...], ...]:
    """Per knot of a :class:`planner.formulation.Layout`, the contacts it holds, as geometry.

    A contact holds at both ends of its phase (the layout's ``contacts_at``), so forces may act
    at the knot where a foot lifts off or touches down. The friction coefficient is the spec
    contact's own, else the robot profile's.

    Args:
        lay: The layout.
        cop_margin: Inward sole margin for the centre of pressure [m].

    Returns:
        One tuple of contacts per knot (0..N).
    """
    robot, spec = lay.robot, lay.spec
    starts = spec.phase_start_times()
    out = []
    for k, active in enumerate(lay.contacts_at):
        tk = float(lay.t[k])
        mus: dict[int, float | None] = {}
        for i, ph in enumerate(spec.phases):
            if starts[i] - 1e-9 <= tk <= starts[i] + ph.duration + 1e-9:
                for c in ph.contacts:
                    mus[robot.frame_id(c.frame)] = c.friction_coefficient
        geos = []
        for fid, (_frame, M) in active.items():
            contact = Contact(
                frame=robot.model.frames[fid].name,
                placement=Pose(position=tuple(float(x) for x in M.translation),
                               rpy=tuple(float(x) for x in pin.rpy.matrixToRpy(M.rotation))),
                friction_coefficient=mus.get(fid),
            )
            geos.append(contact_geometry(contact, robot, cop_margin=cop_margin))
        out.append(tuple(geos))
    return tuple(out)


@dataclass(frozen=True, slots=True, kw_only=True)
class CentroidalFunction:
    """The centroidal terms of a layout as one SX function, for an MX (or SX) NLP.

    ``function(C, U, P, dt) -> (g, cost)`` with ``C`` the CoM per knot (3, N+1) [m], ``U`` the
    force variables, ``P`` the contact parameters and ``dt`` the knot spacing [s]. Calling it
    with MX arguments puts a single node in the NLP graph whose derivatives CasADi computes on
    the SX expressions.

    Attributes:
        function: The CasADi function.
        terms: The terms (bounds, initial guess, parameter values, force indices).
        corner_rows: (knot, foot frame id, corner) of the "sole corner above the ground" rows
            for feet not in contact at a variable knot (corner in the profile's order).
        lbg, ubg: Bounds of the function's ``g`` rows.
    """

    function: ca.Function
    terms: CentroidalTerms
    corner_rows: tuple[tuple[int, int, int], ...]
    lbg: np.ndarray
    ubg: np.ndarray

    @property
    def structure(self) -> tuple:
        """Hashable structure (for the solver cache key)."""
        return (self.terms.structure, self.corner_rows)


def centroidal_function(lay: Any, *, settings: CentroidalSettings = CentroidalSettings(),
                        first_free_knot: int = 2) -> CentroidalFunction:
    """Build :class:`CentroidalFunction` for a :class:`planner.formulation.Layout`.

    Args:
        lay: The layout (grid, contacts held per knot, robot).
        settings: Weights and options.
        first_free_knot: Knots before it are fixed (no corner rows there); knot N repeats N-1.

    Returns:
        The function, its terms and the corner-row selection.
    """
    N = lay.N
    C = ca.SX.sym("com", 3, N + 1)
    dt = ca.SX.sym("dt")
    contacts = layout_contacts(lay, cop_margin=settings.cop_margin)
    terms = build_centroidal([C[:, k] for k in range(N + 1)], dt, contacts, lay.robot.mass, settings=settings)
    g, lbg, ubg = terms.g()
    fn = ca.Function("centroidal", [C, terms.variables, terms.parameters, dt], [g, terms.cost],
                     ["com", "u", "p", "dt"], ["g", "cost"])
    rows = swinging_corners(lay, first_free_knot=first_free_knot)
    return CentroidalFunction(function=fn, terms=terms, corner_rows=rows, lbg=lbg, ubg=ubg)


def swinging_corners(lay: Any, *, first_free_knot: int = 2) -> tuple[tuple[int, int, int], ...]:
    """(knot, foot frame id, corner) of every sole corner of a foot not in contact at a variable knot."""
    feet = [lay.robot.frame_id(f"{s}_foot") for s in ("left", "right")]
    return tuple((k, fid, i) for k in range(first_free_knot, lay.N) for fid in feet
                 if fid not in lay.contacts_at[k] for i in range(4))


def sole_corner_heights(kin: Any, oMi: Any, robot: Robot) -> Any:
    """Heights (8,) of the left then right sole corners from symbolic joint placements [m].

    Args:
        kin: A :class:`planner.symbolic.SymbolicKinematics`.
        oMi: Its joint placements at one knot.
        robot: The robot (foot frames, sole rectangle).

    Returns:
        CasADi column: left corners 0..3, right corners 0..3 (profile order).
    """
    out = []
    for side in ("left", "right"):
        R, p = kin.frame_placement(oMi, robot.frame_id(f"{side}_foot"))
        for x, y in robot.profile.sole.corners(side):
            out.append((p + ca.mtimes(R, ca.DM([x, y, 0.0])))[2])
    return ca.vertcat(*out)


@dataclass(frozen=True, slots=True, kw_only=True)
class DynamicBlocks:
    """The dynamic part of a stage-wise NLP with its hand-assembled derivatives (MX).

    The NLP's variables are ``[x_kin; u; c]``: the chart displacements of the variable knots,
    the force variables, then the CoM of each variable knot (3 per knot, *lifted*: tied to the
    configuration by equality rows). Lifting the CoM keeps the CoM Jacobian (dense over the
    joints) out of the dynamics rows and the angular-momentum cost: those couple the forces
    with 3 CoM variables per knot instead of every joint, which makes the KKT system much
    sparser. Rows: the centroidal rows (dynamics; friction rows without friction edges), the
    CoM rows ``c_k - com(q_k) = 0``, then the sole-corner heights of swinging feet.

    Attributes:
        f: Cost added to the objective.
        g: Constraint rows (column).
        lbg, ubg: Their bounds.
        grad_u, grad_c: Gradient of ``f`` (it does not depend on ``x_kin``) [MX columns].
        jac_x, jac_u, jac_c: Jacobian of ``g`` w.r.t. ``x_kin``, ``u`` and ``c``.
        hess_xx, hess_uu, hess_uc, hess_cc: Hessian blocks of ``lam_f f + lam . g`` (the
            ``x``-``u`` and ``x``-``c`` blocks are zero; ``hess_xx`` is None when not asked for).
        nu, eta: Multipliers (3, N-2) and (8, N-2) whose products with each variable knot's
            CoM and sole-corner heights give the curvature in ``hess_xx``.
    """

    f: Any
    g: Any
    lbg: np.ndarray
    ubg: np.ndarray
    grad_u: Any
    grad_c: Any
    jac_x: Any
    jac_u: Any
    jac_c: Any
    hess_xx: Any
    nu: Any
    eta: Any
    hess_uu: Any
    hess_uc: Any
    hess_cc: Any


def _kinematic_functions(lay: Any) -> tuple[ca.Function, ca.Function]:
    """SX functions of one knot: (dq, q_ref) -> (c, Jc, z, Jz) and (dq, q_ref, nu, eta) -> hess(nu.c + eta.z)."""
    from planner.symbolic import SymbolicKinematics

    robot = lay.robot
    kin = SymbolicKinematics(robot.model)
    dq = ca.SX.sym("dq", robot.nv)
    q_ref = ca.SX.sym("q_ref", robot.nq)
    oMi = kin.joint_placements(q_ref, dq)
    c = kin.com(oMi)
    z = sole_corner_heights(kin, oMi, robot)
    nu = ca.SX.sym("nu", 3)
    eta = ca.SX.sym("eta", 8)
    first = ca.Function("dyn_kin", [dq, q_ref], [c, ca.jacobian(c, dq), z, ca.jacobian(z, dq)])
    second = ca.Function("dyn_kin_hess", [dq, q_ref, nu, eta], [ca.hessian(ca.dot(nu, c) + ca.dot(eta, z), dq)[0]])
    return first, second


def com_rows(lay: Any) -> int:
    """Number of lifted CoM variables (and of the rows tying them to the configuration)."""
    return 3 * (lay.N - 2)


def dynamic_blocks(lay: Any, cf: CentroidalFunction, x_kin: Any, u: Any, c: Any, q_ref: Any, p: Any, dt: Any,
                   lam_f: Any, lam: Any, *, kinematic_hessian: bool = True) -> DynamicBlocks:
    """Assemble the dynamic terms of a stage-wise NLP with exact derivatives.

    The centroidal function (dynamics, friction, cost) is evaluated on the lifted CoM variables
    ``c`` (knots 0 and 1 at the standing CoM, knot N repeating N-1) with its derivatives w.r.t.
    ``(C, u)`` from SX; the configuration enters only through the rows ``c_k - com(q_k)`` and
    the sole-corner heights, whose values and Jacobians come from one mapped SX function and
    whose curvature from a second one (the Hessian of ``-mu_k . com_k + eta_k . z_k`` with the
    multipliers of those rows).

    Args:
        lay: The layout.
        cf: The centroidal function of the layout.
        x_kin: Chart displacements of knots 2..N-1 (MX, nv (N-2)).
        u: Force variables (MX, ``cf.terms.n_variables``).
        c: Lifted CoM of knots 2..N-1 (MX, 3 (N-2)) [m].
        q_ref: Reference configuration (MX, nq).
        p: Contact parameters (MX, ``cf.terms.parameter_values.size``).
        dt: Knot spacing (MX scalar) [s].
        lam_f: Objective multiplier (MX scalar).
        lam: Multipliers of this block's rows (MX, len(lbg)).
        kinematic_hessian: Build :attr:`DynamicBlocks.hess_xx` (off: the caller adds the
            curvature of the CoM and sole-corner rows itself, from ``nu`` and ``eta``).

    Returns:
        The blocks.
    """
    robot, N = lay.robot, lay.N
    nv, n = robot.nv, lay.N - 2
    first, second = _kinematic_functions(lay)
    X = ca.reshape(x_kin, nv, n)
    Qr = ca.repmat(q_ref, 1, n)
    Ck, JC, Z, JZ = first.map(n)(X, Qr)
    c0 = first(ca.MX.zeros(nv), q_ref)[0]
    Cv = ca.reshape(c, 3, n)
    C = ca.horzcat(c0, c0, Cv, Cv[:, n - 1])
    # selection E: vec(C) (3(N+1)) <- c (3n); knot N copies knot N-1
    rows, cols = [], []
    for k in range(2, N + 1):
        j = min(k, N - 1) - 2
        rows += [3 * k + i for i in range(3)]
        cols += [3 * j + i for i in range(3)]
    E = ca.DM(ca.Sparsity.triplet(3 * (N + 1), 3 * n, rows, cols), 1.0)
    # centroidal function derivatives w.r.t. (vec C, u)
    Cs = ca.SX.sym("C", 3, N + 1)
    Us = ca.SX.sym("u", cf.terms.n_variables)
    Ps = ca.SX.sym("p", cf.terms.parameter_values.size)
    dts = ca.SX.sym("dt")
    gs, fs = cf.function(Cs, Us, Ps, dts)
    n_c = gs.numel()
    ls = ca.SX.sym("lam", n_c)
    sig = ca.SX.sym("sigma")
    w = ca.vertcat(ca.vec(Cs), Us)
    lag = sig * fs + ca.dot(ls, gs)
    d1 = ca.Function("dyn_centroidal_d1", [Cs, Us, Ps, dts], [gs, fs, ca.jacobian(gs, w), ca.gradient(fs, w)])
    d2 = ca.Function("dyn_centroidal_d2", [Cs, Us, Ps, dts, sig, ls], [ca.hessian(lag, w)[0]])
    n_m = 3 * n
    lam_c, lam_m, lam_z = lam[:n_c], lam[n_c:n_c + n_m], lam[n_c + n_m:]
    g_c, f_c, J_w, G_w = d1(C, u, p, dt)
    H_w = d2(C, u, p, dt, lam_f, lam_c)
    m = 3 * (N + 1)
    J_C, J_U = J_w[:, :m], J_w[:, m:]
    G_C, G_U = G_w[:m], G_w[m:]
    H_CC, H_CU, H_UU = H_w[:m, :m], H_w[:m, m:], H_w[m:, m:]
    # swinging sole corners: rows picked from Z (8 x n)
    feet = [robot.frame_id(f"{s}_foot") for s in ("left", "right")]
    zr = [(k - 2) * 8 + feet.index(fid) * 4 + i for k, fid, i in cf.corner_rows]
    n_z = len(zr)
    Sz = ca.DM(ca.Sparsity.triplet(n_z, 8 * n, list(range(n_z)), zr), 1.0)
    g_z = ca.mtimes(Sz, ca.vec(Z))
    jac_z = ca.mtimes(Sz, ca.diagcat(*ca.horzsplit(JZ, nv)))
    eta = ca.reshape(ca.mtimes(Sz.T, lam_z), 8, n) if n_z else ca.MX.zeros(8, n)
    nu = -ca.reshape(lam_m, 3, n)
    HK = second.map(n)(X, Qr, nu, eta) if kinematic_hessian else None
    n_u = cf.terms.n_variables
    return DynamicBlocks(
        f=f_c,
        g=ca.vertcat(g_c, c - ca.vec(Ck), g_z),
        lbg=np.concatenate([cf.lbg, np.zeros(n_m), np.zeros(n_z)]),
        ubg=np.concatenate([cf.ubg, np.zeros(n_m), np.full(n_z, np.inf)]),
        grad_u=G_U,
        grad_c=ca.mtimes(E.T, G_C),
        jac_x=ca.vertcat(ca.MX(n_c, nv * n), -ca.diagcat(*ca.horzsplit(JC, nv)), jac_z),
        jac_u=ca.vertcat(J_U, ca.MX(n_m + n_z, n_u)),
        jac_c=ca.vertcat(ca.mtimes(J_C, E), ca.MX(ca.DM.eye(n_m)), ca.MX(n_z, n_m)),
        hess_xx=ca.diagcat(*ca.horzsplit(HK, nv)) if kinematic_hessian else None,
        nu=nu,
        eta=eta,
        hess_uu=H_UU,
        hess_uc=ca.mtimes(H_CU.T, E),
        hess_cc=ca.mtimes(E.T, ca.mtimes(H_CC, E)),
    )


def stage_hessians(lay: Any, x_kin: Any, q_ref: Any, p_kin: Any, lam_f: Any, lam_kin: Any, nu: Any,
                   eta: Any) -> Any:
    """Block-diagonal chart Hessian of a dynamic NLP's Lagrangian, one SX function per stage type.

    For the knots of each stage group of :func:`planner.trajopt.stage_groups`, one mapped SX
    function gives the Hessian of ``lam_f cost_k + lam_k . g_k + nu_k . com_k + eta_k . z_k``
    w.r.t. ``dq_k``: the kinematic terms and the CoM and sole-corner rows of the dynamics share
    one forward-kinematics pass, and the blocks are laid out in knot order with one ``diagcat``
    (no sparse products with selection matrices). Parameters and multipliers are read in the
    order :func:`planner.trajopt.build_nlp` gives them.

    Args:
        lay: The dynamic layout.
        x_kin: Chart displacements of knots 2..N-1 (MX, nv (N-2)).
        q_ref: Reference configuration (MX, nq).
        p_kin: Parameters of the kinematic NLP (MX).
        lam_f: Objective multiplier (MX scalar).
        lam_kin: Multipliers of the kinematic rows (MX).
        nu, eta: Multipliers on each variable knot's CoM (3, N-2) and sole-corner heights (8, N-2).

    Returns:
        The (nv (N-2), nv (N-2)) block-diagonal Hessian (MX, both triangles), without the
        constant quadratic costs.
    """
    from planner.symbolic import SymbolicKinematics
    from planner.trajopt import FRAME_KINDS, stage_groups, term_expression

    robot = lay.robot
    nq, nv, n = robot.nq, robot.nv, lay.N - 2
    X = ca.reshape(x_kin, nv, n)
    kin = SymbolicKinematics(robot.model)
    blocks: dict[int, Any] = {}
    p_offset, g_offset = nq + 3, 0
    for gi, (_sig, knots, term_lists) in enumerate(stage_groups(lay)):
        terms = [lay.terms[i] for i in term_lists[0]]
        dq = ca.SX.sym("dq", nv)
        qr = ca.SX.sym("q_ref", nq)
        oMi = kin.joint_placements(qr, dq)
        frame_ids = sorted({t.structure[1] for t in terms if t.kind in FRAME_KINDS})
        com = kin.com(oMi)
        k = {"com": com, "frames": {f: kin.frame_placement(oMi, f)[::-1] for f in frame_ids}, "dq": dq}
        ps = ca.SX.sym("p", sum(len(t.params) for t in terms))
        sigma = ca.SX.sym("sigma")
        rows, cost, offset = [], 0, 0
        # soft CoM targets w |S (c - c*)|^2: Hessian 2 w (J^T S^T S J + sum_i e_i hess c_i), the
        # second part folded into the CoM multiplier (AD of the square costs ~5x more)
        nu_cost = ca.SX.zeros(3)
        gauss_newton = ca.SX.zeros(nv, nv)
        for t in terms:
            pt = ps[offset: offset + len(t.params)]
            offset += len(t.params)
            if t.kind == "com_pos" and t.structure[2] not in ("eq", "box"):
                sel = [i for i, a in enumerate(t.structure[1]) if a]
                e = (com - pt[0:3])[sel]
                J = ca.jacobian(com[sel], dq)
                gauss_newton = gauss_newton + 2 * pt[3] * ca.mtimes(J.T, J)
                nu_cost[sel] = nu_cost[sel] + 2 * pt[3] * e
                continue
            r, cst = term_expression(t, pt, k, qr, robot)
            cost = cost + cst
            if r is not None:
                rows.append(r)
        g = ca.vertcat(*rows) if rows else ca.SX.zeros(0)
        lam = ca.SX.sym("lam", g.numel())
        nu_s = ca.SX.sym("nu", 3)
        eta_s = ca.SX.sym("eta", 8)
        nu_all = ca.SX.sym("nu_all", 3)
        z = sole_corner_heights(kin, oMi, robot)
        lag = sigma * cost + ca.dot(lam, g) + ca.dot(nu_all, com) + ca.dot(eta_s, z)
        hess = ca.substitute(ca.hessian(lag, dq)[0], nu_all, nu_s + sigma * nu_cost) + sigma * gauss_newton
        fn = ca.Function(f"dyn_stage_hess{gi}", [dq, qr, ps, sigma, lam, nu_s, eta_s], [hess])
        m = len(knots)
        cols = [kk - 2 for kk in knots]
        n_p = ps.numel()
        Pg = ca.reshape(p_kin[p_offset: p_offset + n_p * m], n_p, m)
        p_offset += n_p * m
        L = ca.reshape(lam_kin[g_offset: g_offset + g.numel() * m], g.numel(), m)
        g_offset += g.numel() * m
        HS = fn.map(m)(X[:, cols], ca.repmat(q_ref, 1, m), Pg, ca.repmat(lam_f, 1, m), L, nu[:, cols], eta[:, cols])
        for kk, block in zip(knots, ca.horzsplit(HS, nv), strict=True):
            blocks[kk] = block
    return ca.diagcat(*[blocks[kk] for kk in range(2, lay.N)])


# ---------------------------------------------------------------------------------------------
# The dynamic layout: what planner.trajopt calls for a spec with dynamic = True
# ---------------------------------------------------------------------------------------------


def _layout_class():
    from planner.formulation import Layout

    return Layout


class DynamicLayout(_layout_class()):  # type: ignore[misc]
    """A :class:`planner.formulation.Layout` with CoM dynamics and contact forces.

    Built by :func:`to_dynamic_layout`. Its :meth:`structure` adds the force pattern (contacts per
    knot, swinging sole corners), so the solver cache never confuses it with a kinematic
    layout or with another contact pattern.

    Attributes:
        centroidal_settings: Weights and options of the dynamic terms.
        kinematic_terms: Number of chart variables ``nv (N - 2)`` (the forces follow).
    """

    centroidal_settings: CentroidalSettings
    _cf: CentroidalFunction | None
    _pattern: CentroidalPattern | None

    def centroidal(self) -> CentroidalFunction:
        """The centroidal function of this layout (CasADi; built once, only to build a solver)."""
        if self._cf is None:
            self._cf = centroidal_function(self, settings=self.centroidal_settings)
        return self._cf

    def pattern(self) -> CentroidalPattern:
        """The numbers of the centroidal terms (no CasADi; what a cached solver needs)."""
        if self._pattern is None:
            contacts = layout_contacts(self, cop_margin=self.centroidal_settings.cop_margin)
            self._pattern = centroidal_pattern(contacts, self.robot.mass, settings=self.centroidal_settings)
        return self._pattern

    def corner_rows(self) -> tuple[tuple[int, int, int], ...]:
        """(knot, foot frame id, corner) of the sole-corner rows (feet not in contact)."""
        return swinging_corners(self)

    def structure(self) -> tuple:
        """Kinematic structure + the dynamic one (with :data:`DYNAMIC_FORMULATION`: the solver
        cache hashes the planner sources but not this file, so an edited dynamic NLP bumps it)."""
        return (super().structure(), "dynamic", DYNAMIC_FORMULATION, self.pattern().structure,
                self.corner_rows(), self.centroidal_settings)

    @property
    def n_kinematic(self) -> int:
        """Number of chart variables (the force variables come after them)."""
        return self.robot.nv * (self.N - 2)


def to_dynamic_layout(lay: Any, settings: CentroidalSettings = CentroidalSettings()) -> DynamicLayout:
    """The dynamic version of a kinematic layout.

    The support-polygon rows on the CoM are dropped except at the last variable knot (the robot
    ends at rest there): with contact forces, balance is the centre of pressure inside the
    soles, which the corner forces guarantee at every knot.

    Args:
        lay: The layout of a spec (``planner.formulation.make_layout``).
        settings: Weights and options of the dynamic terms.

    Returns:
        The dynamic layout (a new object; ``lay`` is not changed).
    """
    import dataclasses

    fields = {f.name: getattr(lay, f.name) for f in dataclasses.fields(lay)}
    fields["terms"] = [t for t in lay.terms if t.kind != "polygon" or t.knot == lay.N - 1]
    out = DynamicLayout(**fields)
    out.centroidal_settings = settings
    out._cf = None
    out._pattern = None
    return out


def dynamic_sizes(lay: DynamicLayout) -> tuple[int, int]:
    """(force + lifted CoM variables, dynamic constraint rows) of a dynamic layout."""
    pat = lay.pattern()
    return pat.n_variables + com_rows(lay), len(pat.lbg) + com_rows(lay) + len(lay.corner_rows())


def extend_nlp(lay: DynamicLayout, nlp: dict, derivatives: dict) -> tuple[dict, dict]:
    """Add the forces, lifted CoM, CoM dynamics and sole-corner rows to a stage-wise kinematic NLP.

    Args:
        lay: The dynamic layout.
        nlp: ``{x, p, f, g}`` of the kinematic NLP (MX).
        derivatives: Its ``grad_f``, ``jac_g``, ``hess_lag`` functions (nlpsol options).

    Returns:
        The extended ``(nlp, derivatives)``: variables ``[x; u; c]``, parameters ``[p; contact
        geometry]``, rows ``[g; dynamic rows]``.
    """
    cf = lay.centroidal()
    robot = lay.robot
    n_x, n_p, n_g = nlp["x"].numel(), nlp["p"].numel(), nlp["g"].numel()
    n_u = cf.terms.n_variables
    n_m = com_rows(lay)
    _, n_gd = dynamic_sizes(lay)
    n_pd = cf.terms.parameter_values.size
    x = ca.MX.sym("x", n_x + n_u + n_m)
    p = ca.MX.sym("p", n_p + n_pd)
    lam_f = ca.MX.sym("lam_f")
    lam_g = ca.MX.sym("lam_g", n_g + n_gd)
    xk, u, c = x[:n_x], x[n_x:n_x + n_u], x[n_x + n_u:]
    pk, pd = p[:n_p], p[n_p:]
    nq = robot.nq
    b = dynamic_blocks(lay, cf, xk, u, c, pk[:nq], pd, pk[nq + 2], lam_f, lam_g[n_g:], kinematic_hessian=False)
    f_k, grad_k = derivatives["grad_f"](xk, pk)
    g_k, jac_k = derivatives["jac_g"](xk, pk)
    # chart Hessian: the constant quadratic costs + per-knot blocks (kinematic terms and the
    # CoM / sole-corner rows together), instead of the kinematic hess_lag plus a second pass
    from planner.trajopt import _quadratic_operators

    A, P, _ = _quadratic_operators(lay)
    w_smooth, w_posture, dt = pk[nq], pk[nq + 1], pk[nq + 2]
    quad = lam_f * (2 * w_smooth / dt**3 * ca.mtimes(A.T, A) + 2 * w_posture * dt * ca.mtimes(P.T, P))
    h_k = ca.triu(quad + stage_hessians(lay, xk, pk[:nq], pk, lam_f, lam_g[:n_g], b.nu, b.eta))
    f = f_k + b.f
    g = ca.vertcat(g_k, b.g)
    grad = ca.vertcat(grad_k, b.grad_u, b.grad_c)
    jac = ca.vertcat(ca.horzcat(jac_k, ca.MX(n_g, n_u + n_m)), ca.horzcat(b.jac_x, b.jac_u, b.jac_c))
    hess = ca.blockcat([
        [h_k, ca.MX(n_x, n_u), ca.MX(n_x, n_m)],
        [ca.MX(n_u, n_x), ca.triu(b.hess_uu), b.hess_uc],
        [ca.MX(n_m, n_x), ca.MX(n_m, n_u), ca.triu(b.hess_cc)],
    ])
    out = {
        "grad_f": ca.Function("nlp_grad_f", [x, p], [f, grad], ["x", "p"], ["f", "grad_f_x"]),
        "jac_g": ca.Function("nlp_jac_g", [x, p], [g, jac], ["x", "p"], ["g", "jac_g_x"]),
        "hess_lag": ca.Function("nlp_hess_l", [x, p, lam_f, lam_g], [hess], ["x", "p", "lam_f", "lam_g"],
                                ["triu_hess_gamma_x_x"]),
    }
    return {"x": x, "p": p, "f": f, "g": g}, out


def extend_bounds(lay: DynamicLayout, lbx: np.ndarray, ubx: np.ndarray, lbg: np.ndarray,
                  ubg: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Bounds of the extended NLP from the kinematic ones (force boxes, free CoM, dynamic rows)."""
    pat = lay.pattern()
    rows = lay.corner_rows()
    n_z = len(rows)
    n_m = com_rows(lay)
    return (
        np.concatenate([lbx, pat.lower, np.full(n_m, -np.inf)]),
        np.concatenate([ubx, pat.upper, np.full(n_m, np.inf)]),
        np.concatenate([lbg, pat.lbg, np.zeros(n_m), swing_corner_floor(lay, rows)]),
        np.concatenate([ubg, pat.ubg, np.zeros(n_m), np.full(n_z, np.inf)]),
    )


SWING_CLEARANCE = 0.01  # [m] lowest sole corner of a swinging foot, away from lift-off and touch-down


def swing_corner_floor(lay: Any, rows: Sequence[tuple[int, int, int]]) -> np.ndarray:
    """Lower bounds of the swinging sole-corner heights [m].

    0 at the first and last free knot of a swing (the sole may still or already touch there),
    :data:`SWING_CLEARANCE` in between. With 0 everywhere, a Talos 4-step plan put the swinging
    toe on the ground two knots (0.15 s) before its touch-down, and the simulation, tracking it
    within millimetres, touched the floor early: an unplanned contact.
    """
    floor = np.zeros(len(rows))
    n = len(lay.contacts_at)
    for j, (k, fid, _corner) in enumerate(rows):
        before = k - 1 >= 0 and fid in lay.contacts_at[k - 1]
        after = k + 1 >= n or fid in lay.contacts_at[k + 1]
        if not before and not after:
            floor[j] = SWING_CLEARANCE
    return floor


def extend_parameters(lay: DynamicLayout, p: np.ndarray) -> np.ndarray:
    """Parameter values of the extended NLP: the kinematic ones, then the contact geometry."""
    return np.concatenate([p, lay.pattern().parameter_values])


def initial_guess(lay: DynamicLayout) -> np.ndarray:
    """Initial ``[x; u; c]``: the heading warm start for the chart, the weight shared by the
    corners, the CoM of the guessed configurations."""
    from planner.symbolic import chart_to_configuration

    dq = heading_guess(lay)
    model, data = lay.robot.model, lay.robot.data()
    com = [pin.centerOfMass(model, data, chart_to_configuration(model, lay.q_ref, dq[k])) for k in range(2, lay.N)]
    return np.concatenate([dq[2:lay.N].ravel(), lay.pattern().initial, np.ravel(com)])


def forces_of(lay: DynamicLayout, x: np.ndarray) -> np.ndarray:
    """The force variables ``u`` from a solution ``x = [x_kin; u; c]`` of the extended NLP."""
    return np.asarray(x, dtype=float)[lay.n_kinematic:lay.n_kinematic + lay.pattern().n_variables]


def rest_polygon_checks(lay: Any, com: np.ndarray, tolerance: float) -> list[ConstraintCheck]:
    """Support-polygon CoM bounds of a dynamic plan, where they apply: at the last knot (at rest).

    Args:
        lay: The layout.
        com: CoM per knot (N+1, 3) [m].
        tolerance: Accepted excursion [m].

    Returns:
        One check per support-polygon bound of the spec.
    """
    from planner.formulation import halfplanes, support_polygon
    from planner.plan import ConstraintCheck

    out = []
    k = lay.N
    hull = support_polygon(lay, k)
    for bounds in lay.spec.com_bounds:
        if not bounds.support_polygon or len(hull) < 3:
            continue
        A, b = halfplanes(hull)
        viol = max(0.0, float(np.max(A @ com[k, :2] - (b - bounds.margin))))
        out.append(ConstraintCheck(name=f"CoM bound {bounds.name!r} support polygon at rest", violation=viol,
                                   tolerance=tolerance, unit="m", time=float(lay.t[k])))
    return out


def heading_guess(lay: Any) -> np.ndarray:
    """Initial guess of the chart displacements (N+1, nv): the base follows the feet.

    At each knot the base keeps its standing pose relative to the *heading* of the placements in
    use (the mean position and yaw of the feet's latest contact placements), interpolated
    linearly in time between consecutive touch-downs; the joints stay at the reference. This
    keeps the contact rotation errors small for turns (the antisymmetric rotation error is
    singular at 90 degrees) and the feet close to their placements for steps.

    Args:
        lay: The layout (``q_ref`` is the standing posture the chart is centred on).

    Returns:
        ``dq`` per knot; knots 0 and 1 are zero.
    """
    robot = lay.robot
    feet = [robot.frame_id(f"{s}_foot") for s in ("left", "right")]
    latest: dict[int, pin.SE3] = {}
    data = robot.data()
    pin.framesForwardKinematics(robot.model, data, lay.q_ref)
    for fid in feet:
        latest[fid] = pin.SE3(data.oMf[fid])
    start = _mean_heading([latest[f] for f in feet])
    headings = []
    for active in lay.contacts_at:
        for fid, (_frame, M) in active.items():
            if fid in latest:
                latest[fid] = M
        headings.append(_mean_heading([latest[f] for f in feet]))
    # smooth the jumps of the heading (a swing moves it at touch-down) by a centred moving average
    H = np.array(headings)
    H[:, 2] = np.unwrap(H[:, 2])
    width = max(1, int(round(0.5 * (lay.N + 1) / max(1, len(lay.spec.phases)))))
    kernel = np.ones(2 * width + 1) / (2 * width + 1)
    padded = np.pad(H, ((width, width), (0, 0)), mode="edge")
    H = np.column_stack([np.convolve(padded[:, i], kernel, mode="valid") for i in range(3)])
    base_ref = lay.q_ref[:3]
    R_ref = pin.Quaternion(lay.q_ref[3:7]).matrix()
    rel = base_ref[:2] - start[:2]
    rel_local = _rz2(-start[2]) @ rel
    dq = np.zeros((lay.N + 1, robot.nv))
    for k in range(2, lay.N + 1):
        x, y, yaw = H[k]
        dyaw = yaw - start[2]
        p = np.array([*(np.array([x, y]) + _rz2(yaw) @ rel_local), base_ref[2]])
        dq[k, :3] = R_ref.T @ (p - base_ref)
        dq[k, 3:6] = R_ref.T @ np.array([0.0, 0.0, dyaw])
    return dq


def _rz2(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s], [s, c]])


def _mean_heading(placements: Sequence[pin.SE3]) -> np.ndarray:
    yaws = [math.atan2(M.rotation[1, 0], M.rotation[0, 0]) for M in placements]
    yaw = math.atan2(sum(math.sin(y) for y in yaws), sum(math.cos(y) for y in yaws))
    mid = np.mean([M.translation[:2] for M in placements], axis=0)
    return np.array([mid[0], mid[1], yaw])


# ---------------------------------------------------------------------------------------------
# Numeric checks on a finished plan
# ---------------------------------------------------------------------------------------------


def friction_violation(forces: np.ndarray, rotation: np.ndarray, mu: float) -> np.ndarray:
    """How far each force is outside the Coulomb cone and the unilateral half-space [N].

    Args:
        forces: (..., 3) world forces [N].
        rotation: Contact frame in the world (3, 3).
        mu: Friction coefficient [-].

    Returns:
        (...,) violation >= 0: ``max(0, |f_t| - mu f_n, -f_n)``.
    """
    local = np.asarray(forces, dtype=float) @ np.asarray(rotation)
    fn = local[..., 2]
    ft = np.linalg.norm(local[..., :2], axis=-1)
    return np.maximum(0.0, np.maximum(ft - mu * fn, -fn))


def center_of_pressure(points_in_frame: np.ndarray, forces: np.ndarray, rotation: np.ndarray, *, min_normal: float = 1e-6) -> np.ndarray:
    """Centre of pressure of corner forces in the contact frame (x, y) [m]; NaN when unloaded.

    Args:
        points_in_frame: Corner points (n, 3) in the contact frame [m].
        forces: (T, n, 3) world forces [N].
        rotation: Contact frame in the world (3, 3).
        min_normal: Total normal force below which the CoP is undefined [N].

    Returns:
        (T, 2) CoP in the contact frame.
    """
    fn = np.asarray(forces, dtype=float) @ np.asarray(rotation)[:, 2]  # (T, n)
    total = fn.sum(axis=1)
    cop = np.full((fn.shape[0], 2), np.nan)
    ok = total > min_normal
    cop[ok] = (fn[ok] @ points_in_frame[:, :2]) / total[ok, None]
    return cop


def cop_violation(cop: np.ndarray, x_range: tuple[float, float], y_range: tuple[float, float]) -> np.ndarray:
    """Distance of each CoP (T, 2) outside the rectangle ``x_range`` x ``y_range`` [m] (0 inside, NaN ignored)."""
    cop = np.asarray(cop, dtype=float)
    dx = np.maximum(0.0, np.maximum(x_range[0] - cop[:, 0], cop[:, 0] - x_range[1]))
    dy = np.maximum(0.0, np.maximum(y_range[0] - cop[:, 1], cop[:, 1] - y_range[1]))
    out = np.hypot(dx, dy)
    return np.where(np.isnan(out), 0.0, out)


def dynamic_checks(
    lay: Any,
    q: np.ndarray,
    com: np.ndarray,
    terms: CentroidalTerms,
    corner_rows: Sequence[tuple[int, int, int]],
    force_values: np.ndarray,
    *,
    force_tolerance: float = 1e-3,
    position_tolerance: float = 1e-5,
) -> list[ConstraintCheck]:
    """Report of a dynamic plan, recomputed with Pinocchio and numpy from the solution.

    Groups: Newton's law for the CoM (with the Pinocchio CoM of the returned configurations),
    the friction cone (the true Coulomb cone, not the pyramid) and the centre of pressure inside
    each sole rectangle per contact frame (where the sole carries more than the force tolerance:
    the CoP of a nearly unloaded sole, e.g. at take-off, is not defined), no force at a knot
    without contact, and every sole corner of a swinging foot above the ground.

    Args:
        lay: The layout.
        q: Configurations (N+1, nq).
        com: CoM per knot (N+1, 3) [m].
        terms: The centroidal terms of the NLP.
        corner_rows: (knot, foot frame id, corner) rows of swinging sole corners.
        force_values: Solution values of ``terms.variables``.
        force_tolerance: Accepted force-law violation, as a fraction of the body weight [-].
        position_tolerance: Accepted CoP excursion and corner depth [m].

    Returns:
        One :class:`~planner.plan.ConstraintCheck` per group.
    """
    cen = terms
    t = np.asarray(lay.t, dtype=float)
    dt = float(t[1] - t[0])
    tol_n = force_tolerance * cen.weight
    corners = cen.corner_forces(force_values)
    checks: list[ConstraintCheck] = []

    def worst(name: str, values: list[tuple[float, float]], tol: float, unit: str) -> None:
        if not values:
            return
        v, tt = max(values, key=lambda x: x[0])
        checks.append(ConstraintCheck(name=name, violation=max(0.0, float(v)), tolerance=tol, unit=unit, time=float(tt)))

    newton = []
    mass = cen.weight / float(np.linalg.norm(GRAVITY))
    for k in cen.dynamics_knots:
        acc = (com[k + 1] - 2 * com[k] + com[k - 1]) / dt**2
        total = sum((corners[f][k].sum(axis=0) for f in corners), np.zeros(3))
        newton.append((float(np.linalg.norm(com_dynamics_residual(mass, acc, total))), t[k]))
    worst("CoM dynamics m(c'' - g) = sum f", newton, tol_n, "N")
    friction: dict[str, list] = {}
    cop: dict[str, list] = {}
    idle = []
    for k, active in enumerate(cen.contacts):
        held = {c.frame for c in active} if k in cen.dynamics_knots else set()
        for frame, f in corners.items():
            if frame not in held:
                idle.append((float(np.abs(f[k]).max()), t[k]))
        if k not in cen.dynamics_knots:
            continue
        for c in active:
            fk = corners[c.frame][k]
            friction.setdefault(c.frame, []).append((float(friction_violation(fk, c.rotation, c.friction_coefficient).max()), t[k]))
            full = contact_geometry_points(lay.robot, c.frame)
            if full is not None:
                p = center_of_pressure(c.points_in_frame, fk[None], c.rotation, min_normal=tol_n)
                viol = cop_violation(p, (full[:, 0].min(), full[:, 0].max()), (full[:, 1].min(), full[:, 1].max()))
                cop.setdefault(c.frame, []).append((float(viol[0]), t[k]))
    for frame, rows in friction.items():
        worst(f"{frame} friction cone", rows, tol_n, "N")
    for frame, rows in cop.items():
        worst(f"{frame} centre of pressure in the sole", rows, position_tolerance, "m")
    worst("no contact force without contact", idle, 0.0, "N")
    model, data = lay.robot.model, lay.robot.data()
    depth = []
    sole = lay.robot.profile.sole
    by_knot: dict[int, list[tuple[int, int]]] = {}
    for k, fid, i in corner_rows:
        by_knot.setdefault(k, []).append((fid, i))
    for k, rows in by_knot.items():
        pin.framesForwardKinematics(model, data, q[k])
        for fid, i in rows:
            side = lay.robot.foot_side(model.frames[fid].name)
            x, y = sole.corners(side)[i]
            z = float((data.oMf[fid].act(np.array([x, y, 0.0])))[2])
            depth.append((-z, t[k]))
    worst("swing sole corners above the ground", depth, position_tolerance, "m")
    return checks


def dynamic_plan_checks(lay: DynamicLayout, q: np.ndarray, com: np.ndarray, forces: np.ndarray | None,
                        checks: Sequence[ConstraintCheck], settings: Any) -> list[ConstraintCheck]:
    """The report of a dynamic plan: the kinematic checks with the support polygon taken at rest
    (the last knot), plus the dynamic checks (:func:`dynamic_checks`).

    Args:
        lay: The dynamic layout.
        q: Configurations (N+1, nq).
        com: CoM per knot (N+1, 3) [m].
        forces: Solution values of the force variables (None: none available).
        checks: The kinematic report (``planner.diagnose.check_plan``).
        settings: ``PlannerSettings`` (``polygon_tolerance`` [m]).

    Returns:
        The checks.
    """
    out = [c for c in checks if not (c.name.startswith("CoM bound") and c.name.endswith("support polygon"))]
    out += rest_polygon_checks(lay, com, settings.polygon_tolerance)
    if forces is not None:
        out += dynamic_checks(lay, q, com, lay.pattern(), lay.corner_rows(), forces,
                              force_tolerance=lay.centroidal_settings.force_tolerance,
                              position_tolerance=settings.polygon_tolerance)
    return out


def diagnose_dynamic(lay: Any, failed: Any) -> str:
    """Explain a failed dynamic plan in task terms: the worst violated group, when, in which phase."""
    spec = lay.spec
    status = failed.stats.status.value
    bad = sorted((c for c in failed.checks if not c.ok), key=lambda c: -(c.violation / max(c.tolerance, 1e-12)))
    if not bad:
        return (f"the solver stopped: {status} ({failed.stats.raw_status}) after {failed.stats.iterations} "
                "iterations, with every checked constraint met")
    c = bad[0]
    phase = spec.phases[spec.phase_at(c.time)].name
    text = (f"{c.name} violated by {c.violation:.3g} {c.unit} at t = {c.time:.2f} s in phase {phase!r} ({status})")
    hints = {
        "friction": "the feet would slip: ask for shorter or slower steps",
        "CoM dynamics": "the contact forces cannot move the body as planned: ask for a slower motion",
        "velocity": "the joints would move faster than their limits: ask for a slower or smaller motion",
        "CoM target": "the centre of mass cannot reach the target in time",
    }
    for key, hint in hints.items():
        if key in c.name:
            text += f"; {hint}"
            break
    if len(bad) > 1:
        text += "; also " + ", ".join(f"{b.name} ({b.violation:.2g} {b.unit})" for b in bad[1:4])
    return text


def contact_geometry_points(robot: Robot, frame: str) -> np.ndarray | None:
    """The full (unshrunk) sole rectangle corners (4, 2) of a foot frame in its frame, None otherwise."""
    side = robot.foot_side(frame)
    if side is None:
        return None
    return np.array(robot.profile.sole.corners(side), dtype=float)


__all__ = [
    "DYNAMIC_FORMULATION",
    "GRAVITY",
    "CentroidalSettings",
    "CentroidalFunction",
    "CentroidalPattern",
    "CentroidalTerms",
    "ConstraintBlock",
    "ContactGeometry",
    "DynamicBlocks",
    "DynamicLayout",
    "angular_momentum_rate",
    "build_centroidal",
    "build_centroidal_for_spec",
    "center_of_pressure",
    "centroidal_function",
    "centroidal_pattern",
    "com_acceleration",
    "com_dynamics_residual",
    "com_rows",
    "forces_of",
    "contact_geometry",
    "contact_geometry_points",
    "contacts_per_knot",
    "dynamic_blocks",
    "diagnose_dynamic",
    "dynamic_checks",
    "dynamic_plan_checks",
    "dynamic_sizes",
    "extend_nlp",
    "extend_bounds",
    "extend_parameters",
    "initial_guess",
    "rest_polygon_checks",
    "to_dynamic_layout",
    "layout_contacts",
    "cop_violation",
    "friction_pyramid",
    "friction_violation",
    "heading_guess",
    "pyramid_edges",
    "sole_corner_heights",
    "stage_hessians",
    "swinging_corners",
]
