"""Pydantic request and response models of the HTTP API (the only place pydantic is used)."""

from __future__ import annotations

import math
from typing import Annotated, Literal

from pydantic import (
    AfterValidator,
    BaseModel,
    ConfigDict,
    Field,
    WithJsonSchema,
    model_validator,
)
from pydantic.config import JsonDict

Vector3 = tuple[float, float, float]
Quaternion = tuple[float, float, float, float]


class ErrorDetail(BaseModel):
    code: str = Field(description="stable machine-readable code (not_found, invalid_request, ...)")
    message: str = Field(description="what is wrong, naming the limit when there is one")
    field: str | None = Field(
        default=None, description="the offending field, dotted (start.stand_at), or null"
    )


class ErrorBody(BaseModel):
    """Every error answer (4xx, 5xx): ``{"error": {"code", "message", "field"}}``."""

    error: ErrorDetail


# The domain status of an answer (always HTTP 200); planner.result.PlanStatus's values.
PlanStatusName = Literal[
    "SOLVED", "APPROXIMATE", "INVALID_START", "INVALID_GOAL", "TIMEOUT", "INFEASIBLE"
]
StepStatusName = Literal["SOLVED", "INFEASIBLE"]


def _exactly_one_of(first: str, second: str) -> JsonDict:
    """JSON Schema for "exactly one of two optional fields is given (and not null)"."""
    return {
        "oneOf": [
            {"required": [name], "properties": {name: {"not": {"type": "null"}}}}
            for name in (first, second)
        ]
    }


class Health(BaseModel):
    status: Literal["ok"] = "ok"
    version: str
    characters: int
    scenes: int


class RootPose(BaseModel):
    """Root placement: position in metres (world frame), orientation as [x, y, z, w]."""

    model_config = ConfigDict(frozen=True)

    position: Vector3
    orientation: Quaternion = (0.0, 0.0, 0.0, 1.0)


class Configuration(BaseModel):
    """A whole-body configuration: root pose plus joint values (radians or metres) by name."""

    root: RootPose
    joints: dict[str, float]


class LimbInfo(BaseModel):
    name: str
    root_joint: str
    effector_frame: str
    contact: Literal["point", "patch"]
    half_size: tuple[float, float] = Field(description="half-sizes of the contact patch, metres")
    normal: Vector3 = Field(description="contact normal in the effector frame")
    mu: float = Field(description="default friction coefficient")
    on_request: bool = Field(
        default=False,
        description="used only when a request names it (a sit bone); Twister auto skips it",
    )


class CharacterSummary(BaseModel):
    id: str
    mass: float
    joint_count: int
    limbs: list[str]


class CharacterDetail(BaseModel):
    id: str
    mass: float = Field(description="total mass, kg")
    joints: list[str] = Field(description="joint names in configuration order (root excluded)")
    reference_configuration: Configuration = Field(
        description="standing posture on flat ground at z = 0"
    )
    limbs: list[LimbInfo]
    trunk: list[dict[str, object]] = Field(description="trunk bounding shapes W0, root frame")


class SurfaceInfo(BaseModel):
    id: int
    kind: Literal["support", "lean"]
    normal: Vector3
    area: float = Field(description="square metres")
    centroid: Vector3
    polygons: list[list[Vector3]] = Field(description="boundary loops, world frame, metres")


class SceneSummary(BaseModel):
    id: str
    name: str
    builtin: bool
    triangle_count: int
    surface_count: int


class SceneDetail(BaseModel):
    id: str
    name: str
    builtin: bool
    bounds: tuple[Vector3, Vector3] = Field(description="axis-aligned bounds [min, max], metres")
    triangle_count: int
    surfaces: list[SurfaceInfo]


# -- planning requests and responses --------------------------------------------------------

MAX_TIME_BUDGET_S = 60.0
MAX_COORDINATE = 10_000.0
MAX_SEED = 2**53 - 1  # the largest integer a JSON number carries exactly in JavaScript

Coordinate = Annotated[float, Field(ge=-MAX_COORDINATE, le=MAX_COORDINATE)]
Point3 = tuple[Coordinate, Coordinate, Coordinate]
Seed = Annotated[
    int,
    Field(
        ge=0,
        le=MAX_SEED,
        description="replays the answer bit for bit; at most 2^53 - 1, so that JavaScript and "
        "other JSON readers keeping numbers as doubles replay it exactly",
    ),
]
TimeBudget = Annotated[
    float,
    Field(
        gt=0,
        le=MAX_TIME_BUDGET_S,
        description="seconds of planning, at most 60: they buy the work that decides the "
        "answer (the same on any machine); the clock only caps it (report.clock_cap_hit)",
    ),
]
Rate = Annotated[float, Field(gt=0, le=240, description="keyframes per second")]


