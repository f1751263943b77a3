"""Contact primitives: maintain contacts under a new root, create one contact, break one.

Anchor: contact-planner-anchor sections 4-6 (candidates near allowed surfaces, scored by
closeness to the posture and to a target, projected by IK, checked for collision, static
equilibrium with a robustness margin and 2PAC quasi-static reachability, Eq. 5-6).
Every primitive returns a structured result; none raises on an infeasible request.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from planner.contact.checks import (
    balance_margin,
    check_state,
    collision_free,
    com_of,
    contact_on_surface,
    contact_points_at,
    effector_pose,
    forward,
    hold_error,
    kinematics_of,
    lifts_clear,
    make_contact,
    shrunk_equilibrium,
)
from planner.contact.context import (
    ContactContext,
    ContactParams,
    FailureReason,
    character_obstacles,
    make_context,
)
from planner.contact.reachability import ground_limbs
from planner.contact.state import ContactState, LimbContact
from planner.kinematics import (
    ComTask,
    ContactNormalTask,
    FramePlacementTask,
    FramePositionTask,
    IkResult,
    PostureTask,
    Priority,
    TargetTask,
    Task,
    project_contact,
    solve_ik,
)
from planner.kinematics.model import has_free_flyer_root, joint_id, limb_reach
from planner.motion.spec import torso_columns
from planner.scene import Surface
from planner.scene.geometry2d import plane_basis
from planner.shapes import Capsule
from trajectory import Halfspaces, transition_point

FloatArray = NDArray[np.float64]

__all__ = [
    "ContactAttempt",
    "ContactContext",
    "ContactParams",
    "FailureReason",
    "break_contact",
    "character_obstacles",
    "create_contact",
    "maintain",
    "make_context",
    "stand_state",
    "stand_up",
    "state_from_configuration",
]

_HOLD_TOL = 1e-3  # m, a held contact further than this from its placement is lost
BENT_CHEST = 0.2  # rad: a chest joint this far from the reference is bent (stand_up)
MAX_TRUNK_TILT = np.radians(45.0)
"""rad the root may tilt from the vertical in a state made by a whole-body reach, beyond the
character's ``max_pitch``: the motion keeps such a trunk near level, so a state further over
cannot be played. Measured at the scenarios' seeds: states tilt up to 44 degrees on the
climbing wall, 41 on Talos' platforms; Talos reaching for a stair's foothold once dropped
its root 0.26 m and tilted it 57 degrees, and no motion could follow."""
_STAGE = {
    FailureReason.NOTHING_REACHABLE: 0,
    FailureReason.NOT_IN_CONTACT: 1,
    FailureReason.COLLISION: 2,
    FailureReason.NOT_BALANCED: 3,
}


@dataclass(frozen=True, slots=True)
class ContactAttempt:
    """Outcome of a primitive.

    ok : success. state : the new state (the input state on failure). reason : why it
    failed (None on success). candidates_tried : surface targets projected. message : detail.
    limb : the limb acted on. surface : surface id of a created contact (-1 otherwise).
    resampled : colliding limb postures replaced by another database sample.
    """

    ok: bool
    state: ContactState
    reason: FailureReason | None
    candidates_tried: int
    message: str
    limb: str
    surface: int = -1
    resampled: int = 0


def _fail(
    state: ContactState, reason: FailureReason, limb: str, message: str, tried: int = 0
) -> ContactAttempt:
    return ContactAttempt(False, state, reason, tried, message, limb)


def posture_task(
    ctx: ContactContext, gain: float = 0.3, root_from: FloatArray | None = None
) -> PostureTask:
    """Pull toward the character's reference posture, root free; with ``root_from`` (nq,),
    the root's orientation is also pulled toward that configuration's (a trunk that keeps
    its pitch on a slope)."""
    weights = np.ones(ctx.model.nv)
    weights[:6] = 0.0
    target = np.array(ctx.character.q_ref)
    if root_from is not None:
        target[3:7] = root_from[3:7]
        weights[3:6] = 1.0
    return PostureTask(target, weights, gain=gain)


def hold_tasks(contacts: Sequence[LimbContact], ctx: ContactContext) -> list[TargetTask]:
    """Contact-tier tasks keeping each contact's effector at its placement."""
    out: list[TargetTask] = []
    for c in contacts:
        spec = ctx.character.limb(c.limb)
        if spec.contact == "point":
            goal = c.placement[:3, 3]
            out.append(FramePositionTask(spec.frame_id, goal, np.zeros(3), Priority.CONTACT))
        else:
            out.append(FramePlacementTask(spec.frame_id, c.placement, Priority.CONTACT))
    return out


def balance_ik(
    ctx: ContactContext,
    q: FloatArray,
    contacts: Sequence[LimbContact],
    com: FloatArray,
    extra: Sequence[Task] = (),
    axes: tuple[bool, bool, bool] = (True, True, True),
    moving: Sequence[str] = (),
    keep_orientation: bool = False,
    chest_still: bool = False,
) -> IkResult:
    """Whole-body IK: hold ``contacts``, COM to ``com`` (3,), then ``extra`` and the posture
    (with ``keep_orientation``, the root's orientation in ``q`` is part of it); with
    ``chest_still`` the joints of no limb (a chest's, a head's) keep their values in ``q``."""
    tasks: list[Task] = [*hold_tasks(contacts, ctx), ComTask(com, axes), *extra]
    tasks.append(posture_task(ctx, root_from=np.asarray(q) if keep_orientation else None))
    active = active_dofs(ctx, [*(c.limb for c in contacts), *moving])
    if chest_still:
        active = np.setdiff1d(active, chest_dofs(ctx)).astype(np.int64)
    return solve_ik(
        ctx.model,
        q,
        tasks,
        data=ctx.pin_data,
        active=active,
        max_iterations=ctx.params.ik_iterations,
    )


