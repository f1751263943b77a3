"""Gecko trajectory: static equilibrium, transition points and 2PAC COM trajectories.

Pure maths over float64 numpy arrays (SI units, world frame z up, gravity (0, 0, -9.81)).
"""

from trajectory.bezier import BezierCurve, PiecewiseBezier, bernstein, concatenate
from trajectory.com import (
    BoundaryState,
    ComTrajectory,
    PhaseReport,
    attractor_curve,
    multi_attractor_curve,
    plan_com_trajectory,
    polyline_parametrisation,
    quasi_static_polyline,
    validate_dynamics,
    weierstrass_curve,
)
from trajectory.contacts import Contact, ContactPhase, friction_rays, tangent_basis
from trajectory.dynamic import (
    DynamicCom,
    DynamicOutcome,
    DynamicSettings,
    dynamic_com,
    solve_dynamic_com,
)
from trajectory.equilibrium import (
    EQ1_TOLERANCE,
    EquilibriumMargin,
    equilibrium_halfspaces,
    equilibrium_margin,
    equilibrium_polygon,
    equilibrium_polytope,
    holds_at,
    is_static_equilibrium,
)
from trajectory.kinematics import EffectorConstraint, kinematic_polytope, to_world
from trajectory.polytope import Halfspaces, stack
from trajectory.transition import (
    TransitionCost,
    TransitionPoint,
    check_transition_point,
    transition_point,
    transition_qp,
    transition_qp_generators,
)

__all__ = [
    "EQ1_TOLERANCE",
    "BezierCurve",
    "BoundaryState",
    "ComTrajectory",
    "Contact",
    "ContactPhase",
    "DynamicCom",
    "DynamicOutcome",
    "DynamicSettings",
    "EffectorConstraint",
    "EquilibriumMargin",
    "Halfspaces",
    "PhaseReport",
    "PiecewiseBezier",
    "TransitionCost",
    "TransitionPoint",
    "attractor_curve",
    "bernstein",
    "check_transition_point",
    "concatenate",
    "dynamic_com",
    "equilibrium_halfspaces",
    "equilibrium_margin",
    "equilibrium_polygon",
    "equilibrium_polytope",
    "friction_rays",
    "holds_at",
    "is_static_equilibrium",
    "kinematic_polytope",
    "multi_attractor_curve",
    "plan_com_trajectory",
    "polyline_parametrisation",
    "quasi_static_polyline",
    "solve_dynamic_com",
    "stack",
    "tangent_basis",
    "to_world",
    "transition_point",
    "transition_qp",
    "transition_qp_generators",
    "validate_dynamics",
    "weierstrass_curve",
]