def _unit_quaternion(value: Quaternion) -> Quaternion:
    """``value`` scaled to unit length: any finite quaternion but zero has a direction (it is
    scaled by its largest component first, so huge or tiny components neither overflow nor
    underflow)."""
    scale = max(abs(v) for v in value)
    if not math.isfinite(scale) or scale == 0.0:
        raise ValueError("orientation must be a finite, non-zero quaternion [x, y, z, w]")
    scaled = [v / scale for v in value]
    norm = math.sqrt(sum(v * v for v in scaled))
    x, y, z, w = (v / norm for v in scaled)
    return (x, y, z, w)


# An input orientation: any quaternion but zero, normalised on input. The schema says so:
# four numbers, not all zero (JSON Schema's const compares numbers, so -0.0 is zero too).
OrientationIn = Annotated[
    Quaternion,
    AfterValidator(_unit_quaternion),
    WithJsonSchema(
        {
            "type": "array",
            "prefixItems": [{"type": "number"}] * 4,
            "minItems": 4,
            "maxItems": 4,
            "not": {"prefixItems": [{"const": 0}] * 4},
            "description": "quaternion [x, y, z, w], any length but zero (normalised on input)",
        }
    ),
]


class PoseIn(BaseModel):
    """A root pose: position (m, world) and orientation [x, y, z, w] (normalised on input)."""

    model_config = ConfigDict(extra="forbid")

    position: Point3
    orientation: OrientationIn = (0.0, 0.0, 0.0, 1.0)


class EndpointIn(BaseModel):
    """Where a motion starts or ends: exactly one of ``position`` (a root pose, with an
    optional ``orientation``) or ``stand_at`` (a point on the scene where the service finds a
    balanced standing state)."""

    model_config = ConfigDict(
        extra="forbid", json_schema_extra=_exactly_one_of("position", "stand_at")
    )

    position: Point3 | None = None
    orientation: OrientationIn | None = None
    stand_at: Point3 | None = Field(
        default=None, description="a point on the scene; the service finds a standing state"
    )

    @model_validator(mode="after")
    def _one_kind(self) -> EndpointIn:
        if (self.position is None) == (self.stand_at is None):
            raise ValueError("give exactly one of 'position' (with 'orientation') or 'stand_at'")
        return self


class ContactOut(BaseModel):
    limb: str
    points: list[Vector3]
    normal: Vector3
    mu: float
    surface: int


class ContactIn(BaseModel):
    """A limb in contact; its placement is recomputed from the configuration."""

    model_config = ConfigDict(extra="forbid")

    limb: str = Field(max_length=100)
    points: list[Point3] | None = Field(
        default=None, max_length=16, description="as returned; recomputed from the configuration"
    )
    normal: Point3 | None = None
    mu: float | None = Field(default=None, gt=0, le=5)
    surface: int | None = Field(default=None, ge=-1, le=10_000_000)


class ConfigurationIn(BaseModel):
    model_config = ConfigDict(extra="forbid")

    root: PoseIn
    joints: dict[str, Annotated[float, Field(ge=-100, le=100)]] = Field(max_length=500)


class StateIn(BaseModel):
    """A whole-body configuration and the limbs in contact (as an earlier answer returned)."""

    model_config = ConfigDict(extra="forbid")

    configuration: ConfigurationIn
    contacts: list[ContactIn] = Field(max_length=16)


class StateOut(BaseModel):
    configuration: Configuration
    contacts: list[ContactOut]


class PhaseOut(BaseModel):
    t0: float
    t1: float
    contacts: list[ContactOut]


class ComSegmentOut(BaseModel):
    t0: float
    t1: float
    control_points: list[Vector3]


class KeyframeOut(BaseModel):
    t: float
    root: RootPose
    joints: dict[str, float]
    contacts: list[str]