def chest_dofs(ctx: ContactContext) -> NDArray[np.int64]:
    """Velocity indices (k,) of the joints of no limb past the root (a chest's, a head's)."""
    root = int(ctx.model.nvs[1]) if has_free_flyer_root(ctx.model) else 0
    return np.array(torso_columns(ctx.character, root), dtype=np.int64)


def _carried_by_chest(ctx: ContactContext, limb: str) -> bool:
    """Whether a joint of no limb carries ``limb`` (an arm on a chest, not a leg)."""
    model = ctx.model
    chest = set(chest_dofs(ctx).tolist())
    joint = int(model.parents[int(ctx.character.limb(limb).joint_ids[0])])
    while joint > 1:
        if int(model.idx_vs[joint]) in chest:
            return True
        joint = int(model.parents[joint])
    return False


def stand_up(ctx: ContactContext, state: ContactState) -> ContactState:
    """``state`` with its chest and free arms back at the reference posture, its COM where it
    was and its contacts held by the legs and root alone, when its chest is bent (a joint
    ``BENT_CHEST`` or more from the reference), no contact it holds is carried by the chest
    (the hands have let go) and that makes a valid state; else ``state`` itself. The
    end of a climb: the chest bent over the wall to reach stands up once the hands let go."""
    chest_q = _chest_q(ctx)
    reference = np.asarray(ctx.character.q_ref)[chest_q]
    if (
        len(chest_q) == 0
        or np.abs(np.asarray(state.q)[chest_q] - reference).max() < BENT_CHEST
        or any(_carried_by_chest(ctx, c.limb) for c in state.contacts)
    ):
        return state
    q = np.array(state.q)
    q[chest_q] = reference
    for spec in ctx.character.limbs:  # the free arms hang again (they reached with the chest)
        if state.contact(spec.name) is None and _carried_by_chest(ctx, spec.name):
            q[spec.idx_q] = np.asarray(ctx.character.q_ref)[spec.idx_q]
    res = balance_ik(ctx, q, state.contacts, com_of(ctx, state.q), chest_still=True)
    straight = ContactState(np.array(res.q), state.contacts)
    if not _holds(ctx, straight.q, state.contacts) or not check_state(ctx, straight).valid:
        return state
    return straight


def _chest_q(ctx: ContactContext) -> NDArray[np.int64]:
    """Configuration indices (k,) of the joints of no limb past the root."""
    model = ctx.model
    chest = set(chest_dofs(ctx).tolist())
    out = [
        int(model.idx_qs[j]) + i
        for j in range(2, model.njoints)
        if int(model.idx_vs[j]) in chest
        for i in range(int(model.nqs[j]))
    ]
    return np.array(out, dtype=np.int64)


def active_dofs(ctx: ContactContext, limbs: Sequence[str]) -> NDArray[np.int64]:
    """Velocity indices (k,) of every dof except those of limbs not in ``limbs`` (a dof two
    limbs share, a hip for a foot and the back of its thigh, stays when either is listed)."""
    mask = np.ones(ctx.model.nv, dtype=bool)
    for spec in ctx.character.limbs:
        if spec.name not in limbs:
            mask[spec.idx_v] = False
    for spec in ctx.character.limbs:
        if spec.name in limbs:
            mask[spec.idx_v] = True
    return np.flatnonzero(mask).astype(np.int64)


def _tilt(q: FloatArray) -> float:
    """Angle (rad) between the root's z axis in ``q`` (nq,) and the world vertical."""
    x, y = float(q[3]), float(q[4])  # the quaternion's (x, y): R[2, 2] = 1 - 2 (x^2 + y^2)
    return float(np.arccos(np.clip(1.0 - 2.0 * (x * x + y * y), -1.0, 1.0)))


def _holds(ctx: ContactContext, q: FloatArray, contacts: Sequence[LimbContact]) -> bool:
    return hold_error(ctx, q, contacts) <= _HOLD_TOL


def maintain(
    ctx: ContactContext, state: ContactState, root_pose: FloatArray
) -> tuple[ContactState, tuple[str, ...]]:
    """Move the root to ``root_pose`` (4, 4) and re-solve the contact limbs (root fixed).

    Returns the new state with the contacts that still hold, and the limbs lost.
    """
    q = np.array(state.q)
    q[:3] = root_pose[:3, 3]
    q[3:7] = pin.Quaternion(np.asarray(root_pose[:3, :3])).coeffs()
    if not state.contacts:
        return ContactState(q, ()), ()
    active = np.concatenate([ctx.character.limb(c.limb).idx_v for c in state.contacts])
    result = solve_ik(
        ctx.model,
        q,
        [*hold_tasks(state.contacts, ctx), posture_task(ctx)],
        data=ctx.pin_data,
        active=active,
        max_iterations=ctx.params.ik_iterations,
    )
    kept: list[LimbContact] = []
    lost: list[str] = []
    for c, residual in zip(state.contacts, result.residuals, strict=False):
        if residual[0] <= _HOLD_TOL:
            kept.append(c)
        else:
            lost.append(c.limb)
    return ContactState(np.array(result.q), tuple(kept)), tuple(lost)


def _cached_point(
    ctx: ContactContext, sid: int, desired: FloatArray, radius: float
) -> FloatArray | None:
    """:func:`_point_on` memoised on the surface and ``desired`` rounded to 1 cm."""
    key = ("point", sid, radius, tuple(np.round(desired, 2).tolist()))
    surface = ctx.scene.surfaces[sid]
    boxed: tuple[FloatArray | None] = ctx.cached(
        key, lambda: (_point_on(surface, desired, radius),)
    )
    return boxed[0]


