"""Assembly over a knot grid: the force variables, their bounds and rows (the sparsity pattern and
its numbers, :class:`CentroidalPattern`), and the CasADi terms (:func:`build_centroidal`,
:func:`centroidal_function`)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import casadi as ca
import numpy as np

from planner.exceptions import PlannerError
from planner.trajopt.centroidal.contacts import (
    ContactGeometry,
    _geometry_values,
    contacts_per_knot,
    layout_contacts,
)
from planner.trajopt.centroidal.physics import (
    GRAVITY,
    angular_momentum_rate,
    com_acceleration,
    friction_pyramid,
    pyramid_edges,
)
from planner.trajopt.centroidal.settings import CentroidalSettings
from planner.trajopt.layout_data import LayoutData
from robots import Robot
from tasks import TaskSpec

# ---------------------------------------------------------------------------------------------
# Assembly over a knot grid
# ---------------------------------------------------------------------------------------------


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


class _ForceReadout:
    """Force readout shared by :class:`CentroidalTerms` and :class:`CentroidalPattern`."""

    __slots__ = ()
    lower: np.ndarray
    weight: float
    force_index: tuple[Mapping[str, np.ndarray], ...]
    generators: tuple[Mapping[str, np.ndarray], ...]
    frames: tuple[str, ...]

    @property
    def n_variables(self) -> int:
        """Number of force variables."""
        return int(self.lower.shape[0])

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


@dataclass(frozen=True, slots=True, kw_only=True)
class CentroidalTerms(_ForceReadout):
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

    def g(self) -> tuple[Any, np.ndarray, np.ndarray]:
        """All constraint rows stacked: (expr, lower, upper)."""
        if not self.constraints:
            return ca.DM.zeros(0, 1), np.zeros(0), np.zeros(0)
        return (
            ca.vertcat(*[b.expr for b in self.constraints]),
            np.concatenate([b.lower for b in self.constraints]),
            np.concatenate([b.upper for b in self.constraints]),
        )


@dataclass(frozen=True, slots=True, kw_only=True)
class CentroidalPattern(_ForceReadout):
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


def _ankle_bounds(c: ContactGeometry, settings: CentroidalSettings, weight: float) -> np.ndarray:
    """Bounds (n,) of a contact's ankle-torque rows: ``ankle_torque_margin`` x each ankle joint's
    effort limit, in body weights x m (the rows' unit); empty without ankle rows."""
    if settings.ankle_torque_margin is None:
        return np.zeros(0)
    return np.array([settings.ankle_torque_margin * a.effort / weight for a in c.ankle])


def _structure(settings: CentroidalSettings, per_knot: list) -> tuple:
    return (settings.inner_pyramid, settings.angular_momentum_weight > 0.0,
            "edges" if settings.friction_edges else "components",
            "whole-body momentum" if settings.whole_body_momentum else "centroidal",
            "lifted moment" if settings.lifts_moment else "moment cost", tuple(per_knot))


def momentum_row_index(blocks: Sequence[ConstraintBlock]) -> np.ndarray:
    """Row indices (3 per dynamics knot, knot order) of the "angular momentum" blocks among ``blocks``."""
    out, offset = [], 0
    for b in blocks:
        n = int(b.expr.shape[0])
        if b.name == "angular momentum":
            out += list(range(offset, offset + n))
        offset += n
    return np.asarray(out, dtype=int)


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
        ankle = [_ankle_bounds(c, settings, weight) for c in active]
        structure.append((k, tuple((c.frame, c.n_points, len(a)) for c, a in zip(active, ankle, strict=True))))
        for c, bound in zip(active, ankle, strict=True):
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
            pvals.append(_geometry_values(c, ankle=len(bound) > 0))
            if not settings.friction_edges:
                lbg.append(np.zeros(5 * m))
                ubg.append(np.full(5 * m, np.inf))
            lbg.append(-bound)
            ubg.append(bound)
        lbg.append(np.zeros(3))
        ubg.append(np.zeros(3))
        if settings.whole_body_momentum:  # the angular-momentum rows (planner.trajopt.centroidal.momentum)
            lbg.append(np.zeros(3))
            ubg.append(np.zeros(3))
    def cat(xs: list) -> np.ndarray:
        return np.concatenate(xs) if xs else np.zeros(0)

    return CentroidalPattern(
        lower=cat(lower), upper=cat(upper), initial=cat(initial), parameter_values=cat(pvals),
        lbg=cat(lbg), ubg=cat(ubg), weight=weight, contacts=tuple(tuple(c) for c in contacts),
        force_index=tuple(index), generators=tuple(gens), frames=tuple(frames),
        dynamics_knots=tuple(range(1, T - 1)), structure=_structure(settings, structure),
    )


class _ContactBlock(NamedTuple):
    u: Any  # the force variables (b per point)
    prm: Any  # the contact's parameters: points, rotation, friction, ankle levers
    rows: list[ConstraintBlock]  # friction (without edges) and ankle torque rows
    points: list[Any]  # contact points (world) [m]
    forces: list[Any]  # their forces [body weights]


def _contact_block(c: ContactGeometry, bound: np.ndarray, k: int, settings: CentroidalSettings,
                   symbol: type[ca.SX] | type[ca.MX]) -> _ContactBlock:
    """One active contact at knot ``k``: its force variables and parameters, the force at each of
    its points (pyramid edges or a 3D force), its friction rows and the torque rows of the ankle
    axes it loads (``bound``: their limits)."""
    edges = settings.friction_edges
    b = 4 if edges else 3
    m = c.n_points
    n_a = len(bound)
    u = symbol.sym(f"u_{c.frame}_{k}", b * m)
    prm = symbol.sym(f"contact_{c.frame}_{k}", 3 * m + 10 + 3 * m * n_a)
    R = ca.reshape(prm[3 * m : 3 * m + 9], 3, 3)
    E = pyramid_edges(R, prm[3 * m + 9], inner=settings.inner_pyramid) if edges else None
    E_local = pyramid_edges(ca.DM.eye(3), prm[3 * m + 9], inner=settings.inner_pyramid) if edges and n_a else None
    rows, points, forces = [], [], []
    for i in range(m):
        if edges:
            f_i = ca.mtimes(E, u[4 * i : 4 * i + 4])
        else:
            f_i = u[3 * i : 3 * i + 3]
            rows.append(friction_pyramid(f_i, R, prm[3 * m + 9], inner=settings.inner_pyramid))
        points.append(prm[3 * i : 3 * i + 3])
        forces.append(f_i)
    blocks = []
    if rows:
        expr = ca.vertcat(*rows)
        blocks.append(ConstraintBlock(
            name=f"friction {c.frame}", knot=k, expr=expr,
            lower=np.zeros(expr.shape[0]), upper=np.full(expr.shape[0], np.inf),
        ))
    if n_a:
        # moment of the corner forces about each ankle axis, in the sole frame: sum_i l_ji . R^T f_i
        # with the levers l_ji = a_j x (r_i - o_j) as parameters (fixed per robot and foot)
        levers = prm[3 * m + 10:]
        if edges:
            local = [ca.mtimes(E_local, u[4 * i: 4 * i + 4]) for i in range(m)]
        else:
            local = [ca.mtimes(R.T, f) for f in forces]
        expr = ca.vertcat(*[sum(ca.dot(levers[3 * (j * m + i): 3 * (j * m + i) + 3], local[i])
                                for i in range(m)) for j in range(n_a)])
        blocks.append(ConstraintBlock(name=f"ankle torque {c.frame}", knot=k, expr=expr,
                                      lower=-bound, upper=bound))
    return _ContactBlock(u, prm, blocks, points, forces)


def _euler_rows(com_k: Any, points: list[Any], forces: list[Any], k: int, dt: Any,
                settings: CentroidalSettings) -> tuple[list[ConstraintBlock], Any]:
    """Euler at knot ``k``: the rows ``-Ldot_k = 0`` of the forces' moment about the CoM (with
    whole-body momentum) and its cost (without, or None)."""
    ldot = angular_momentum_rate(com_k, points, forces) if forces else ca.DM.zeros(3)  # [m x body weights]
    rows = []
    if settings.whole_body_momentum:
        # -Ldot_k here; the NLP adds the whole body's momentum rate (h_{k+1/2} - h_{k-1/2}) / dt
        # to these rows (planner.trajopt.centroidal.momentum): zero when Euler's law holds. With
        # settings.lifts_moment it adds a variable Ldot_k instead, penalized and tied to the rate
        # by rows of its own (planner.trajopt.centroidal.nlp): no cost on the moment here
        rows.append(ConstraintBlock(name="angular momentum", knot=k, expr=-ldot, lower=np.zeros(3), upper=np.zeros(3)))
    if forces and settings.angular_momentum_weight > 0.0 and not settings.lifts_moment:
        return rows, settings.angular_momentum_weight * dt * ca.sumsqr(ldot)
    return rows, None


def _cat(xs: list) -> np.ndarray:
    return np.concatenate(xs) if xs else np.zeros(0)


@dataclass
class _Collected:
    """What :func:`build_centroidal` collects over the knots, in the order of the variables."""

    T: int
    syms: list[Any] = field(default_factory=list)
    psyms: list[Any] = field(default_factory=list)
    pvals: list[np.ndarray] = field(default_factory=list)
    lower: list[np.ndarray] = field(default_factory=list)
    upper: list[np.ndarray] = field(default_factory=list)
    initial: list[np.ndarray] = field(default_factory=list)
    blocks: list[ConstraintBlock] = field(default_factory=list)
    frames: list[str] = field(default_factory=list)
    structure: list[tuple] = field(default_factory=list)
    dyn_knots: list[int] = field(default_factory=list)
    cost: Any = 0
    n: int = 0
    index: list[dict[str, np.ndarray]] = field(init=False)
    gens: list[dict[str, np.ndarray]] = field(init=False)

    def __post_init__(self) -> None:
        self.index = [{} for _ in range(self.T)]
        self.gens = [{} for _ in range(self.T)]

    def add(self, c: ContactGeometry, k: int, block: _ContactBlock, b: int, box: tuple, values: np.ndarray,
            generator: np.ndarray) -> None:
        """A contact's variables (``b`` per point), bounds, guess, parameters and rows at knot ``k``."""
        if c.frame not in self.frames:
            self.frames.append(c.frame)
        m = c.n_points
        self.syms.append(block.u)
        self.psyms.append(block.prm)
        self.pvals.append(values)
        self.index[k][c.frame] = np.arange(self.n, self.n + b * m).reshape(m, b)
        self.gens[k][c.frame] = generator
        self.n += b * m
        lo, hi, guess = box
        self.lower.append(lo)
        self.upper.append(hi)
        self.initial.append(guess)
        self.blocks += block.rows

    def terms(self, symbol: type[ca.SX] | type[ca.MX], weight: float,
              contacts: Sequence[Sequence[ContactGeometry]], settings: CentroidalSettings) -> CentroidalTerms:
        return CentroidalTerms(
            variables=ca.vertcat(*self.syms) if self.syms else symbol(0, 1),
            lower=_cat(self.lower),
            upper=_cat(self.upper),
            initial=_cat(self.initial),
            parameters=ca.vertcat(*self.psyms) if self.psyms else symbol(0, 1),
            parameter_values=_cat(self.pvals),
            constraints=tuple(self.blocks),
            cost=self.cost,
            weight=weight,
            contacts=tuple(tuple(c) for c in contacts),
            force_index=tuple(self.index),
            generators=tuple(self.gens),
            frames=tuple(self.frames),
            dynamics_knots=tuple(self.dyn_knots),
            structure=_structure(settings, self.structure),
        )


def build_centroidal(
    com: Sequence[Any],
    dt: Any,
    contacts: Sequence[Sequence[ContactGeometry]],
    mass: float,
    *,
    settings: CentroidalSettings = CentroidalSettings(),
    gravity: np.ndarray = GRAVITY,
    symbol: type[ca.SX] | type[ca.MX] = ca.SX,
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
    grid = _Collected(T)
    edges = settings.friction_edges
    b = 4 if edges else 3
    # edges: 4 |u_p|^2 equals |f|^2 for a force along the normal split evenly over the edges
    force_weight = settings.force_weight * (4.0 if edges else 1.0)
    for k in range(1, T - 1):
        active = contacts[k]
        n_points = sum(c.n_points for c in active)
        ankle = [_ankle_bounds(c, settings, weight) for c in active]
        grid.structure.append((k, tuple((c.frame, c.n_points, len(a)) for c, a in zip(active, ankle, strict=True))))
        total = ca.DM.zeros(3)
        points, forces = [], []
        for c, bound in zip(active, ankle, strict=True):
            block = _contact_block(c, bound, k, settings, symbol)
            grid.add(c, k, block, b, _force_box(c, n_points, settings), _geometry_values(c, ankle=len(bound) > 0),
                     _generator(c, settings))
            for f_i in block.forces:
                total = total + f_i
            points += block.points
            forces += block.forces
            grid.cost = grid.cost + force_weight * dt * ca.sumsqr(block.u)
        acc = com_acceleration(com[k - 1], com[k], com[k + 1], dt)
        residual = (acc / g_norm - ca.DM(g_unit)) - total  # normalized Newton: (c'' - g)/|g| = sum u
        grid.blocks.append(ConstraintBlock(name="CoM dynamics", knot=k, expr=residual, lower=np.zeros(3),
                                           upper=np.zeros(3)))
        grid.dyn_knots.append(k)
        momentum_rows, momentum_cost = _euler_rows(com[k], points, forces, k, dt, settings)
        grid.blocks += momentum_rows
        if momentum_cost is not None:
            grid.cost = grid.cost + momentum_cost
    return grid.terms(symbol, weight, contacts, settings)


def build_centroidal_for_spec(
    spec: TaskSpec,
    robot: Robot,
    t: Sequence[float] | np.ndarray,
    com: Sequence[Any],
    *,
    settings: CentroidalSettings = CentroidalSettings(),
    symbol: type[ca.SX] | type[ca.MX] = ca.SX,
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


def centroidal_function(lay: LayoutData, *, settings: CentroidalSettings = CentroidalSettings(),
                        first_free_knot: int = 2) -> CentroidalFunction:
    """Build :class:`CentroidalFunction` for a :class:`planner.trajopt.layout.Layout`.

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


def swinging_corners(lay: LayoutData, *, first_free_knot: int = 2) -> tuple[tuple[int, int, int], ...]:
    """(knot, foot frame id, corner) of every sole corner of a foot not in contact at a variable knot."""
    feet = [lay.robot.frame_id(f"{s}_foot") for s in ("left", "right")]
    return tuple((k, fid, i) for k in range(first_free_knot, lay.N) for fid in feet
                 if fid not in lay.contacts_at[k] for i in range(4))
