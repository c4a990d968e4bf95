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

Functions work on CasADi ``SX``/``MX`` (and numpy where stated); :func:`build_centroidal`
assembles them over a knot grid into a :class:`CentroidalTerms` record that the NLP builder
concatenates to its own variables, constraints and cost. Numeric checks on a finished plan
(:func:`friction_violation`, :func:`center_of_pressure`, :func:`cop_violation`) use numpy.

Modules, in import order: ``settings``, ``physics`` (the per-knot expressions), ``contacts``
(contact geometry), ``pattern`` (assembly over the knot grid: the sparsity pattern and the CasADi
terms), ``heading`` (the chart's heading guess), ``data`` (:class:`DynamicData`: a layout's data
with these parts, what the modules after it take), ``nlp`` (the extension of the kinematic NLP),
``guess`` (initial guess), ``checks`` (numeric checks of a plan), ``diagnose``, ``layout``
(:class:`DynamicLayout`, the formulation).
Every public name is also importable from this package (on first access).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from robots import lazy_face

if TYPE_CHECKING:
    from planner.trajopt.centroidal.checks import (
        center_of_pressure,
        cop_violation,
        dynamic_checks,
        dynamic_plan_checks,
        friction_violation,
        rest_polygon_checks,
    )
    from planner.trajopt.centroidal.contacts import (
        ContactGeometry,
        contact_geometry,
        contact_geometry_points,
        contacts_per_knot,
        layout_contacts,
    )
    from planner.trajopt.centroidal.data import DynamicData
    from planner.trajopt.centroidal.diagnose import diagnose_dynamic
    from planner.trajopt.centroidal.guess import forces_of, initial_guess
    from planner.trajopt.centroidal.heading import heading_guess
    from planner.trajopt.centroidal.layout import (
        DYNAMIC_FORMULATION,
        DynamicLayout,
        to_dynamic_layout,
    )
    from planner.trajopt.centroidal.nlp import (
        SWING_CLEARANCE,
        DynamicBlocks,
        com_rows,
        dynamic_blocks,
        dynamic_sizes,
        extend_bounds,
        extend_nlp,
        extend_parameters,
        sole_corner_heights,
        stage_hessians,
        swing_corner_floor,
    )
    from planner.trajopt.centroidal.pattern import (
        CentroidalFunction,
        CentroidalPattern,
        CentroidalTerms,
        ConstraintBlock,
        build_centroidal,
        build_centroidal_for_spec,
        centroidal_function,
        centroidal_pattern,
        swinging_corners,
    )
    from planner.trajopt.centroidal.physics import (
        GRAVITY,
        angular_momentum_rate,
        com_acceleration,
        com_dynamics_residual,
        friction_pyramid,
        pyramid_edges,
    )
    from planner.trajopt.centroidal.settings import CentroidalSettings

_EXPORTS = {  # public name -> module that defines it
    "GRAVITY": "planner.trajopt.centroidal.physics",
    "angular_momentum_rate": "planner.trajopt.centroidal.physics",
    "com_acceleration": "planner.trajopt.centroidal.physics",
    "com_dynamics_residual": "planner.trajopt.centroidal.physics",
    "friction_pyramid": "planner.trajopt.centroidal.physics",
    "pyramid_edges": "planner.trajopt.centroidal.physics",
    "CentroidalSettings": "planner.trajopt.centroidal.settings",
    "ContactGeometry": "planner.trajopt.centroidal.contacts",
    "contact_geometry": "planner.trajopt.centroidal.contacts",
    "contact_geometry_points": "planner.trajopt.centroidal.contacts",
    "contacts_per_knot": "planner.trajopt.centroidal.contacts",
    "layout_contacts": "planner.trajopt.centroidal.contacts",
    "CentroidalFunction": "planner.trajopt.centroidal.pattern",
    "CentroidalPattern": "planner.trajopt.centroidal.pattern",
    "CentroidalTerms": "planner.trajopt.centroidal.pattern",
    "ConstraintBlock": "planner.trajopt.centroidal.pattern",
    "build_centroidal": "planner.trajopt.centroidal.pattern",
    "build_centroidal_for_spec": "planner.trajopt.centroidal.pattern",
    "centroidal_function": "planner.trajopt.centroidal.pattern",
    "centroidal_pattern": "planner.trajopt.centroidal.pattern",
    "swinging_corners": "planner.trajopt.centroidal.pattern",
    "DynamicBlocks": "planner.trajopt.centroidal.nlp",
    "SWING_CLEARANCE": "planner.trajopt.centroidal.nlp",
    "com_rows": "planner.trajopt.centroidal.nlp",
    "dynamic_blocks": "planner.trajopt.centroidal.nlp",
    "dynamic_sizes": "planner.trajopt.centroidal.nlp",
    "extend_bounds": "planner.trajopt.centroidal.nlp",
    "extend_nlp": "planner.trajopt.centroidal.nlp",
    "extend_parameters": "planner.trajopt.centroidal.nlp",
    "sole_corner_heights": "planner.trajopt.centroidal.nlp",
    "stage_hessians": "planner.trajopt.centroidal.nlp",
    "swing_corner_floor": "planner.trajopt.centroidal.nlp",
    "DYNAMIC_FORMULATION": "planner.trajopt.centroidal.layout",
    "DynamicData": "planner.trajopt.centroidal.data",
    "DynamicLayout": "planner.trajopt.centroidal.layout",
    "to_dynamic_layout": "planner.trajopt.centroidal.layout",
    "forces_of": "planner.trajopt.centroidal.guess",
    "heading_guess": "planner.trajopt.centroidal.heading",
    "initial_guess": "planner.trajopt.centroidal.guess",
    "center_of_pressure": "planner.trajopt.centroidal.checks",
    "cop_violation": "planner.trajopt.centroidal.checks",
    "dynamic_checks": "planner.trajopt.centroidal.checks",
    "dynamic_plan_checks": "planner.trajopt.centroidal.checks",
    "friction_violation": "planner.trajopt.centroidal.checks",
    "rest_polygon_checks": "planner.trajopt.centroidal.checks",
    "diagnose_dynamic": "planner.trajopt.centroidal.diagnose",
}

__all__ = [  # what `from ... import *` and the TYPE_CHECKING imports above cover
    "DYNAMIC_FORMULATION",
    "GRAVITY",
    "SWING_CLEARANCE",
    "CentroidalFunction",
    "CentroidalPattern",
    "CentroidalSettings",
    "CentroidalTerms",
    "ConstraintBlock",
    "ContactGeometry",
    "DynamicBlocks",
    "DynamicData",
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
    "contact_geometry",
    "contact_geometry_points",
    "contacts_per_knot",
    "cop_violation",
    "diagnose_dynamic",
    "dynamic_blocks",
    "dynamic_checks",
    "dynamic_plan_checks",
    "dynamic_sizes",
    "extend_bounds",
    "extend_nlp",
    "extend_parameters",
    "forces_of",
    "friction_pyramid",
    "friction_violation",
    "heading_guess",
    "initial_guess",
    "layout_contacts",
    "pyramid_edges",
    "rest_polygon_checks",
    "sole_corner_heights",
    "stage_hessians",
    "swing_corner_floor",
    "swinging_corners",
    "to_dynamic_layout",
]


__getattr__, __dir__ = lazy_face(__name__, _EXPORTS)
