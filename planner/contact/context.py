"""The context shared by the contact primitives: scene, collision world, character, offline data.

A :class:`ContactContext` owns Pinocchio scratch data and is therefore meant for one thread.
"""

from __future__ import annotations

import enum
import math
from collections import OrderedDict
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from planner.character import Character
from planner.offline import OfflineData
from planner.scene import CollisionWorld, Scene, SurfaceKind
from planner.scene.coal_shapes import coal_geometry, shape_world_matrix, to_transform
from planner.shapes import Box, Capsule
from trajectory import Halfspaces

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
Obstacle = tuple[Box | Capsule, FloatArray]
_CACHE_SIZE = 512
# values shared by every context of this process (see ContactContext.shared): key ->
# (character, offline data, value)
_SHARED: OrderedDict[Any, tuple[Character, OfflineData, Any]] = OrderedDict()
_SHARED_SIZE = 2048  # entries kept, the least recently used dropped first
_MISSING = object()  # a memo's miss (its values may be None or False)


class FailureReason(enum.Enum):
    """Why a contact primitive or a step failed."""

    NOTHING_REACHABLE = "NOTHING_REACHABLE"
    NOT_BALANCED = "NOT_BALANCED"
    COLLISION = "COLLISION"
    NOT_IN_CONTACT = "NOT_IN_CONTACT"
    ALREADY_IN_CONTACT = "ALREADY_IN_CONTACT"
    UNKNOWN_LIMB = "UNKNOWN_LIMB"
    UNKNOWN_SURFACE = "UNKNOWN_SURFACE"
    INVALID_STATE = "INVALID_STATE"
    INVALID_ACTION = "INVALID_ACTION"
    MOTION_FAILED = "MOTION_FAILED"


@dataclass(frozen=True, slots=True)
class ContactParams:
    """Tuning of contact generation.

    margin : robustness threshold of static equilibrium, N (smallest friction-cone generator
        weight, Del Prete et al. 2016). com_shrink : m, the equilibrium polygon is shrunk by
        this much when placing a COM. max_candidates : surface targets tried per creation.
    surface_tolerance : m, contact points must lie this close to their surface.
    normal_tolerance : rad between the effector contact normal and the surface normal.
    clearance : m, contacts are placed this far above the surface (anchor: 1e-3).
    lift : m, how far a freed effector is raised along the surface normal.
    allowed_surfaces : surface ids usable for contacts (None: every surface of ``kinds``).
    kinds : surface kinds usable for contacts. reach_radius : m, database samples this close
        to a target count as reaching it with the root fixed. body_reach : m, how much
        further than the limb alone a whole-body motion may reach. max_seeds : database
        postures tried per candidate (re-sampling a colliding limb). crouch_drops : m, COM
        drops tried before a whole-body reach when the limb alone cannot reach a target.
    """

    margin: float = 1.0
    com_shrink: float = 0.03
    max_candidates: int = 6
    surface_tolerance: float = 0.005
    normal_tolerance: float = math.radians(5.0)
    clearance: float = 1e-3
    lift: float = 0.06
    allowed_surfaces: tuple[int, ...] | None = None
    kinds: tuple[SurfaceKind, ...] = (SurfaceKind.SUPPORT,)
    reach_radius: float = 0.08
    body_reach: float = 0.5
    max_seeds: int = 3
    crouch_drops: tuple[float, ...] = ()
    ik_iterations: int = 150


@dataclass(slots=True)
class WorkCount:
    """Work done through a context, counted (never timed): a plan's work budget charges the
    contact search for it (``planner.budgets``). states_checked : calls of ``check_state``,
    each a candidate state's collision, balance and reach checks (and, before it, its IK)."""

    states_checked: int = 0