class StepActionIn(BaseModel):
    """One Twister move: create or break a limb's contact, or let the game choose ('auto')."""

    model_config = ConfigDict(
        extra="forbid",
        json_schema_extra={
            # 'create' and 'break' name their limb: the kind is 'auto', or a limb is given.
            "anyOf": [
                {"properties": {"kind": {"const": "auto"}}},
                {"required": ["limb"], "properties": {"limb": {"type": "string"}}},
            ],
            "description": "One Twister move: 'create' or 'break' the contact of 'limb' "
            "(required for both), or 'auto' (the game picks a limb and a move).",
        },
    )

    kind: Literal["create", "break", "auto"]
    limb: str | None = Field(default=None, max_length=100)
    surface: int | None = Field(default=None, ge=0, le=10_000_000)
    target: Point3 | None = None

    @model_validator(mode="after")
    def _limb_needed(self) -> StepActionIn:
        if self.kind in ("create", "break") and self.limb is None:
            raise ValueError(f"action '{self.kind}' needs a 'limb'")
        return self


class OtherCharacterIn(BaseModel):
    """Another character on the mat, posed as given; an obstacle for this step."""

    model_config = ConfigDict(extra="forbid")

    character: str = Field(max_length=100)
    configuration: ConfigurationIn


MIN_SPEED, MAX_SPEED = 0.25, 3.0  # planner.motion.sequence's bounds on options.speed
TransitionCostKind = Literal["distance", "tired", "groovy", "to_one_side", "low"]


class AttractorIn(BaseModel):
    """A transition point placed by the user (2PAC section 7.3): where the COM passes when
    phase change ``transition`` happens (0 is the first contact change of the plan)."""

    model_config = ConfigDict(extra="forbid")

    transition: int = Field(ge=0, le=10_000)
    point: Point3


class TimingOptionsIn(BaseModel):
    """How the COM of a plan or a Twister step is timed (2PAC sections 6.4, 7.3)."""

    model_config = ConfigDict(extra="forbid")

    speed: float = Field(
        default=1.0,
        ge=MIN_SPEED,
        le=MAX_SPEED,
        description="factor on the nominal pace of the COM and of the swings; "
        "the report's dynamic_validity says how physical the result is",
    )
    attractors: list[AttractorIn] = Field(
        default_factory=list,
        max_length=64,
        description="user-placed transition points; each is honoured when balanced and "
        "reachable for both phases, else refused (report.attractors says why)",
    )


class TwisterStepRequest(BaseModel):
    """One Twister move from exactly one of ``state`` (an earlier answer's) or ``stand_at``."""

    model_config = ConfigDict(
        extra="forbid",
        json_schema_extra={
            **_exactly_one_of("state", "stand_at"),
            "examples": [
                {
                    "character": "quadruped",
                    "scene": "twister",
                    "stand_at": [0, 0, 0],
                    "action": {"kind": "break", "limb": "lf_foot"},
                    "seed": 3,
                }
            ],
        },
    )

    character: str = Field(max_length=100)
    scene: str = Field(max_length=128)
    state: StateIn | None = Field(default=None, description="current state; or use stand_at")
    stand_at: Point3 | None = Field(default=None, description="start standing at this point")
    yaw: float | None = Field(
        default=None,
        ge=-7.0,
        le=7.0,
        description="rad, heading of the stand_at state (about +z; default: any that stands)",
    )
    action: StepActionIn
    others: list[OtherCharacterIn] = Field(default_factory=list, max_length=8)
    surfaces: list[Annotated[int, Field(ge=0)]] | None = Field(
        default=None,
        max_length=10_000,
        description="surface ids contacts may use (default: every Support surface)",
    )
    seed: Seed | None = None
    time_budget_s: TimeBudget = 5.0
    rate: Rate = 30.0
    options: TimingOptionsIn = Field(
        default_factory=TimingOptionsIn,
        description="timing of the step's motion, as for a plan (its one transition is 0; "
        "the transition point is the new state's COM unless an attractor moves it)",
    )

    @model_validator(mode="after")
    def _state_or_stand(self) -> TwisterStepRequest:
        if (self.state is None) == (self.stand_at is None):
            raise ValueError("give exactly one of 'state' or 'stand_at'")
        if self.yaw is not None and self.stand_at is None:
            raise ValueError("'yaw' goes with 'stand_at' (a state has its own heading)")
        return self


class FailureOut(BaseModel):
    reason: str
    message: str
    limb: str | None = None


