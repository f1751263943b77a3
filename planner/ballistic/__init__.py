"""Ballistic multi-contact jumps: closed-form parabola steering, arcs, cones and the roadmap.

Modules: ``steering`` (batched closed-form steering in t = tan(alpha)), ``arc`` (evaluation,
bounded-gap sampling, trunk collision and the collision-free search over t), ``cones``
(centroidal cone from contacts), ``roadmap`` (directed jump roadmap: build, persist, query),
``synthetic`` (horizontal-platform sampler and sphere-trunk/box collision, for tests and
benchmarks), ``nodes`` (reduced model on a real scene: trunk collision, contact estimate, node
sampling), ``stance`` (whole-body contact configurations at nodes) and ``planner``
(``plan_jumps``, whose keyframes come from ``planner.motion.jump``, and the
``RoadmapStore``: the domain API of the jump endpoints).
"""

from planner.ballistic.cones import CentroidalCone, centroidal_cone, centroidal_cones
from planner.ballistic.planner import (
    JumpContact,
    JumpEnd,
    JumpInfo,
    JumpParams,
    JumpPlan,
    RoadmapStore,
    plan_jumps,
)
from planner.ballistic.roadmap import Roadmap, RoadmapParams
from planner.ballistic.steering import (
    GRAVITY,
    Choice,
    Jump,
    SteerFailure,
    SteerResult,
    SteerTolerances,
    jump_at,
    jumps_at,
    min_launch_speed_sq,
    range_prefilter,
    steer,
    verify_jumps,
)

__all__ = [
    "GRAVITY",
    "CentroidalCone",
    "Choice",
    "Jump",
    "JumpContact",
    "JumpEnd",
    "JumpInfo",
    "JumpParams",
    "JumpPlan",
    "Roadmap",
    "RoadmapParams",
    "RoadmapStore",
    "SteerFailure",
    "SteerResult",
    "SteerTolerances",
    "centroidal_cone",
    "centroidal_cones",
    "jump_at",
    "jumps_at",
    "min_launch_speed_sq",
    "plan_jumps",
    "range_prefilter",
    "steer",
    "verify_jumps",
]
