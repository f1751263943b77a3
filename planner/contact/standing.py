"""Balanced standing states: the ground limbs of ``q_ref`` put by IK on the Support surfaces.

``state_from_root_pose`` keeps a given root pose and projects each ground limb (the limbs
touching the ground in ``q_ref``) onto the Support surface below its reference contact;
``standing_state`` searches root poses above a point of the scene (as a game engine with a
navigation mesh asks). A state is accepted when every IK converged, the contact points lie on
their surfaces (within ``CONTACT_TOLERANCE`` of the plane, inside the polygons) with aligned
normals, the joints are within limits, the trunk W0 and the body are collision-free (the
contacting foot geometry excepted), the body is free of self-collision, the root pose meets
the reachability condition and the COM is in static equilibrium with a robustness margin.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from planner.character import Character, Limb
from planner.contact.body import (
    body_geometry,
    contact_placement,
    contact_points,
    lies_on,
    lifted_geometries,
    self_collides,
    sphere_centre,
)
from planner.contact.reachability import ReachabilityChecker, ground_limbs
from planner.contact.slope import LEVEL_PITCH, along_slope, body_span, terrain_line
from planner.contact.state import ContactState, LimbContact
from planner.kinematics import (
    FramePositionTask,
    IkResult,
    PostureTask,
    Priority,
    Task,
    limb_dofs,
    project_contact,
    scratch_data,
    solve_ik,
    within_limits,
)
from planner.offline import OfflineData
from planner.poses import matrix_to_quaternion, pose_matrix, yaw_matrix
from planner.result import PlanResult, PlanStatus
from planner.scene import Scene, Surface, SurfaceKind
from planner.shapes import Box
from planner.termination import Termination, never
from trajectory import Contact, ContactPhase, equilibrium_margin

FloatArray = NDArray[np.float64]

CONTACT_TOLERANCE = 0.005
"""Largest distance (m) of a contact point from its surface plane."""
NORMAL_TOLERANCE = 0.02
"""Largest angle (rad) between the effector contact normal and the surface normal."""
GRAVITY = 9.81
_HEADINGS = 16  # root yaws tried, evenly spread, when none is imposed


@dataclass(frozen=True, slots=True)
class StandingParams:
    """Tunables of the standing search.

    margin : required equilibrium robustness as a fraction of the mean generator weight
        (m g / number of friction-cone generators); 0 only asks for static equilibrium.
    attempts : root poses tried by ``standing_state``. jitter : m, standard deviation of the
        sideways root offset after the first attempt. search_height : m, how far above or
        below a reference contact a Support surface is looked for.
    posture_weight : pull of the IK toward ``q_ref`` in [0, 1].
    """

    margin: float = 0.05
    attempts: int = 32
    jitter: float = 0.04
    search_height: float = 0.35
    posture_weight: float = 0.5


def body_collides_scene(
    scene: Scene, character: Character, q: FloatArray, contacts: Sequence[LimbContact] = ()
) -> bool:
    """Whether the character's collision geometry at ``q`` (nq,) touches the scene mesh; the
    shapes carrying ``contacts`` are tested raised by ``CONTACT_LIFT`` along their normal."""
    body = body_geometry(character)
    model = character.model
    data = scratch_data(model)
    pin.forwardKinematics(model, data, np.asarray(q, dtype=np.float64))
    raised = lifted_geometries(character, [(c.limb, c.normal) for c in contacts])
    bvh = scene.collision.bvh
    identity = coal.Transform3s()
    request, result = coal.CollisionRequest(), coal.CollisionResult()
    for g, (parent, geometry, offset) in enumerate(body.objects):
        world = data.oMi[parent] * offset
        position = np.array(world.translation) + raised.get(g, np.zeros(3))
        tf = coal.Transform3s(np.array(world.rotation), position)
        result.clear()
        if coal.collide(bvh, identity, geometry, tf, request, result):
            return True
    return False


_FOOTPRINTS: dict[int, tuple[Surface, tuple[FloatArray, FloatArray]]] = {}


def _footprint(surface: Surface) -> tuple[FloatArray, FloatArray]:
    """The lowest and highest corners (3,) of ``surface``'s triangles' bounding box, made
    once per surface (a standing state looks under every foot on every surface)."""
    hit = _FOOTPRINTS.get(id(surface))
    if hit is None or hit[0] is not surface:
        corners = surface.triangle_vertices.reshape(-1, 3)
        box = (corners.min(axis=0), corners.max(axis=0))
        for array in box:
            array.flags.writeable = False
        if len(_FOOTPRINTS) > 4096:
            _FOOTPRINTS.clear()
        hit = (surface, box)
        _FOOTPRINTS[id(surface)] = hit
    return hit[1]


def _support_below(
    scene: Scene, point: FloatArray, search_height: float
) -> tuple[Surface, FloatArray] | None:
    """The topmost Support surface under ``point`` (3,) whose closest point is within
    ``search_height`` of it in height (lower ones are hidden below it), and that closest point
    (3,); None when there is none."""
    best: tuple[float, Surface, FloatArray] | None = None
    for surface in scene.surfaces_of(SurfaceKind.SUPPORT):
        lo, hi = _footprint(surface)
        if np.any(point[:2] < lo[:2] - 1e-6) or np.any(point[:2] > hi[:2] + 1e-6):
            continue
        if not surface.contains_projection(point[None])[0]:
            continue
        target = surface.closest_point(point[None])[0]
        if abs(float(target[2] - point[2])) <= search_height and (
            best is None or target[2] > best[0]
        ):
            best = (float(target[2]), surface, target)
    return None if best is None else (best[1], best[2])


def _project(
    model: pin.Model,
    limb: Limb,
    q: FloatArray,
    target: FloatArray,
    normal: FloatArray,
    reference: FloatArray,
    params: StandingParams,
    data: pin.Data,
) -> IkResult:
    """IK of one limb onto ``target``: patches align their normal; a point contact puts its
    sphere's centre (the effector frame origin) one radius above ``target`` along ``normal``,
    so that its lowest point, the recorded contact point, is on the surface."""
    if limb.contact == "patch":
        return project_contact(
            model,
            q,
            limb.root_joint,
            limb.effector_frame,
            target,
            normal,
            contact_normal=limb.normal,
            contact_offset=limb.offset,
            reference=reference,
            posture_weight=params.posture_weight,
            data=data,
        )
    dofs = limb_dofs(model, limb.root_joint, limb.effector_frame)
    weights = np.zeros(model.nv)
    weights[dofs] = params.posture_weight
    tasks: list[Task] = [
        FramePositionTask(
            limb.frame_id, sphere_centre(limb, target, normal), np.zeros(3), Priority.CONTACT
        ),
        PostureTask(reference, weights, gain=0.3),
    ]
    return solve_ik(model, q, tasks, data=data, active=dofs)


def _equilibrium(
    character: Character, q: FloatArray, contacts: Sequence[LimbContact], params: StandingParams
) -> tuple[bool, float, FloatArray]:
    """(balanced with the margin, margin in N, COM (3,))."""
    model = character.model
    com = np.array(pin.centerOfMass(model, scratch_data(model), q), dtype=np.float64)
    phase = ContactPhase([Contact(c.points, c.normal, c.mu) for c in contacts], mass=character.mass)
    result = equilibrium_margin(phase, com)
    generators = phase.wrench_generators.shape[0]
    needed = params.margin * character.mass * GRAVITY / max(generators, 1)
    return bool(result.feasible and result.margin >= needed), float(result.margin), com


def state_from_root_pose(
    scene: Scene,
    character: Character,
    data: OfflineData,
    root_pose: FloatArray,
    *,
    limbs: Sequence[str] | None = None,
    checker: ReachabilityChecker | None = None,
    params: StandingParams | None = None,
) -> PlanResult[ContactState]:
    """A balanced standing state keeping the root at ``root_pose`` (4, 4, world frame).

    limbs : the limbs to put in contact (default: the ground limbs of ``q_ref``), each on the
    Support surface below its reference contact. checker : the reachability condition the root
    pose must meet (default: built from ``data`` with default settings). SOLVED with the state
    (contacts in ``limbs`` order), else INFEASIBLE with a message saying what failed.
    """
    params = StandingParams() if params is None else params
    pose = np.asarray(root_pose, dtype=np.float64).reshape(4, 4)
    names = ground_limbs(character) if limbs is None else tuple(limbs)
    if checker is None:
        checker = ReachabilityChecker(scene, character, data)
    if not checker.is_valid(pose):
        return _fail("the root pose fails the reachability condition")
    model = character.model
    q = np.array(character.q_ref, dtype=np.float64)
    q[0:3] = pose[:3, 3]
    q[3:7] = matrix_to_quaternion(pose[:3, :3])
    reference = q.copy()
    offsets = checker.offsets
    chosen: list[tuple[Limb, Surface]] = []
    pin_data = model.createData()
    for name in names:
        limb = character.limb(name)
        ref_point = pose[:3, :3] @ offsets[name] + pose[:3, 3]
        below = _support_below(scene, ref_point, params.search_height)
        if below is None:
            return _fail(f"no Support surface under {name}")
        surface, target = below
        ik = _project(model, limb, q, target, surface.normal, reference, params, pin_data)
        if not ik.success:
            return _fail(f"IK cannot put {name} on surface {surface.id}")
        q = np.array(ik.q, dtype=np.float64)
        chosen.append((limb, surface))
    if not within_limits(model, q):
        return _fail("joint limits violated")
    contacts = []
    for limb, surface in chosen:
        placement = contact_placement(character, limb.name, q, pin_data)
        contact = LimbContact(
            limb.name,
            placement,
            contact_points(limb, placement, surface.normal),
            surface.normal,
            limb.mu,
            surface.id,
        )
        if not lies_on(
            contact,
            surface,
            limb,
            height_tolerance=CONTACT_TOLERANCE,
            normal_tolerance=NORMAL_TOLERANCE,
        ):
            return _fail(f"{limb.name} is not fully on surface {surface.id}")
        contacts.append(contact)
    if body_collides_scene(scene, character, q, contacts):
        return _fail("the body collides with the scene")
    model = character.model
    if self_collides(character, q, scratch_data(model), pin.GeometryData(character.geometry)):
        return _fail("the body collides with itself")
    balanced, margin, com = _equilibrium(character, q, contacts, params)
    stats: dict[str, float | int | str] = {
        "margin": margin,
        "com_x": float(com[0]),
        "com_y": float(com[1]),
        "com_z": float(com[2]),
    }
    if not balanced:
        return PlanResult(PlanStatus.INFEASIBLE, None, stats, "not balanced with the margin")
    return PlanResult(PlanStatus.SOLVED, ContactState(q, tuple(contacts)), stats)


def _trunk_points(character: Character) -> FloatArray:
    """(k, 3) points of the trunk shapes in the root frame (box corners, capsule ends)."""
    points = []
    for shape in character.trunk:
        if isinstance(shape, Box):
            points.append(shape.vertices())
        else:
            ends = np.array([[0.0, 0.0, -shape.half_length], [0.0, 0.0, shape.half_length]])
            local = ends @ shape.offset[:3, :3].T + shape.offset[:3, 3]
            lift = np.array([0.0, 0.0, shape.radius])
            points.append(np.vstack([local + lift, local - lift]))
    return np.asarray(np.vstack(points), dtype=np.float64)


def _trunk_clearance_level(
    scene: Scene,
    character: Character,
    root: FloatArray,
    rotation: FloatArray,
    height: float,
    params: StandingParams,
) -> float | None:
    """Root height (m) putting the trunk 1 cm above the highest Support surface under it (near
    ``height``), or None when there is none."""
    points = _trunk_points(character)
    tops = []
    for point in points @ rotation.T + root:
        probe = np.array([point[0], point[1], height])
        below = _support_below(scene, probe, params.search_height)
        if below is not None:
            tops.append(float(below[1][2]))
    if not tops:
        return None
    return max(tops) + 0.01 - float(points[:, 2].min())


def _fail(message: str) -> PlanResult[ContactState]:
    return PlanResult(PlanStatus.INFEASIBLE, None, {}, message)


def _stance_rotation(checker: ReachabilityChecker, point: FloatArray, heading: float) -> FloatArray:
    """(3, 3) root rotation of a stance at ``point`` (3,) facing ``heading`` (rad): level,
    or for a character allowed to pitch, lying along the terrain's slope there."""
    rotation = yaw_matrix(np.array(heading))
    max_pitch = checker.character.max_pitch
    if max_pitch <= LEVEL_PITCH:
        return rotation
    half_length, half_width, stand = body_span(checker)
    pose = np.eye(4)
    pose[:3, :3] = rotation
    pose[:3, 3] = point + np.array([0.0, 0.0, stand])
    line = terrain_line(checker.scene, pose, half_length, half_width)
    if line is None:
        return rotation
    return along_slope(heading, line[1], max_pitch)[0]