@dataclass(frozen=True, slots=True, eq=False)
class ContactContext:
    """Everything the primitives need; build with :func:`make_context`.

    world : scene collision world including obstacles (e.g. other characters).
    base_world : the same without ``obstacles`` (the (shape, (4, 4) pose) pairs added).
    surfaces : ids of the surfaces contacts may use. com_local : per limb, the COM half-spaces
    in the effector frame (2PAC Eq. 3). limb_dofs : per limb, its velocity indices (k,).
    work : the work done through this context, counted (states checked).
    """

    scene: Scene
    world: CollisionWorld
    character: Character
    data: OfflineData
    params: ContactParams
    surfaces: tuple[int, ...]
    com_local: dict[str, Halfspaces]
    pin_data: Any = field(repr=False)
    geom_data: Any = field(repr=False)
    base_world: CollisionWorld = field(repr=False)
    obstacles: tuple[Obstacle, ...] = ()
    obstacle_geometry: tuple[tuple[Any, Any, FloatArray, float], ...] = field(
        default=(), repr=False
    )
    cache: dict[Any, Any] = field(default_factory=dict, repr=False)
    work: WorkCount = field(default_factory=WorkCount, repr=False)
    by_state: dict[Any, Any] = field(default_factory=dict, repr=False)
    by_configuration: dict[Any, Any] = field(default_factory=dict, repr=False)

    def cached(self, key: Any, make: Callable[[], Any]) -> Any:
        """Memoise ``make()`` under ``key`` (bounded; cleared when full)."""
        hit = self.cache.get(key)
        if hit is None:
            if len(self.cache) > _CACHE_SIZE:
                self.cache.clear()
            hit = make()
            self.cache[key] = hit
        return hit

    def per_state(
        self, state: Any, key: Any, make: Callable[[], Any], *, in_cache: bool = False
    ) -> Any:
        """Memoise ``make()`` per ``state`` object and ``key`` (bounded; cleared when full),
        for a value that is a function of the state and the key alone. Kept apart from
        :meth:`cached`'s memory, whose clearing (and so the answers of the values it keeps
        by a rounded key) it leaves as it is, unless ``in_cache`` (the releases, remembered
        there since before: moving them would move those answers)."""
        memory = self.cache if in_cache else self.by_state
        full = (id(state), key)
        hit = memory.get(full)
        if hit is not None and hit[0] is state:  # not the id of a state since collected
            return hit[1]
        if hit is None and len(memory) > _CACHE_SIZE:
            memory.clear()
        value = make()
        memory[full] = (state, value)
        return value

    def per_configuration(self, q: FloatArray, key: Any, make: Callable[[], Any]) -> Any:
        """Memoise ``make()`` per configuration ``q`` (nq,; its exact values) and ``key``
        (bounded; cleared when full), for a value that is a function of them and of this
        context alone: a search checks the same configuration again (a state's collisions
        when its COM needs no shift before a release)."""
        full = (np.asarray(q, dtype=np.float64).tobytes(), key)
        hit = self.by_configuration.get(full, _MISSING)
        if hit is not _MISSING:
            return hit
        if len(self.by_configuration) > _CACHE_SIZE:
            self.by_configuration.clear()
        value = make()
        self.by_configuration[full] = value
        return value

    def shared(self, key: Any, make: Callable[[], Any]) -> Any:
        """Memoise ``make()`` under ``key`` for every context of this process with the same
        character and offline data (the least recently used dropped past ``_SHARED_SIZE``:
        a full memory no longer starts again from nothing). Only for a value that is a
        function of ``key``, the character and its offline data alone (never of the scene,
        the obstacles, the request or a rounded key), so that no answer depends on which
        request came before it: a Twister game asks for the same contact sets again."""
        full = (id(self.character), id(self.data), key)
        hit = _SHARED.get(full)
        if hit is not None and hit[0] is self.character and hit[1] is self.data:
            _SHARED.move_to_end(full)
            return hit[2]
        value = make()
        _SHARED[full] = (self.character, self.data, value)
        _SHARED.move_to_end(full)
        while len(_SHARED) > _SHARED_SIZE:
            _SHARED.popitem(last=False)
        return value

    @property
    def model(self) -> Any:
        """The character's Pinocchio model."""
        return self.character.model

    def limb_names(self) -> tuple[str, ...]:
        """Names of the default limbs (not the ``on_request`` ones) in the character's order."""
        return tuple(limb.name for limb in self.character.default_limbs)

    def has_limb(self, name: str) -> bool:
        """Whether the character has a limb called ``name``."""
        return any(limb.name == name for limb in self.character.limbs)

    def with_obstacles(self, obstacles: Sequence[Obstacle]) -> ContactContext:
        """The same context with extra obstacles in the collision world."""
        return make_context(
            self.scene,
            self.character,
            self.data,
            self.params,
            (*self.obstacles, *obstacles),
            world=self.base_world,
            cache=self.cache,
        )