class TwisterStepResponse(BaseModel):
    id: str = Field(
        default="", description="content id of this answer: GET it again as JSON or as .glb"
    )
    status: StepStatusName = Field(description="INFEASIBLE: see failure; the state is unchanged")
    seed: int
    state: StateOut
    phases: list[PhaseOut]
    com: list[ComSegmentOut]
    keyframes: list[KeyframeOut]
    failure: FailureOut | None = None
    report: dict[str, object] = Field(
        description="the attempts made and how the motion came out; clock_cap_hit: the "
        "wall-clock cap stopped 'auto' before it had tried every limb (a replay may differ)"
    )
    timings: dict[str, float]


class RoadmapRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    character: str = Field(max_length=100)
    scene: str = Field(max_length=128)
    mu: float = Field(default=1.0, gt=0, le=5)
    vmax_takeoff: float = Field(default=6.0, gt=0, le=50, description="m/s")
    vmax_landing: float = Field(default=8.0, gt=0, le=50, description="m/s")
    nodes: int = Field(default=500, ge=2, le=10_000)
    seed: Seed = 0


JobStateName = Literal["queued", "running", "done", "failed", "cancelled", "interrupted"]


class RoadmapStatus(BaseModel):
    id: str
    status: JobStateName
    progress: float = Field(ge=0, le=1)
    nodes: int = 0
    edges: int = 0
    message: str = ""
    seconds: float = 0.0


class JumpContactOut(BaseModel):
    limb: str
    point: Vector3
    normal: Vector3
    mu: float


class JumpEndOut(BaseModel):
    position: Vector3 = Field(
        description="the centre of mass (not the root), m, world frame, when the contacts "
        "break (takeoff) or are made (landing): the flight is the COM's parabola "
        "position + velocity t + g t^2 / 2"
    )
    velocity: Vector3 = Field(description="the centre of mass's velocity, m/s")
    contacts: list[JumpContactOut]


class JumpOut(BaseModel):
    takeoff: JumpEndOut
    landing: JumpEndOut
    apex: Vector3 = Field(description="the centre of mass's highest point, m")
    duration: float = Field(description="flight time, s")
    t_start: float = Field(default=0.0, description="s: the crouch before the push begins")
    push_start: float = Field(default=0.0, description="s: the COM leaves rest (the push)")
    takeoff_time: float = Field(default=0.0, description="s: the contacts break")
    landing_time: float = Field(default=0.0, description="s: the landing contacts are made")
    rest_time: float = Field(default=0.0, description="s: the landing has stopped the COM")


class JumpRequest(BaseModel):
    model_config = ConfigDict(
        extra="forbid",
        json_schema_extra={
            "examples": [
                {
                    "character": "quadruped",
                    "scene": "gaps",
                    "start": {"stand_at": [0.75, 0, 0.6]},
                    "goal": {"stand_at": [8.25, 0, 1.0]},
                    "nodes": 300,
                    "seed": 2,
                }
            ]
        },
    )

    character: str = Field(max_length=100)
    scene: str = Field(max_length=128)
    start: EndpointIn
    goal: EndpointIn
    roadmap: str | None = Field(default=None, max_length=128)
    mu: float = Field(default=1.0, gt=0, le=5)
    vmax_takeoff: float = Field(default=6.0, gt=0, le=50)
    vmax_landing: float = Field(default=8.0, gt=0, le=50)
    nodes: int = Field(default=300, ge=2, le=10_000, description="roadmap size when building")
    seed: Seed | None = None
    time_budget_s: TimeBudget = 10.0
    rate: Rate = 30.0


class JumpResponse(BaseModel):
    id: str = Field(
        default="", description="content id of this answer: GET it again as JSON or as .glb"
    )
    status: PlanStatusName
    seed: int
    jumps: list[JumpOut]
    keyframes: list[KeyframeOut]
    phases: list[PhaseOut] = Field(default_factory=list, description="flights hold no contact")
    com: list[ComSegmentOut] = Field(
        default_factory=list, description="COM curve; the flights are the jumps' parabolas"
    )
    report: dict[str, object] = Field(
        default_factory=dict, description="the whole-body motion builder's report, as plans'"
    )
    roadmap: str | None = None
    message: str = ""
    timings: dict[str, float]


MAX_PITCH = 0.8  # rad, planner.character.MAX_PITCH (clients import this module, not planner)