def _point_on(surface: Surface, desired: FloatArray, radius: float) -> FloatArray | None:
    """A point of ``surface`` near ``desired`` (3,) with a disc of ``radius`` inside it.

    From the closest point, the disc centre is pushed away from the nearest boundary point
    until it clears the boundary by ``radius`` (a few pushes settle corners): a foot keeps
    its place along a stair tread and only moves across it. Falls back to moving toward the
    centroid in quarter steps.
    """
    closest = surface.closest_point(desired[None])[0]
    p = surface.to_plane(closest[None])[0]
    for _ in range(6):
        world = surface.from_plane(p[None])
        inside = bool(surface.contains_projection(world)[0])
        distance, nearest = surface.nearest_boundary(p[None])
        if inside and distance[0] >= radius:
            return _on_mesh(surface, world[0])
        away = p - nearest[0]
        if distance[0] < 1e-6 or not inside:
            away = -p  # on or outside the boundary: head for the centroid (plane origin)
        norm = float(np.linalg.norm(away))
        if norm < 1e-9:
            break
        p = nearest[0] + away / norm * (radius + 1e-3)
    steps = np.array([0.25, 0.5, 0.75, 1.0])
    centres = closest + steps[:, None] * (surface.centroid - closest)  # (4, 3)
    fits = np.flatnonzero(surface.contains_projection(centres, margin=radius))
    if len(fits) == 0:
        return None
    return _on_mesh(surface, centres[int(fits[0])])


def _on_mesh(surface: Surface, point: FloatArray) -> FloatArray:
    """``point`` (3,) dropped onto the surface's triangles (read-only copy)."""
    p = surface.closest_point(point[None])[0] if surface.flatness > 1e-9 else point
    out = np.array(p, dtype=np.float64)
    out.flags.writeable = False
    return out


_BOUNDS: dict[int, tuple[Surface, float]] = {}


def _bound(surface: Surface) -> float:
    """Radius (m) of the smallest centroid-centred ball containing ``surface``'s polygons."""
    hit = _BOUNDS.get(id(surface))
    if hit is None or hit[0] is not surface:
        pts = np.concatenate(surface.polygons)
        hit = (surface, float(np.max(np.linalg.norm(pts - surface.centroid, axis=1))))
        if len(_BOUNDS) > 4096:
            _BOUNDS.clear()
        _BOUNDS[id(surface)] = hit
    return hit[1]


def _patch_radius(ctx: ContactContext, limb: str) -> float:
    """m, the radius of ``limb``'s contact patch around its effector, plus a millimetre
    (remembered per character)."""

    def make() -> float:
        spec = ctx.character.limb(limb)
        pts = spec.contact_points() - spec.offset
        return float(np.max(np.linalg.norm(pts[:, :2], axis=1))) + 0.001

    radius: float = ctx.shared(("patch_radius", limb), make)
    return radius


def _clear_of(
    ctx: ContactContext,
    sid: int,
    point: FloatArray,
    others: Sequence[LimbContact],
    gap: float,
    radius: float,
) -> FloatArray | None:
    """``point`` (3,) on surface ``sid``, pushed (along the surface) away from the nearest
    contact point of ``others`` until it is ``gap`` m clear of all of them; None if it cannot."""
    for _ in range(3):
        near = [(float(np.min(np.linalg.norm(c.points - point, axis=1))), c) for c in others]
        close = [(d, c) for d, c in near if d < gap]
        if not close:
            return point
        d, c = min(close, key=lambda x: x[0])
        nearest = c.points[int(np.argmin(np.linalg.norm(c.points - point, axis=1)))]
        away = point - nearest
        away[2] = 0.0
        n = float(np.linalg.norm(away))
        if n < 1e-6:
            return None
        moved = _point_on(ctx.scene.surfaces[sid], point + away / n * (gap - d + 0.01), radius)
        if moved is None:
            return None
        point = moved
    return None


AVOID_RADIUS = 0.1
"""m: a contact re-planned because the whole-body motion could not make it is not sought
again this close to where it was (``create_contact(avoid=)``): a limb's collision shapes are
a few centimetres across, so a nearer contact would meet the same obstacle."""
_DETOUR_SHARE = 1.3
"""A surface whose nearest point is avoided is asked for its points nearest to points this
many ``AVOID_RADIUS`` around the avoided one instead."""
_HEADROOM = 0.1  # m of free space wanted above a contact point
_HEADROOM_RADIUS = 0.03  # m, at least, of that free space's radius (a point foot's ankle)
_REAIM_RADIUS = 0.05  # m: a whole-body reach that ends this close is aimed again where it got


def _stands_on(ctx: ContactContext, limb: str) -> bool:
    """Whether the character stands on ``limb`` (its contact touches the ground in the
    reference configuration): a foot, which the swing lifts straight off its foothold."""
    feet: frozenset[str] = ctx.cached(
        "ground_limbs", lambda: frozenset(ground_limbs(ctx.character))
    )
    return limb in feet


def _uncovered(ctx: ContactContext, sid: int, point: FloatArray, radius: float) -> bool:
    """Whether the space just above ``point`` (3,) on surface ``sid`` is free: not inside a
    solid of the scene (ground running on under a staircase), and a capsule of half the
    patch ``radius`` (at least ``_HEADROOM_RADIUS``: a point foot's ankle and shin are wider
    than its patch) standing ``_HEADROOM`` m along the normal, starting just off the surface,
    touches nothing (ground under the edge of a slab, an obstacle, a riser or rock side)."""
    key = ("uncovered", sid, radius, tuple(np.round(point, 2).tolist()))

    def test() -> bool:
        normal = ctx.scene.surfaces[sid].normal
        if ctx.scene.inside_solid(point + 0.005 * normal):
            return False
        r = max(0.5 * radius, _HEADROOM_RADIUS)
        pose = np.eye(4)
        pose[:3, :3] = plane_basis(normal).T
        pose[:3, 3] = point + normal * (0.005 + r + 0.5 * _HEADROOM)
        return not ctx.world.collides(Capsule(r, 0.5 * _HEADROOM), pose)

    free: bool = ctx.cached(key, test)
    return free