def standing_state(
    scene: Scene,
    character: Character,
    data: OfflineData,
    point: FloatArray,
    *,
    rng: np.random.Generator,
    yaw: float | None = None,
    until: Termination = never,
    checker: ReachabilityChecker | None = None,
    params: StandingParams | None = None,
) -> PlanResult[ContactState]:
    """A balanced standing state at ``point`` (3,), a point of a Support surface (world, m).

    The root is placed so the ground limbs' reference contacts are centred on the point, with
    yaw ``yaw`` (rad) or else 16 yaws 22.5 degrees apart from one drawn from ``rng`` (and, for
    a character with a ``max_pitch``, pitched along the terrain's slope); further
    attempts also shift the root sideways at random (``params.jitter``). Root heights tried,
    low to high: the reference height above the lowest, mean and highest Support surface
    found below the contacts, and the height at which the trunk clears the Support surfaces
    under it. SOLVED with the state; INFEASIBLE when no Support surface is at the point or
    ``params.attempts`` root poses all fail (message: the last reason); TIMEOUT when ``until``
    fires first.
    """
    params = StandingParams() if params is None else params
    p = np.asarray(point, dtype=np.float64).reshape(3)
    if _support_below(scene, p, 0.1) is None:
        return _fail("no Support surface at the point")
    if checker is None:
        checker = ReachabilityChecker(scene, character, data)
    names = ground_limbs(character)
    local = np.stack([checker.offsets[name] for name in names])
    centre = local.mean(axis=0)
    message = "no attempt made"
    base = float(rng.uniform(-np.pi, np.pi))
    for attempt in range(params.attempts):
        if until():
            return PlanResult(PlanStatus.TIMEOUT, None, {"attempts": attempt}, "deadline")
        if yaw is None:  # headings spread over the circle, then again with sideways shifts
            heading = base + (attempt % _HEADINGS) * 2.0 * np.pi / _HEADINGS
            shifted = attempt >= _HEADINGS
        else:
            heading, shifted = float(yaw), attempt > 0
        rotation = _stance_rotation(checker, p, heading)
        shift = np.zeros(3)
        if shifted:
            shift[:2] = rng.normal(0.0, params.jitter, size=2)
        root = p + shift - rotation @ centre
        heights = []
        for k in range(len(names)):
            foot = rotation @ local[k] + root
            foot[2] = p[2]
            below = _support_below(scene, foot, params.search_height)
            if below is not None:
                heights.append(float(below[1][2]))
        if len(heights) < len(names):
            message = "a foot has no Support surface below it"
            continue
        levels = {min(heights), float(np.mean(heights)), max(heights)}
        clear = _trunk_clearance_level(scene, character, root, rotation, p[2], params)
        if clear is not None and clear + centre[2] > max(heights):
            levels.add(clear + centre[2])
        for level in sorted(levels):
            root[2] = level - centre[2]
            result = state_from_root_pose(
                scene,
                character,
                data,
                pose_matrix(root, rotation),
                limbs=names,
                checker=checker,
                params=params,
            )
            if result.status is PlanStatus.SOLVED:
                break
        if result.status is PlanStatus.SOLVED:
            stats = dict(result.stats)
            stats["attempts"] = attempt + 1
            stats["yaw"] = heading
            return PlanResult(PlanStatus.SOLVED, result.value, stats)
        message = result.message
    return PlanResult(PlanStatus.INFEASIBLE, None, {"attempts": params.attempts}, message)