class PlanOptionsIn(TimingOptionsIn):
    """Tuning of a contact plan; every field has a bound."""

    model_config = ConfigDict(extra="forbid")

    transition_cost: TransitionCostKind = Field(
        default="tired",
        description="how transition points are chosen (2PAC 7.3): distance (closest to the "
        "previous), tired (least travel over both neighbours), groovy (alternating "
        "sideways), to_one_side, low (COM as low as possible)",
    )
    cost_strength: float = Field(
        default=0.3, ge=0, le=2.0, description="m, weight of the groovy/to_one_side/low terms"
    )
    overlap_swings: bool = Field(
        default=True,
        description="a walker on four legs or more lifts its next leg before the last one "
        "lands, on level ground where the dynamics allow (report.overlapped_swings counts "
        "the pairs); false swings one leg at a time",
    )

    rate: Rate = 30.0
    margin: float = Field(default=1.0, ge=0, le=1000, description="equilibrium robustness, N")
    lookahead: float | None = Field(
        default=None,
        gt=0,
        le=2.0,
        description="m ahead of the body where footholds are aimed (default: a third of the "
        "leg length on open ground, 0.15 m on steps, rocks and slopes)",
    )
    max_states: int = Field(default=200, ge=2, le=2000)
    max_pitch: float | None = Field(
        default=None,
        ge=0,
        le=MAX_PITCH,
        description="rad the trunk may pitch (default: the character's; a hexapod climbing "
        "steps lies along them)",
    )
    limbs: list[Annotated[str, Field(max_length=100)]] = Field(
        default_factory=list,
        max_length=16,
        description="limbs the walk may use besides those of the start and goal (a hand on a rail)",
    )


class PlanRequest(BaseModel):
    model_config = ConfigDict(
        extra="forbid",
        populate_by_name=True,
        json_schema_extra={
            "examples": [
                {
                    "character": "humanoid",
                    "scene": "flat",
                    "start": {"stand_at": [0, 0, 0]},
                    "goal": {"stand_at": [1.5, 0, 0]},
                    "seed": 1,
                    "time_budget_s": 10,
                }
            ]
        },
    )

    character: str = Field(max_length=100)
    scene: str = Field(max_length=128)
    start: EndpointIn
    goal: EndpointIn
    options: PlanOptionsIn = Field(default_factory=PlanOptionsIn)
    seed: Seed | None = None
    time_budget_s: TimeBudget = 10.0
    run_async: bool = Field(
        default=False,
        alias="async",
        exclude=True,  # how the answer is delivered, not what it is: not in the result id
        description="true: answer 202 at once with a job (Location: /v1/jobs/{id}) that runs "
        "in the background lane; its budget counts from when it starts",
    )


class JobResult(BaseModel):
    """What a finished job made: a stored plan, or a roadmap."""

    kind: Literal["plan", "roadmap"]
    id: str
    url: str = Field(description="where to GET it")
    status: PlanStatusName | None = Field(default=None, description="a plan's status")


class JobStatus(BaseModel):
    """A job (roadmap build or asynchronous plan), as any service worker reads it."""

    id: str
    kind: Literal["plan", "roadmap"]
    status: JobStateName = Field(
        description="queued, running, done, failed, cancelled (a DELETE) or interrupted "
        "(the service stopped while it ran: submit it again)"
    )
    progress: float = Field(ge=0, le=1)
    message: str = ""
    result: JobResult | None = None
    created_at: float = Field(description="Unix time, s")
    started_at: float | None = Field(default=None, description="Unix time, s")
    finished_at: float | None = Field(default=None, description="Unix time, s")


class PlanResponse(BaseModel):
    id: str = Field(
        default="", description="content id of this answer: GET it again as JSON or as .glb"
    )
    status: PlanStatusName = Field(
        description="SOLVED, APPROXIMATE (a partial plan, kept), INVALID_START, INVALID_GOAL, "
        "TIMEOUT or INFEASIBLE"
    )
    seed: int
    message: str = ""
    phases: list[PhaseOut]
    com: list[ComSegmentOut]
    keyframes: list[KeyframeOut]
    states: list[StateOut]
    report: dict[str, object] = Field(
        description="how the motion came out; clock_cap_hit: the wall-clock cap, not the "
        "work the time budget buys, stopped the plan (a replay may then differ)"
    )
    timings: dict[str, float]


class ResultSummary(BaseModel):
    """A stored result, as listed by ``GET /v1/results``."""

    id: str
    kind: Literal["plan", "step", "jump"]
    character: str | None = None
    scene: str | None = None
    status: PlanStatusName | None = None
    seed: int | None = None
    keyframes: int = Field(default=0, description="number of keyframes")
    duration: float = Field(default=0.0, description="time of the last keyframe, s")
    stored_at: float = Field(description="Unix time the result was stored")