def _surface_spheres(ctx: ContactContext) -> tuple[NDArray[np.int64], FloatArray, FloatArray]:
    """The allowed surface ids (k,), their centroids (k, 3) and bounding radii (k,)."""

    def make() -> tuple[NDArray[np.int64], FloatArray, FloatArray]:
        ids = np.asarray(ctx.surfaces, dtype=np.int64)
        centres = np.array([ctx.scene.surfaces[i].centroid for i in ids]).reshape(-1, 3)
        bounds = np.array([_bound(ctx.scene.surfaces[i]) for i in ids], dtype=np.float64)
        return ids, centres, bounds

    out: tuple[NDArray[np.int64], FloatArray, FloatArray] = ctx.cached("surface_spheres", make)
    return out


def nearest_foothold(
    ctx: ContactContext, limb: str, point: FloatArray, within: float = 0.5
) -> FloatArray | None:
    """The point (3,) of an allowed surface nearest to ``point`` (3,) where ``limb``'s contact
    patch fits, searched within ``within`` m; None when there is none."""
    radius = _patch_radius(ctx, limb)
    ids, centres, bounds = _surface_spheres(ctx)
    lower = np.linalg.norm(centres - point, axis=1) - bounds  # no closer than this
    best: FloatArray | None = None
    best_gap = within
    for k in np.argsort(lower, kind="stable"):
        if lower[k] > best_gap:
            break
        sid = int(ids[k])
        found = _cached_point(ctx, sid, point, radius)
        if found is None or not _uncovered(ctx, sid, found, radius):
            continue
        gap = float(np.linalg.norm(found - point))
        if gap < best_gap:
            best, best_gap = found, gap
    return best


@dataclass(frozen=True, slots=True)
class _Candidate:
    score: float
    surface: int
    point: FloatArray
    seeds: NDArray[np.int64]


def _banned(point: FloatArray, banned: FloatArray) -> bool:
    """Whether ``point`` (3,) lies within ``AVOID_RADIUS`` of a point of ``banned`` (m, 3)."""
    return len(banned) > 0 and float(np.min(np.linalg.norm(banned - point, axis=1))) <= AVOID_RADIUS


def _detours(point: FloatArray, banned: FloatArray) -> list[FloatArray]:
    """Desired points (3,) around the banned point nearest ``point``, ``_DETOUR_SHARE``
    times ``AVOID_RADIUS`` from it in the horizontal plane: straight away from it first,
    then turning both ways in eighths of a turn."""
    centre = banned[int(np.argmin(np.linalg.norm(banned - point, axis=1)))]
    away = (point - centre)[:2]
    angle = float(np.arctan2(away[1], away[0])) if float(np.linalg.norm(away)) > 1e-6 else 0.0
    turns = (0, 1, -1, 2, -2, 3, -3, 4)
    out = []
    for turn in turns:
        a = angle + turn * np.pi / 4.0
        offset = _DETOUR_SHARE * AVOID_RADIUS * np.array([np.cos(a), np.sin(a), 0.0])
        out.append(centre + offset)
    return out


def _limb_reach(ctx: ContactContext, limb: str, hip_root: FloatArray) -> float:
    """m, the farthest the effector of ``limb`` gets from its root joint at ``hip_root`` (3,)
    (root frame, taken to the micrometre) over its database's samples; remembered per
    database and root joint position (fixed on the trunk for a leg, up to round-off)."""
    db = ctx.data.limb(limb).database
    hip = np.round(hip_root, 6)
    farthest: float = ctx.per_state(
        db,
        ("reach", hip.tobytes()),
        lambda: float(np.max(np.linalg.norm(db.positions - hip, axis=1))),
    )
    return farthest