def make_context(
    scene: Scene,
    character: Character,
    data: OfflineData,
    params: ContactParams | None = None,
    obstacles: Sequence[Obstacle] = (),
    *,
    world: CollisionWorld | None = None,
    cache: dict[Any, Any] | None = None,
    pin_data: Any = None,
) -> ContactContext:
    """A context over ``scene`` (or ``world``) with ``obstacles`` ((shape, (4, 4) world pose)
    pairs) added. ``cache`` shares memoised contact data with another context of the same
    scene, character and params. ``pin_data``: the context's pin.Data, lent by the caller
    for the context's life (default: its own)."""
    p = params or ContactParams()
    base = scene.collision if world is None else world
    full = base.with_obstacles(list(obstacles)) if obstacles else base
    if p.allowed_surfaces is None:
        surfaces = tuple(s.id for s in scene.surfaces if s.kind in p.kinds)
    else:
        surfaces = tuple(int(i) for i in p.allowed_surfaces)
    com_local = {}
    for limb in character.limbs:
        poly = data.com_constraint(limb.name).polytope
        com_local[limb.name] = Halfspaces(np.asarray(poly.A), np.asarray(poly.b))
    return ContactContext(
        scene,
        full,
        character,
        data,
        p,
        surfaces,
        com_local,
        character.model.createData() if pin_data is None else pin_data,
        pin.GeometryData(character.geometry),
        base,
        tuple(obstacles),
        tuple(_obstacle_geometry(shape, pose) for shape, pose in obstacles),
        {} if cache is None else cache,
    )


def _obstacle_geometry(
    shape: Box | Capsule, pose: FloatArray
) -> tuple[Any, Any, FloatArray, float]:
    """coal geometry, coal transform, bounding-ball centre (3,) and radius (m)."""
    matrix = shape_world_matrix(shape, np.asarray(pose, dtype=np.float64))
    if isinstance(shape, Box):
        radius = float(np.linalg.norm(shape.half_extents))
    else:
        radius = float(shape.radius + shape.half_length)
    return coal_geometry(shape), to_transform(matrix), matrix[:3, 3].copy(), radius


def character_obstacles(character: Character, q: FloatArray) -> list[Obstacle]:
    """The collision shapes of ``character`` posed at ``q`` (nq,) as world obstacles.

    Boxes stay boxes; cylinders and spheres become their bounding capsules.
    """
    model, geometry = character.model, character.geometry
    data = model.createData()
    gdata = pin.GeometryData(geometry)
    pin.updateGeometryPlacements(model, data, geometry, gdata, np.asarray(q, dtype=np.float64))
    out: list[Obstacle] = []
    for obj, placement in zip(geometry.geometryObjects, gdata.oMg, strict=True):
        pose = np.asarray(placement.homogeneous, dtype=np.float64)
        geom = obj.geometry
        name = type(geom).__name__
        if name == "Box":
            out.append((Box(np.asarray(geom.halfSide, dtype=np.float64)), pose))
        elif name == "Cylinder":
            out.append((Capsule(float(geom.radius), float(geom.halfLength)), pose))
        elif name == "Sphere":
            out.append((Capsule(float(geom.radius), 0.0), pose))
        elif name == "Capsule":
            out.append((Capsule(float(geom.radius), float(geom.halfLength)), pose))
    return out