def _candidates(
    ctx: ContactContext,
    state: ContactState,
    limb: str,
    rng: np.random.Generator,
    surfaces: Sequence[int],
    target: FloatArray | None,
    lookahead: FloatArray | None,
    randomness: float,
    banned: FloatArray | None = None,
) -> list[_Candidate]:
    """Up to ``max_candidates`` contact candidates of ``limb``, best first: per surface, its
    point nearest to the desired one, or, when that lies within ``AVOID_RADIUS`` of a point
    of ``banned`` (m, 3), its nearest to points around the banned one."""
    spec = ctx.character.limb(limb)
    db = ctx.data.limb(limb).database
    forward(ctx, state.q)
    root = np.asarray(ctx.pin_data.oMi[1].homogeneous, dtype=np.float64)
    current = effector_pose(ctx, limb)[:3, 3]
    nominal = root[:3, :3] @ db.positions[0] + root[:3, 3]
    base = np.asarray(ctx.pin_data.oMi[ctx.model.getJointId(spec.root_joint)].translation)
    hip_root = root[:3, :3].T @ (base - root[:3, 3])
    reach = _limb_reach(ctx, limb, hip_root) + ctx.params.body_reach
    radius = _patch_radius(ctx, limb)
    desired = target if target is not None else 0.5 * (current + nominal)
    others = [c for c in state.contacts if c.limb != limb]
    # cheap pre-selection on bounding discs before the exact (slower) surface queries
    ids, centres, bounds = _surface_spheres(ctx)
    if len(surfaces) != len(ids):  # a subset of the allowed surfaces (in their order)
        pick = np.isin(ids, np.asarray(surfaces, dtype=np.int64))
        ids, centres, bounds = ids[pick], centres[pick], bounds[pick]
    lower = np.maximum(np.linalg.norm(centres - desired, axis=1) - bounds, 0.0)
    keep = np.linalg.norm(centres - base, axis=1) - bounds <= reach
    order = np.argsort(np.where(keep, lower, np.inf), kind="stable")
    order = order[keep[order]][: 2 * ctx.params.max_candidates + 2]
    out: list[_Candidate] = []
    for sid in ids[order].tolist():
        point = _cached_point(ctx, sid, desired, radius)
        if point is not None and banned is not None and _banned(point, banned):
            aims = (_cached_point(ctx, sid, aim, radius) for aim in _detours(point, banned))
            point = next((p for p in aims if p is not None and not _banned(p, banned)), None)
        if point is None or not _uncovered(ctx, sid, point, radius):
            continue
        if np.linalg.norm(point - base) > reach:
            continue
        point = _clear_of(ctx, sid, point, others, 0.5 * radius + 0.02, radius)
        if point is None:
            continue
        local = root[:3, :3].T @ (point - root[:3, 3])
        seeds = db.samples_near(local[None], ctx.params.reach_radius)[:4]
        score = float(np.linalg.norm(point - nominal))
        score += 0.5 * float(np.linalg.norm(point - current))
        if target is not None:
            score += 2.0 * float(np.linalg.norm(point - target))
        if lookahead is not None:
            score += float(np.linalg.norm(point - lookahead))
        if len(seeds) == 0:
            score += 0.5  # needs the whole body
        score += randomness * float(rng.random())
        out.append(_Candidate(score, sid, point, seeds))
    out.sort(key=lambda c: c.score)
    return out[: ctx.params.max_candidates]


def _aim(
    ctx: ContactContext, limb: str, point: FloatArray, normal: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Where ``limb``'s contact on ``point`` (3,) of a surface facing ``normal`` (3,) is aimed:
    (the goal (3,), world; the point of the effector frame sent there (3,), its frame). A
    point contact sends the frame's origin, lifted by the clearance and the offset's length;
    a patch its offset point, lifted by the clearance."""
    spec = ctx.character.limb(limb)
    if spec.contact == "point":
        lift = ctx.params.clearance + float(np.linalg.norm(spec.offset))
        return point + lift * normal, np.zeros(3)
    return point + ctx.params.clearance * normal, np.asarray(spec.offset, dtype=np.float64)


def _contact_task(ctx: ContactContext, limb: str, point: FloatArray, normal: FloatArray) -> Task:
    spec = ctx.character.limb(limb)
    goal, _ = _aim(ctx, limb, point, normal)
    if spec.contact == "point":
        return FramePositionTask(spec.frame_id, goal, np.zeros(3), Priority.CONTACT)
    return ContactNormalTask(
        spec.frame_id,
        goal,
        normal,
        spec.normal,
        spec.offset,
        Priority.CONTACT,
    )


def _projections(
    ctx: ContactContext, state: ContactState, limb: str, cand: _Candidate
) -> Iterator[FloatArray]:
    """Configurations putting ``limb`` on the candidate: root fixed from each database seed
    (re-sampling the limb posture, 2PAC 7.2), then the whole body with the contacts held.
    The seeds are not tried when the candidate lies beyond the limb's reach from where the
    body holds its root joint (:func:`_beyond_reach`: those IKs can only fail)."""
    spec = ctx.character.limb(limb)
    db = ctx.data.limb(limb).database
    normal = ctx.scene.surfaces[cand.surface].normal
    seeds = () if _beyond_reach(ctx, state, limb, cand.point, normal) else cand.seeds
    for idx in seeds[: ctx.params.max_seeds]:
        q0 = np.array(state.q)
        q0[spec.idx_q] = db.q[idx]
        if spec.contact == "point":
            res = solve_ik(
                ctx.model,
                q0,
                [_contact_task(ctx, limb, cand.point, normal), posture_task(ctx)],
                data=ctx.pin_data,
                active=spec.idx_v,
                max_iterations=ctx.params.ik_iterations,
            )
            if res.success:
                yield np.array(res.q)
            continue
        res = project_contact(
            ctx.model,
            q0,
            spec.root_joint,
            spec.effector_frame,
            cand.point,
            normal,
            contact_normal=spec.normal,
            contact_offset=spec.offset,
            clearance=ctx.params.clearance,
            reference=ctx.character.q_ref,
            posture_weight=0.3,
            data=ctx.pin_data,
        )
        if res.success:
            yield np.array(res.q)
    com = com_of(ctx, state.q)
    surface = ctx.scene.surfaces[cand.surface]
    radius = _patch_radius(ctx, limb)
    starts = [np.array(state.q)]
    drops = ctx.params.crouch_drops if len(cand.seeds) == 0 and state.contacts else ()
    for k, drop in enumerate((0.0, *drops)):
        if k > 0:  # lower the body first (COM straight down), then reach from there
            crouch = balance_ik(ctx, np.array(state.q), state.contacts, com - [0.0, 0.0, drop])
            if not _holds(ctx, crouch.q, state.contacts):
                continue
            starts.append(np.array(crouch.q))
        res = balance_ik(
            ctx,
            starts[-1],
            state.contacts,
            com - [0.0, 0.0, drop],
            extra=[_contact_task(ctx, limb, cand.point, normal)],
            axes=(True, True, False),
            moving=(limb,),
        )
        index = len(state.contacts) + 1
        if res.residuals[index, 0] <= 1e-3 and _holds(ctx, res.q, state.contacts):
            yield np.array(res.q)
            return
        if spec.on_request and res.residuals[index, 0] <= _REAIM_RADIUS:
            # a sit bone got close: aim again at the point of the seat it reached
            reached = effector_pose(ctx, limb, np.asarray(res.q))[:3, 3]
            aim = _point_on(surface, surface.closest_point(reached[None])[0], radius)
            if aim is None:
                continue
            again = balance_ik(
                ctx,
                np.array(res.q),
                state.contacts,
                com - [0.0, 0.0, drop],
                extra=[_contact_task(ctx, limb, aim, normal)],
                axes=(True, True, False),
                moving=(limb,),
            )
            if again.residuals[index, 0] <= 1e-3 and _holds(ctx, again.q, state.contacts):
                yield np.array(again.q)
                return


def _beyond_reach(
    ctx: ContactContext, state: ContactState, limb: str, point: FloatArray, normal: FloatArray
) -> bool:
    """Whether the limb's contact on ``point`` (3,) of a surface facing ``normal`` (3,), aimed
    as :func:`_aim` aims it, lies further from the origin of the limb's root joint at
    ``state`` than the limb reaches (:func:`limb_reach`) plus ``REACH_SLACK``: no posture of
    the limb alone puts it there."""
    spec = ctx.character.limb(limb)
    goal, offset = _aim(ctx, limb, point, normal)
    reach: float = ctx.cached(
        ("reach", limb), lambda: limb_reach(ctx.model, spec.root_joint, spec.frame_id, offset)
    )
    pin.forwardKinematics(ctx.model, ctx.pin_data, state.q)
    hip = ctx.pin_data.oMi[joint_id(ctx.model, spec.root_joint)].translation
    return float(np.linalg.norm(goal - hip)) > reach + REACH_SLACK


REACH_SLACK = 1e-3
"""m: a candidate counts as beyond a limb's reach only this far beyond it (the projection's
tolerance is 1e-4 m)."""


def _balanced_after_create(
    ctx: ContactContext, before: ContactState, q: FloatArray, contact: LimbContact
) -> tuple[FloatArray | None, FailureReason | None]:
    """Make the COM of ``q`` balanced on the old contacts, inside both kinematic sets."""
    after = (*before.contacts, contact)
    kin = kinematics_of(ctx, after)
    com = com_of(ctx, q)
    if (
        balance_margin(ctx, before.contacts, com) >= ctx.params.margin
        and kin.violation(com) <= 1e-3
    ):
        return q, None
    tp = transition_point(
        shrunk_equilibrium(ctx, before.contacts),
        shrunk_equilibrium(ctx, after),
        com,
        kin_prev=kinematics_of(ctx, before.contacts),
        kin_next=kin,
    )
    if not tp.feasible:
        return None, FailureReason.NOT_BALANCED
    res = balance_ik(ctx, q, after, tp.point)
    q2 = np.array(res.q)
    if not _holds(ctx, q2, after):
        return None, FailureReason.NOT_BALANCED
    com2 = com_of(ctx, q2)
    if balance_margin(ctx, before.contacts, com2) < ctx.params.margin or kin.violation(com2) > 1e-3:
        return None, FailureReason.NOT_BALANCED
    return q2, None


def create_contact(
    ctx: ContactContext,
    state: ContactState,
    limb: str,
    *,
    rng: np.random.Generator,
    surface: int | None = None,
    target: FloatArray | None = None,
    lookahead: FloatArray | None = None,
    randomness: float = 0.05,
    avoid: Sequence[FloatArray] = (),
) -> ContactAttempt:
    """Put the free ``limb`` on an allowed surface (``surface`` id, or near ``target`` (3,)).

    Candidates are surface points near the limb's reach, scored by distance to the limb's
    nominal position (reference posture at the current root), to ``target`` and to
    ``lookahead`` (3,); each is projected by IK (limb only from database seeds, else whole
    body with the other contacts held) and checked: contact on the surface, no collision,
    the new COM balanced on the old contacts with the margin and inside the new kinematic set
    (so the 2PAC transition exists). The first candidate passing wins; a colliding limb
    posture is re-sampled from the next database seed. ``randomness`` (m) is the scale of
    a uniform score jitter drawn from ``rng`` (ties and game-like variety). Candidates within
    ``AVOID_RADIUS`` of a point of ``avoid`` ((3,) each, world frame) are skipped (a contact
    change the whole-body motion could not make, re-planned).
    """
    if not ctx.has_limb(limb):
        return _fail(state, FailureReason.UNKNOWN_LIMB, limb, f"unknown limb {limb!r}")
    if state.contact(limb) is not None:
        return _fail(state, FailureReason.ALREADY_IN_CONTACT, limb, f"{limb} is in contact")
    if surface is not None:
        if surface not in ctx.surfaces:
            return _fail(
                state, FailureReason.UNKNOWN_SURFACE, limb, f"surface {surface} not allowed"
            )
        surfaces: Sequence[int] = (surface,)
    else:
        surfaces = ctx.surfaces
    tgt = None if target is None else np.asarray(target, dtype=np.float64).reshape(3)
    look = None if lookahead is None else np.asarray(lookahead, dtype=np.float64).reshape(3)
    banned = np.asarray(avoid, dtype=np.float64).reshape(-1, 3)
    cands = _candidates(ctx, state, limb, rng, surfaces, tgt, look, randomness, banned)
    if not cands:
        return _fail(state, FailureReason.NOTHING_REACHABLE, limb, "no surface within reach")
    worst = FailureReason.NOTHING_REACHABLE
    resampled = 0
    for tried, cand in enumerate(cands, start=1):
        for q in _projections(ctx, state, limb, cand):
            contact = make_contact(ctx, limb, q, cand.surface)
            if not contact_on_surface(ctx, contact):
                worst = max(worst, FailureReason.NOT_IN_CONTACT, key=_STAGE.__getitem__)
                continue
            q2, why = _balanced_after_create(ctx, state, q, contact)
            if q2 is None:
                worst = max(worst, why or FailureReason.NOT_BALANCED, key=_STAGE.__getitem__)
                break
            if _tilt(q2) > MAX_TRUNK_TILT + ctx.character.max_pitch:
                worst = max(worst, FailureReason.NOT_BALANCED, key=_STAGE.__getitem__)
                continue  # the next projection (a database posture, or none)
            if not collision_free(ctx, q2, (*state.contacts, contact)) or (
                _stands_on(ctx, limb) and not lifts_clear(ctx, q2, contact, _HEADROOM)
            ):
                worst = max(worst, FailureReason.COLLISION, key=_STAGE.__getitem__)
                resampled += 1
                continue  # re-sample the limb posture
            new = state.with_contact(contact, q2)
            # 2PAC witness: the new COM lies in equilibrium(before) (checked with the margin
            # by _balanced_after_create) and in kinematics(before) and kinematics(after).
            report = check_state(ctx, new)
            witness = kinematics_of(ctx, state.contacts).violation(report.com) <= 1e-3
            if not witness or not report.valid:
                worst = max(worst, FailureReason.NOT_BALANCED, key=_STAGE.__getitem__)
                break
            return ContactAttempt(True, new, None, tried, "", limb, cand.surface, resampled)
    return _fail(state, worst, limb, f"no candidate of {len(cands)} passed", len(cands))


def _lift_offsets(lift: float, normal: FloatArray) -> list[FloatArray]:
    """Effector displacements (3,) tried when releasing a contact: ``lift`` m along the
    surface ``normal``, then half of it, then the same lift tilted 45 degrees toward each of
    four horizontal directions (away from a riser or a wall next to the contact)."""
    u, v, n = plane_basis(np.asarray(normal, dtype=np.float64))
    out = [lift * n, 0.5 * lift * n]
    for side in (-u, u, -v, v):
        out.append(lift * (n + side) / np.sqrt(2.0))
    return out


_SHIFT_DEPTHS = (1.0, 2.0, 4.0)  # times ``com_shrink``: deeper transition points tried
# (m the shifted COM is raised, root orientation kept) tried while the shifted body collides
_SHIFT_TRIES = ((0.0, False), (0.0, True), (0.03, True), (0.06, True))


def _shift_com(
    ctx: ContactContext, state: ContactState, after: tuple[LimbContact, ...]
) -> tuple[FloatArray, FloatArray] | ContactAttempt:
    """The posture (nq,) and COM (3,) of ``state`` with its COM moved over the contacts
    ``after`` with the margin, holding ``state``'s contacts (2PAC: a point of
    equilibrium(after) inside kinematics(before) and kinematics(after)); a failed attempt
    when none is found. The equilibrium prism is shrunk deeper in turn when the margin is
    missed (the prism's shrink is in metres, the margin in newtons: a light body on
    uneven footholds needs more than the default)."""
    limb = next(c.limb for c in state.contacts if c not in after)
    com = com_of(ctx, state.q)
    kin_before = kinematics_of(ctx, state.contacts)
    kin_after = kinematics_of(ctx, after)
    failure = _fail(state, FailureReason.NOT_BALANCED, limb, "no balanced COM reachable")
    for depth in _SHIFT_DEPTHS:
        equilibrium = shrunk_equilibrium(ctx, after, depth)
        if all(p.violation(com) <= 0.0 for p in (equilibrium, kin_before, kin_after)):
            # the COM serves both sets where it is: it is the transition point (the
            # nearest point of the sets), without the QP (a hexapod walk's every release)
            shifted = com
        else:
            tp = transition_point(
                equilibrium,
                Halfspaces(np.zeros((0, 3)), np.zeros(0)),  # equilibrium(before) contains it
                com,
                kin_prev=kin_before,
                kin_next=kin_after,
            )
            if not tp.feasible:
                return failure
            shifted = tp.point
        for rise, keep in _SHIFT_TRIES:
            # equilibrium is a vertical prism: a higher COM keeps it and may lift the
            # trunk off a step's nosing; so may keeping the trunk's pitch
            point = shifted + np.array([0.0, 0.0, rise])
            if rise > 0.0 and kin_before.violation(point) > 1e-3:
                continue
            res = balance_ik(ctx, np.array(state.q), state.contacts, point, keep_orientation=keep)
            q1 = np.array(res.q)
            if not _holds(ctx, q1, state.contacts):
                return _fail(state, FailureReason.NOT_BALANCED, limb, "COM shift not reachable", 1)
            if collision_free(ctx, q1, state.contacts):
                break
        com1 = com_of(ctx, q1)
        margin = balance_margin(ctx, after, com1)
        if margin >= ctx.params.margin:
            return q1, com1
        failure = _fail(
            state, FailureReason.NOT_BALANCED, limb, f"COM shift not balanced: {margin:.3g} N", 1
        )
    return failure


def break_contact(ctx: ContactContext, state: ContactState, limb: str) -> ContactAttempt:
    """Release ``limb``: shift the COM over the remaining contacts (2PAC: a point of
    equilibrium(after) inside kinematics(before)), then lift the effector by ``params.lift``.
    Remembered per state object and limb in ``ctx`` (the contact planner asks whether a leg
    can be released before it releases it): asked again, the same attempt, at no work."""
    attempt: ContactAttempt = ctx.per_state(
        state, ("break", limb), lambda: _break_contact(ctx, state, limb), in_cache=True
    )
    return attempt


def _break_contact(ctx: ContactContext, state: ContactState, limb: str) -> ContactAttempt:
    """:func:`break_contact` computed."""
    if not ctx.has_limb(limb):
        return _fail(state, FailureReason.UNKNOWN_LIMB, limb, f"unknown limb {limb!r}")
    old = state.contact(limb)
    if old is None:
        return _fail(state, FailureReason.NOT_IN_CONTACT, limb, f"{limb} is not in contact")
    after = tuple(c for c in state.contacts if c.limb != limb)
    if not after:
        return _fail(state, FailureReason.NOT_BALANCED, limb, "no contact would remain")
    shifted = _shift_com(ctx, state, after)
    if isinstance(shifted, ContactAttempt):
        return shifted
    q1, com1 = shifted
    kin_before = kinematics_of(ctx, state.contacts)
    spec = ctx.character.limb(limb)
    new, report = ContactState(q1, after), None
    for offset in _lift_offsets(ctx.params.lift, old.normal):
        lifted = old.placement[:3, 3] + offset
        res2 = balance_ik(
            ctx,
            q1,
            after,
            com1,
            extra=[FramePositionTask(spec.frame_id, lifted, np.zeros(3), Priority.EFFECTOR)],
            moving=(limb,),
        )
        candidate = ContactState(np.array(res2.q), after)
        report = check_state(ctx, candidate)
        if report.valid and kin_before.violation(report.com) <= 1e-3:
            new = candidate
            break
    else:
        report = check_state(ctx, new)
    if kin_before.violation(report.com) > 1e-3:  # 2PAC: the COM must serve both sets
        return _fail(state, FailureReason.NOT_BALANCED, limb, "COM out of reach", 1)
    if not report.valid:
        reason = (
            FailureReason.COLLISION if not report.collision_free else FailureReason.NOT_BALANCED
        )
        return _fail(state, reason, limb, f"released state invalid: {report}", 1)
    return ContactAttempt(True, new, None, 1, "", limb)


def stand_state(
    ctx: ContactContext,
    q0: FloatArray,
    surfaces: Mapping[str, int],
    points: Mapping[str, FloatArray] | None = None,
) -> ContactAttempt:
    """A balanced state with each limb of ``surfaces`` on its surface id (at ``points[limb]``
    (3,) when given, else the surface centroid), by whole-body IK from ``q0`` (nq,)."""
    placed: dict[str, FloatArray] = {}
    tasks: list[Task] = []
    for limb, sid in surfaces.items():
        if not ctx.has_limb(limb):
            state = ContactState(q0, ())
            return _fail(state, FailureReason.UNKNOWN_LIMB, limb, f"unknown limb {limb!r}")
        surface = ctx.scene.surfaces[sid]
        p = surface.centroid if points is None or limb not in points else points[limb]
        placed[limb] = np.asarray(surface.closest_point(np.asarray(p)[None])[0])
        tasks.append(_contact_task(ctx, limb, placed[limb], surface.normal))
    centre = np.mean(list(placed.values()), axis=0)
    q = np.array(q0)
    for _ in range(2):
        result = solve_ik(
            ctx.model,
            q,
            [*tasks, ComTask(centre, (True, True, False)), posture_task(ctx)],
            data=ctx.pin_data,
            max_iterations=300,
        )
        q = np.array(result.q)
    contacts = tuple(make_contact(ctx, limb, q, sid) for limb, sid in surfaces.items())
    state = ContactState(q, contacts)
    report = check_state(ctx, state)
    if not report.valid:
        return _fail(state, FailureReason.INVALID_STATE, "", f"standing state invalid: {report}")
    return ContactAttempt(True, state, None, 1, "", "")


def state_from_configuration(
    ctx: ContactContext, q: FloatArray, contacts: Mapping[str, int | None]
) -> ContactAttempt:
    """A state from a configuration ``q`` (nq,) and the limbs in contact, each with its
    surface id or None (then the allowed surface nearest to the contact points). The
    contacts are placed where ``q`` puts the effectors; the state is validated with
    :func:`check_state` (INVALID_STATE on failure, with the report in the message)."""
    qq = np.asarray(q, dtype=np.float64)
    empty = ContactState(qq, ())
    if qq.shape != (ctx.model.nq,) or not np.all(np.isfinite(qq)):
        return _fail(empty, FailureReason.INVALID_STATE, "", f"q must be ({ctx.model.nq},)")
    placed: list[LimbContact] = []
    for limb, sid in contacts.items():
        if not ctx.has_limb(limb):
            return _fail(empty, FailureReason.UNKNOWN_LIMB, limb, f"unknown limb {limb!r}")
        pose = effector_pose(ctx, limb, qq)
        if sid is None:
            sid = _nearest_surface(ctx, limb, pose)
            if sid is None:
                return _fail(empty, FailureReason.NOT_IN_CONTACT, limb, f"{limb}: no surface")
        elif not 0 <= sid < len(ctx.scene.surfaces):
            return _fail(empty, FailureReason.UNKNOWN_SURFACE, limb, f"surface {sid} unknown")
        placed.append(make_contact(ctx, limb, qq, int(sid)))
    state = ContactState(qq, tuple(placed))
    report = check_state(ctx, state)
    if not report.valid:
        return _fail(state, FailureReason.INVALID_STATE, "", f"state invalid: {report}")
    return ContactAttempt(True, state, None, 0, "", "")


def _nearest_surface(ctx: ContactContext, limb: str, pose: FloatArray) -> int | None:
    best: tuple[float, int] | None = None
    for sid in ctx.surfaces:
        surface = ctx.scene.surfaces[sid]
        pts = contact_points_at(ctx, limb, pose, surface.normal)
        gap = float(np.max(np.abs(surface.height(pts))))
        if gap > ctx.params.surface_tolerance or not bool(np.all(surface.contains_projection(pts))):
            continue
        if best is None or gap < best[0]:
            best = (gap, sid)
    return None if best is None else best[1]
