"""Directed jump roadmap: build over sampled nodes, persist as .npz, query by shortest path.

Nodes are root configurations with a centroidal cone (``RoadmapNodes``); an edge i -> j is a
parabola steered from i to j (``steering.steer``). Takeoff and landing bounds and the two cones
differ, so j -> i is steered on its own, never reversed. Candidates come from a k-nearest or a
radius query (scipy cKDTree) limited to the reach bound, then the range pre-filter, then batched
steering, then the trunk collision check along the arc (eager, or lazily at query time, as in
Lazy PRM). Queries add the start and goal like any node and run Dijkstra (scipy csgraph).

Glossary: ``N`` nodes, ``E`` edges; ``src``, ``dst`` (E,) node indices; ``t`` (E,) the chosen
tan(alpha); ``t_lo``, ``t_hi`` its feasible interval; ``reach`` = (v0max^2 + vimpmax^2) / (2 g),
an upper bound on |p1 - p0| for any jump allowed by the speed bounds (add the two pre-filter
inequalities v0max^2 >= g (Z + r) and vimpmax^2 >= g (r - Z)).
"""

from __future__ import annotations

import enum
import hashlib
import json
from collections.abc import Callable, Collection, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from types import MappingProxyType
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import cKDTree

from planner.ballistic.arc import TrunkCollision, arcs_collision_free, search_collision_free
from planner.ballistic.steering import (
    GRAVITY,
    Choice,
    Jump,
    SteerFailure,
    jump_at,
    jumps_at,
    range_prefilter,
    steer,
    verify_jumps,
)
from planner.result import PlanResult, PlanStatus
from planner.termination import Termination, never

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.int64]

FORMAT = "gecko-jump-roadmap/1"
START, GOAL = -1, -2
"""Node ids of the query's start and goal in a ``JumpPath``."""


def _frozen(value: object, dtype: type = np.float64) -> NDArray[Any]:
    out: NDArray[Any] = np.array(value, dtype=dtype)
    out.flags.writeable = False
    return out


def _f(value: object) -> FloatArray:
    return np.asarray(_frozen(value), dtype=np.float64)


# --------------------------------------------------------------------------------------------
# Nodes and sampling


@dataclass(frozen=True, slots=True)
class RoadmapNodes:
    """N root configurations with their centroidal cones (world frame, SI units).

    positions : (N, 3) root positions (m). orientations : (N, 4) unit quaternions [x, y, z, w]
    (normalised here). cone_axes : (N, 3) centroidal cone axes (zero rows mean force closure).
    mus : (N,) cone friction coefficients. contacts : opaque per-node arrays, each with leading
    dimension N (e.g. contact points, limb ids), carried through take/concat and persistence.
    """

    positions: FloatArray
    orientations: FloatArray
    cone_axes: FloatArray
    mus: FloatArray
    contacts: Mapping[str, NDArray[np.generic]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        pos = np.asarray(self.positions, dtype=np.float64).reshape(-1, 3)
        n = len(pos)
        quat = np.asarray(self.orientations, dtype=np.float64).reshape(-1, 4)
        axes = np.asarray(self.cone_axes, dtype=np.float64).reshape(-1, 3)
        mus = np.asarray(self.mus, dtype=np.float64).reshape(-1)
        if quat.shape[0] != n or axes.shape[0] != n or mus.shape[0] != n:
            raise ValueError("positions, orientations, cone_axes and mus must have N rows")
        if not all(np.all(np.isfinite(x)) for x in (pos, quat, axes, mus)) or np.any(mus < 0):
            raise ValueError("node arrays must be finite and mus non-negative")
        norm = np.linalg.norm(quat, axis=1, keepdims=True)
        if np.any(norm < 1e-12):
            raise ValueError("orientations must be non-zero quaternions")
        contacts: dict[str, NDArray[np.generic]] = {}
        for key, value in self.contacts.items():
            array = np.array(value)
            if array.shape[:1] != (n,) or array.dtype == object:
                raise ValueError(f"contacts[{key!r}] must be a numeric array with N rows")
            array.flags.writeable = False
            contacts[str(key)] = array
        object.__setattr__(self, "positions", _f(pos))
        object.__setattr__(self, "orientations", _f(quat / norm))
        object.__setattr__(self, "cone_axes", _f(axes))
        object.__setattr__(self, "mus", _f(mus))
        object.__setattr__(self, "contacts", MappingProxyType(contacts))

    def __len__(self) -> int:
        return int(self.positions.shape[0])

    @staticmethod
    def single(
        position: FloatArray,
        orientation: FloatArray,
        cone_axis: FloatArray,
        mu: float,
        contacts: Mapping[str, NDArray[np.generic]] | None = None,
    ) -> RoadmapNodes:
        """One node from (3,), (4,), (3,) arrays and a mu; contact arrays get a leading 1."""
        return RoadmapNodes(
            positions=np.asarray(position, dtype=np.float64)[None],
            orientations=np.asarray(orientation, dtype=np.float64)[None],
            cone_axes=np.asarray(cone_axis, dtype=np.float64)[None],
            mus=np.array([mu], dtype=np.float64),
            contacts={k: np.asarray(v)[None] for k, v in (contacts or {}).items()},
        )

    def take(self, index: IntArray | slice) -> RoadmapNodes:
        """The nodes at ``index``."""
        return RoadmapNodes(
            self.positions[index],
            self.orientations[index],
            self.cone_axes[index],
            self.mus[index],
            {k: v[index] for k, v in self.contacts.items()},
        )

    def concat(self, other: RoadmapNodes) -> RoadmapNodes:
        """These nodes followed by ``other`` (contact keys must match)."""
        if set(self.contacts) != set(other.contacts):
            raise ValueError("contact keys differ")
        return RoadmapNodes(
            np.concatenate([self.positions, other.positions]),
            np.concatenate([self.orientations, other.orientations]),
            np.concatenate([self.cone_axes, other.cone_axes]),
            np.concatenate([self.mus, other.mus]),
            {k: np.concatenate([v, other.contacts[k]]) for k, v in self.contacts.items()},
        )


class NodeSampler(Protocol):
    """Draws valid root configurations (trunk free, enough limb workspaces on surfaces)."""

    def sample(self, n: int, *, rng: np.random.Generator) -> RoadmapNodes:
        """Up to n valid nodes (fewer if rejection sampling ran out); deterministic given rng."""
        ...


# --------------------------------------------------------------------------------------------
# Parameters


class Connection(enum.Enum):
    """KNEAREST: the k nearest nodes within the radius. RADIUS: every node within the radius,
    a random subset of ``neighbours`` of them when there are more (seeded rng at build time,
    all of them at query time)."""

    KNEAREST = "knearest"
    RADIUS = "radius"


class Cost(enum.Enum):
    """Edge cost for the shortest path: flight time (s), energy 0.5 |V0|^2 (J/kg), or 1/jump."""

    DURATION = "duration"
    ENERGY = "energy"
    JUMPS = "jumps"


class EdgeStatus(enum.IntEnum):
    """UNKNOWN: steered but the arc is not yet collision-checked (lazy). VALID: checked free."""

    UNKNOWN = 0
    VALID = 1


@dataclass(frozen=True, slots=True)
class RoadmapParams:
    """Everything a roadmap depends on besides the sampler; ``digest`` hashes it.

    v0max, vimpmax : takeoff / landing speed bounds (m/s). g : gravity (m/s^2). choice : the t
    policy. connection, neighbours, radius (m; None means ``reach``). cost : edge weight.
    max_gap : arc sampling gap for the trunk check (m). lazy : check arcs at query time.
    search : on a colliding arc, search the feasible interval of t (``arc.search_collision_free``)
    instead of rejecting. scene_key : caller's identifier of (scene, character, data versions).
    """

    v0max: float
    vimpmax: float
    g: float = GRAVITY
    choice: Choice = Choice.MIN_ENERGY
    connection: Connection = Connection.KNEAREST
    neighbours: int = 16
    radius: float | None = None
    cost: Cost = Cost.DURATION
    max_gap: float = 0.05
    lazy: bool = False
    search: bool = True
    scene_key: str = ""

    def __post_init__(self) -> None:
        if not (self.v0max > 0 and self.vimpmax > 0 and self.g > 0 and self.max_gap > 0):
            raise ValueError("v0max, vimpmax, g and max_gap must be positive")
        if self.neighbours < 1 or (self.radius is not None and not self.radius > 0):
            raise ValueError("neighbours must be >= 1 and radius positive")
        for name in ("v0max", "vimpmax", "g", "max_gap"):
            object.__setattr__(self, name, float(getattr(self, name)))
        if self.radius is not None:
            object.__setattr__(self, "radius", float(self.radius))
        object.__setattr__(self, "neighbours", int(self.neighbours))
        object.__setattr__(self, "choice", Choice(self.choice))
        object.__setattr__(self, "connection", Connection(self.connection))
        object.__setattr__(self, "cost", Cost(self.cost))

    @property
    def reach(self) -> float:
        """Upper bound on the length |p1 - p0| of any jump the speed bounds allow (m)."""
        return (self.v0max**2 + self.vimpmax**2) / (2.0 * self.g)

    @property
    def connection_radius(self) -> float:
        """The radius used for candidate neighbours (m)."""
        return min(self.reach, self.radius) if self.radius is not None else self.reach

    def to_json(self) -> str:
        """Canonical JSON (sorted keys)."""
        data = {
            "v0max": self.v0max,
            "vimpmax": self.vimpmax,
            "g": self.g,
            "choice": self.choice.value,
            "connection": self.connection.value,
            "neighbours": self.neighbours,
            "radius": self.radius,
            "cost": self.cost.value,
            "max_gap": self.max_gap,
            "lazy": self.lazy,
            "search": self.search,
            "scene_key": self.scene_key,
        }
        return json.dumps(data, sort_keys=True)

    @staticmethod
    def from_json(text: str) -> RoadmapParams:
        """Inverse of ``to_json``."""
        data = json.loads(text)
        return RoadmapParams(
            v0max=float(data["v0max"]),
            vimpmax=float(data["vimpmax"]),
            g=float(data["g"]),
            choice=Choice(data["choice"]),
            connection=Connection(data["connection"]),
            neighbours=int(data["neighbours"]),
            radius=None if data["radius"] is None else float(data["radius"]),
            cost=Cost(data["cost"]),
            max_gap=float(data["max_gap"]),
            lazy=bool(data["lazy"]),
            search=bool(data["search"]),
            scene_key=str(data["scene_key"]),
        )

    def digest(self) -> str:
        """SHA-256 hex digest of the canonical JSON."""
        return hashlib.sha256(self.to_json().encode()).hexdigest()


# --------------------------------------------------------------------------------------------
# Edges


@dataclass(frozen=True, slots=True)
class Edges:
    """E directed jumps. src, dst (E,) node indices; t, t_lo, t_hi (E,) slope and its feasible
    interval; duration (E,) s; energy (E,) 0.5 |V0|^2 J/kg; cost (E,); status (E,) int8."""

    src: IntArray
    dst: IntArray
    t: FloatArray
    t_lo: FloatArray
    t_hi: FloatArray
    duration: FloatArray
    energy: FloatArray
    cost: FloatArray
    status: NDArray[np.int8]

    def __post_init__(self) -> None:
        for name in ("src", "dst"):
            object.__setattr__(self, name, np.asarray(_frozen(getattr(self, name), np.int64)))
        for name in ("t", "t_lo", "t_hi", "duration", "energy", "cost"):
            object.__setattr__(self, name, _f(getattr(self, name)))
        object.__setattr__(self, "status", np.asarray(_frozen(self.status, np.int8)))

    def __len__(self) -> int:
        return int(self.src.shape[0])

    @staticmethod
    def empty() -> Edges:
        """No edges."""
        z = np.zeros(0)
        return Edges(
            np.zeros(0, np.int64), np.zeros(0, np.int64), z, z, z, z, z, z, np.zeros(0, np.int8)
        )

    def select(self, mask: BoolArray | IntArray) -> Edges:
        """A subset of the edges."""
        return Edges(*(getattr(self, f)[mask] for f in _EDGE_FIELDS))

    def concat(self, other: Edges) -> Edges:
        """These edges followed by ``other``."""
        return Edges(*(np.concatenate([getattr(self, f), getattr(other, f)]) for f in _EDGE_FIELDS))


_EDGE_FIELDS = ("src", "dst", "t", "t_lo", "t_hi", "duration", "energy", "cost", "status")


def _edge_cost(cost: Cost, duration: FloatArray, energy: FloatArray) -> FloatArray:
    if cost is Cost.DURATION:
        return duration
    if cost is Cost.ENERGY:
        return energy
    return np.ones_like(duration)


def _connect(
    nodes: RoadmapNodes,
    src: IntArray,
    dst: IntArray,
    params: RoadmapParams,
    collides_many: TrunkCollision | None,
    stats: dict[str, int],
) -> Edges:
    """Pre-filter, steer and (unless lazy) collision-check the directed pairs src -> dst."""
    p, ax, mu = nodes.positions, nodes.cone_axes, nodes.mus
    keep = range_prefilter(p[src], p[dst], params.v0max, params.vimpmax, params.g)
    stats["pairs"] = stats.get("pairs", 0) + len(src)
    stats["prefiltered_out"] = stats.get("prefiltered_out", 0) + int((~keep).sum())
    src, dst = src[keep], dst[keep]
    res = steer(
        p[src],
        p[dst],
        ax[src],
        mu[src],
        ax[dst],
        mu[dst],
        v0max=params.v0max,
        vimpmax=params.vimpmax,
        g=params.g,
        choice=params.choice,
    )
    for name, count in res.counts().items():
        stats[f"steer_{name}"] = stats.get(f"steer_{name}", 0) + count
    ok = res.ok
    src, dst = src[ok], dst[ok]
    t = res.t[ok].copy()
    lo, hi = res.t_interval[ok, 0], res.t_interval[ok, 1]
    status = np.full(len(src), EdgeStatus.UNKNOWN, dtype=np.int8)
    if collides_many is None:
        status[:] = EdgeStatus.VALID
    elif not params.lazy and len(src):
        valid, t = _check_edges(nodes, src, dst, t, lo, hi, params, collides_many, stats)
        src, dst, t, lo, hi = src[valid], dst[valid], t[valid], lo[valid], hi[valid]
        status = np.full(len(src), EdgeStatus.VALID, dtype=np.int8)
    v0, _, duration, _ = jumps_at(p[src], p[dst], t, params.g)
    energy = 0.5 * np.einsum("ij,ij->i", v0, v0)
    return Edges(
        src, dst, t, lo, hi, duration, energy, _edge_cost(params.cost, duration, energy), status
    )


def _check_edges(
    nodes: RoadmapNodes,
    src: IntArray,
    dst: IntArray,
    t: FloatArray,
    lo: FloatArray,
    hi: FloatArray,
    params: RoadmapParams,
    collides_many: TrunkCollision,
    stats: dict[str, int],
) -> tuple[BoolArray, FloatArray]:
    """Collision-check arcs (batched), then search t on the colliding ones; (valid, new t)."""
    p, q = nodes.positions, nodes.orientations
    v0, _, duration, _ = jumps_at(p[src], p[dst], t, params.g)
    free = arcs_collision_free(
        p[src], v0, duration, q[src], q[dst], collides_many, params.max_gap, params.g
    )
    stats["arcs_checked"] = stats.get("arcs_checked", 0) + len(src)
    t = t.copy()
    if params.search:
        for i in np.flatnonzero(~free):
            margin = 1e-6 * (hi[i] - lo[i])
            found = search_collision_free(
                p[src[i]],
                p[dst[i]],
                q[src[i]],
                q[dst[i]],
                (lo[i] + margin, hi[i] - margin),
                float(t[i]),
                collides_many,
                params.max_gap,
                params.g,
            )
            stats["searches"] = stats.get("searches", 0) + 1
            if found.ok:
                free[i] = True
                t[i] = found.t
                stats["searches_found"] = stats.get("searches_found", 0) + 1
        # The searched slopes lie inside the feasible intervals; re-check every bound anyway.
        bounds_ok = verify_jumps(
            p[src],
            p[dst],
            t,
            nodes.cone_axes[src],
            nodes.mus[src],
            nodes.cone_axes[dst],
            nodes.mus[dst],
            v0max=params.v0max,
            vimpmax=params.vimpmax,
            g=params.g,
        )
        free &= bounds_ok
    stats["arcs_colliding"] = stats.get("arcs_colliding", 0) + int((~free).sum())
    return free, t


def _candidates(
    tree: cKDTree,
    queries: FloatArray,
    params: RoadmapParams,
    rng: np.random.Generator | None,
) -> list[IntArray]:
    """Neighbour lists (indices into the tree's points) of each query point."""
    radius = params.connection_radius
    if params.connection is Connection.KNEAREST:
        k = min(params.neighbours + 1, tree.n)
        _, idx = tree.query(queries, k=k, distance_upper_bound=radius)
        idx = np.asarray(idx).reshape(len(queries), -1)
        return [row[row < tree.n].astype(np.int64) for row in idx]
    if rng is None:
        return [
            np.asarray(sorted(row), dtype=np.int64)
            for row in tree.query_ball_point(queries, r=radius)
        ]
    # A uniform random subset of each ball. Dense balls (at least DENSE of all nodes): draw
    # random nodes and keep those inside (cheap, the acceptance rate is high). Sparse balls:
    # list them and subsample.
    points = np.asarray(tree.data, dtype=np.float64)
    want = params.neighbours + 1
    counts = np.asarray(tree.query_ball_point(queries, r=radius, return_length=True))
    dense = counts >= _DENSE * tree.n
    out = [np.zeros(0, np.int64)] * len(queries)
    rows = np.flatnonzero(dense)
    draws = int(np.ceil(4 * want / _DENSE))
    for start in range(0, len(rows), 512):
        block = rows[start : start + 512]
        pick = rng.integers(0, tree.n, size=(len(block), draws))
        gap = points[pick] - queries[block, None, :]
        inside = np.einsum("ijk,ijk->ij", gap, gap) <= radius**2
        for i, row, mask in zip(block, pick, inside, strict=True):
            hits = row[mask]
            _, first = np.unique(hits, return_index=True)
            out[i] = np.sort(hits[np.sort(first)][:want])  # the first draws: a uniform subset
    sparse = np.flatnonzero(~dense)
    if len(sparse):
        for i, row in zip(sparse, tree.query_ball_point(queries[sparse], r=radius), strict=True):
            arr = np.asarray(sorted(row), dtype=np.int64)
            if len(arr) > want:
                arr = np.sort(rng.choice(arr, size=want, replace=False))
            out[i] = arr
    return out


_DENSE = 0.05
"""Radius connection: a ball holding at least this fraction of the nodes is sampled by
rejection rather than listed."""


# --------------------------------------------------------------------------------------------
# The roadmap


@dataclass(frozen=True, slots=True)
class Roadmap:
    """A built roadmap: parameters, nodes, directed edges and build statistics."""

    params: RoadmapParams
    nodes: RoadmapNodes
    edges: Edges
    stats: Mapping[str, int | float | str] = field(default_factory=dict)

    @property
    def digest(self) -> str:
        """The parameters hash this roadmap was built with."""
        return self.params.digest()

    def save(self, path: str | Path) -> None:
        """Write a .npz (no pickle): nodes, contacts, edges, parameters JSON and its digest."""
        arrays: dict[str, NDArray[np.generic]] = {
            "format": np.array(FORMAT),
            "params": np.array(self.params.to_json()),
            "digest": np.array(self.digest),
            "stats": np.array(json.dumps(dict(self.stats), sort_keys=True)),
            "node.positions": self.nodes.positions,
            "node.orientations": self.nodes.orientations,
            "node.cone_axes": self.nodes.cone_axes,
            "node.mus": self.nodes.mus,
        }
        for key, value in self.nodes.contacts.items():
            arrays[f"contact.{key}"] = value
        for name in _EDGE_FIELDS:
            arrays[f"edge.{name}"] = getattr(self.edges, name)
        with Path(path).open("wb") as handle:
            np.savez_compressed(handle, **arrays)  # type: ignore[arg-type]

    @staticmethod
    def load(path: str | Path, expected: RoadmapParams | None = None) -> Roadmap:
        """Read a roadmap written by ``save``.

        Raises ValueError if the file is not a roadmap, its digest does not match its own
        parameters, or (when ``expected`` is given) it was built with other parameters.
        """
        with np.load(Path(path), allow_pickle=False) as data:
            if "format" not in data or str(data["format"]) != FORMAT:
                raise ValueError(f"{path} is not a {FORMAT} file")
            params = RoadmapParams.from_json(str(data["params"]))
            digest = str(data["digest"])
            if digest != params.digest():
                raise ValueError("roadmap digest does not match its parameters")
            if expected is not None and expected.digest() != digest:
                raise ValueError("roadmap was built with different parameters")
            nodes = RoadmapNodes(
                positions=data["node.positions"],
                orientations=data["node.orientations"],
                cone_axes=data["node.cone_axes"],
                mus=data["node.mus"],
                contacts={
                    k[len("contact.") :]: data[k] for k in data.files if k.startswith("contact.")
                },
            )
            edges = Edges(*(data[f"edge.{name}"] for name in _EDGE_FIELDS))
            stats = json.loads(str(data["stats"]))
        return Roadmap(params=params, nodes=nodes, edges=edges, stats=stats)

    def query(
        self,
        start: RoadmapNodes,
        goal: RoadmapNodes,
        *,
        collides_many: TrunkCollision | None = None,
        node_clear: Callable[[int], bool] | None = None,
        refused: Collection[tuple[int, int]] = (),
        until: Termination = never,
    ) -> PlanResult[JumpPath]:
        """Shortest jump sequence from ``start`` to ``goal``; see ``query_roadmap``."""
        return query_roadmap(
            self,
            start,
            goal,
            collides_many=collides_many,
            node_clear=node_clear,
            refused=refused,
            until=until,
        )


def build_roadmap(
    sampler: NodeSampler,
    n_nodes: int,
    params: RoadmapParams,
    *,
    rng: np.random.Generator,
    collides_many: TrunkCollision | None = None,
    until: Termination = never,
    progress: Callable[[float], None] | None = None,
    batch: int = 256,
) -> PlanResult[Roadmap]:
    """Sample up to ``n_nodes`` nodes and connect them in both directions.

    Sampling takes the first tenth of the progress, connection the rest, in batches of
    ``batch`` nodes; ``until`` is polled between batches. ``collides_many`` None means no trunk
    check (every arc is free). Status: SOLVED when done; APPROXIMATE with the nodes and edges
    made so far when ``until`` fired (or the sampler ran dry) with at least one node; TIMEOUT
    (termination) or INFEASIBLE (sampler gave nothing) without nodes.
    """
    if n_nodes < 1 or batch < 1:
        raise ValueError("n_nodes and batch must be >= 1")
    report = progress if progress is not None else (lambda _fraction: None)
    stats: dict[str, int] = {}
    parts: list[RoadmapNodes] = []
    have = 0
    stopped = False
    dry = 0
    while have < n_nodes:
        if until():
            stopped = True
            break
        got = sampler.sample(min(batch, n_nodes - have), rng=rng)
        if len(got) == 0:
            dry += 1
            if dry >= 3:
                break
            continue
        parts.append(got)
        have += len(got)
        report(0.1 * have / n_nodes)
    if not parts:
        status = PlanStatus.TIMEOUT if stopped else PlanStatus.INFEASIBLE
        return PlanResult(status, None, {}, "no node sampled")
    nodes = parts[0]
    for part in parts[1:]:
        nodes = nodes.concat(part)

    tree = cKDTree(nodes.positions)
    pairs: list[IntArray] = []
    neighbours = _candidates(tree, nodes.positions, params, rng)
    for i, row in enumerate(neighbours):
        row = row[row != i]
        pairs.append(np.stack([np.full(len(row), i), row], axis=1))
        pairs.append(np.stack([row, np.full(len(row), i)], axis=1))
    flat = np.concatenate(pairs).astype(np.int64) if pairs else np.zeros((0, 2), np.int64)
    key = np.unique(flat[:, 0] * len(nodes) + flat[:, 1])
    src_all, dst_all = key // len(nodes), key % len(nodes)

    edges = Edges.empty()
    chunk = max(1, batch * params.neighbours)
    for start in range(0, len(src_all), chunk):
        if until():
            stopped = True
            break
        sl = slice(start, start + chunk)
        edges = edges.concat(
            _connect(nodes, src_all[sl], dst_all[sl], params, collides_many, stats)
        )
        report(0.1 + 0.9 * min(1.0, (start + chunk) / max(1, len(src_all))))
    report(1.0)
    all_stats: dict[str, int | float | str] = dict(stats)
    all_stats.update(nodes=len(nodes), edges=len(edges), stopped=int(stopped))
    roadmap = Roadmap(params=params, nodes=nodes, edges=edges, stats=all_stats)
    complete = not stopped and have >= n_nodes
    status = PlanStatus.SOLVED if complete else PlanStatus.APPROXIMATE
    message = "" if complete else ("terminated early" if stopped else "sampler ran dry")
    return PlanResult(status, roadmap, dict(all_stats), message)


# --------------------------------------------------------------------------------------------
# Query


@dataclass(frozen=True, slots=True)
class JumpPath:
    """A jump sequence. nodes : (m + 1,) roadmap node ids (START = -1, GOAL = -2).

    positions (m + 1, 3), orientations (m + 1, 4): the root at each node. t (m,), v0 (m, 3),
    vimp (m, 3), duration (m,): each jump. cost : the summed edge cost.
    """

    nodes: IntArray
    positions: FloatArray
    orientations: FloatArray
    t: FloatArray
    v0: FloatArray
    vimp: FloatArray
    duration: FloatArray
    cost: float
    g: float = GRAVITY

    def __len__(self) -> int:
        return int(self.t.shape[0])

    def jump_labels(self, i: int) -> tuple[int, int]:
        """Jump ``i``'s (takeoff, landing) node labels, as ``query_roadmap``'s ``refused``
        takes them."""
        return int(self.nodes[i]), int(self.nodes[i + 1])

    def jumps(self) -> list[Jump]:
        """The jumps as ``Jump`` values."""
        return [
            jump_at(self.positions[i], self.positions[i + 1], float(self.t[i]), self.g)
            for i in range(len(self))
        ]


def query_roadmap(
    roadmap: Roadmap,
    start: RoadmapNodes,
    goal: RoadmapNodes,
    *,
    collides_many: TrunkCollision | None = None,
    node_clear: Callable[[int], bool] | None = None,
    refused: Collection[tuple[int, int]] = (),
    until: Termination = never,
) -> PlanResult[JumpPath]:
    """Connect ``start`` (outgoing) and ``goal`` (incoming) like any node, then Dijkstra.

    start, goal : one node each. New edges, and stored edges still UNKNOWN (lazy roadmaps),
    are collision-checked only when they lie on the current shortest path; an invalid one is
    dropped and the search repeats (Lazy PRM). Likewise each roadmap node on the path is
    asked once of ``node_clear`` (its index in ``roadmap.nodes``; None: every node is
    clear), and a refused node's edges are dropped: a whole-body stance that collides where
    only the trunk was checked. The jumps of ``refused`` (pairs of node labels: a roadmap
    index, ``START`` or ``GOAL``) are left out: jumps the caller found the body cannot play.
    The roadmap itself is not modified.
    Statuses: SOLVED (a start equal to the goal gives zero jumps); INVALID_START / INVALID_GOAL
    when no feasible jump leaves the start / reaches the goal; INFEASIBLE when the graph does
    not connect them; TIMEOUT when ``until`` fires.
    """
    if len(start) != 1 or len(goal) != 1:
        raise ValueError("start and goal must be single nodes")
    params = roadmap.params
    base = roadmap.nodes
    n = len(base)
    s_id, g_id = n, n + 1
    stats: dict[str, int] = {}
    ends = RoadmapNodes(
        np.concatenate([start.positions, goal.positions]),
        np.concatenate([start.orientations, goal.orientations]),
        np.concatenate([start.cone_axes, goal.cone_axes]),
        np.concatenate([start.mus, goal.mus]),
    )
    everything = RoadmapNodes(
        np.concatenate([base.positions, ends.positions]),
        np.concatenate([base.orientations, ends.orientations]),
        np.concatenate([base.cone_axes, ends.cone_axes]),
        np.concatenate([base.mus, ends.mus]),
    )
    if np.linalg.norm(start.positions[0] - goal.positions[0]) <= 1e-9:
        empty = np.zeros(0)
        path = JumpPath(
            np.array([START], np.int64),
            start.positions,
            start.orientations,
            empty,
            np.zeros((0, 3)),
            np.zeros((0, 3)),
            empty,
            0.0,
            params.g,
        )
        return PlanResult(PlanStatus.SOLVED, path, {"jumps": 0}, "start equals goal")

    if n:
        tree = cKDTree(base.positions)
        out_nb = _candidates(tree, start.positions, params, None)[0]
        in_nb = _candidates(tree, goal.positions, params, None)[0]
    else:
        out_nb = in_nb = np.zeros(0, np.int64)
    src = np.concatenate([np.full(len(out_nb), s_id), in_nb, [s_id]]).astype(np.int64)
    dst = np.concatenate([out_nb, np.full(len(in_nb), g_id), [g_id]]).astype(np.int64)
    lazy_params = replace(params, lazy=True)
    new = _connect(everything, src, dst, lazy_params, collides_many, stats)
    if not np.any(new.src == s_id):
        return PlanResult(
            PlanStatus.INVALID_START, None, dict(stats), "no feasible jump from the start"
        )
    if not np.any(new.dst == g_id):
        return PlanResult(
            PlanStatus.INVALID_GOAL, None, dict(stats), "no feasible jump to the goal"
        )
    edges = roadmap.edges.concat(new)
    t = edges.t.copy()
    status = edges.status.copy()
    active = np.ones(len(edges), dtype=bool)
    ids_of = {START: s_id, GOAL: g_id}
    for a_label, b_label in refused:
        a_id, b_id = ids_of.get(a_label, a_label), ids_of.get(b_label, b_label)
        active &= ~((edges.src == a_id) & (edges.dst == b_id))
    cleared: dict[int, bool] = {}
    iterations = 0
    while True:
        if until():
            return PlanResult(PlanStatus.TIMEOUT, None, dict(stats), "terminated")
        iterations += 1
        graph = csr_matrix(
            (edges.cost[active], (edges.src[active], edges.dst[active])), shape=(n + 2, n + 2)
        )
        dist, pred = dijkstra(graph, directed=True, indices=s_id, return_predecessors=True)
        if not np.isfinite(dist[g_id]):
            stats["lazy_iterations"] = iterations
            return PlanResult(PlanStatus.INFEASIBLE, None, dict(stats), "goal not reachable")
        chain = [g_id]
        while chain[-1] != s_id:
            chain.append(int(pred[chain[-1]]))
        chain.reverse()
        a, b = np.array(chain[:-1]), np.array(chain[1:])
        # Edge ids along the path (pairs are unique among active edges).
        ids = _edge_ids(edges.src, edges.dst, active, a, b, n + 2)
        unknown = ids[status[ids] == EdgeStatus.UNKNOWN]
        if len(unknown) and collides_many is not None:
            valid, new_t = _check_edges(
                everything,
                edges.src[unknown],
                edges.dst[unknown],
                t[unknown],
                edges.t_lo[unknown],
                edges.t_hi[unknown],
                params,
                collides_many,
                stats,
            )
            t[unknown] = new_t
            status[unknown[valid]] = EdgeStatus.VALID
            active[unknown[~valid]] = False
            if not valid.all():
                continue
        if node_clear is not None:
            for node in chain[1:-1]:
                if node not in cleared:
                    cleared[node] = node_clear(node)
        vetoed = [node for node in chain[1:-1] if not cleared.get(node, True)]
        if vetoed:
            stats["nodes_refused"] = stats.get("nodes_refused", 0) + len(vetoed)
            gone = np.isin(edges.src, vetoed) | np.isin(edges.dst, vetoed)
            active &= ~gone
            continue
        stats["lazy_iterations"] = iterations
        break
    nodes_path = np.array(chain, dtype=np.int64)
    ids_final = ids
    p0, p1 = everything.positions[a], everything.positions[b]
    v0, vimp, duration, _ = jumps_at(p0, p1, t[ids_final], params.g)
    energy = 0.5 * np.einsum("ij,ij->i", v0, v0)
    cost = float(_edge_cost(params.cost, duration, energy).sum())
    labels = np.where(nodes_path == s_id, START, np.where(nodes_path == g_id, GOAL, nodes_path))
    path = JumpPath(
        nodes=np.asarray(_frozen(labels, np.int64)),
        positions=_f(everything.positions[nodes_path]),
        orientations=_f(everything.orientations[nodes_path]),
        t=_f(t[ids_final]),
        v0=_f(v0),
        vimp=_f(vimp),
        duration=_f(duration),
        cost=cost,
        g=params.g,
    )
    stats["jumps"] = len(path)
    return PlanResult(PlanStatus.SOLVED, path, dict(stats))


def _edge_ids(
    src: IntArray, dst: IntArray, active: BoolArray, a: IntArray, b: IntArray, size: int
) -> IntArray:
    """Indices of the active edges a[i] -> b[i]."""
    keys = np.where(active, src * size + dst, -1)
    order = np.argsort(keys, kind="stable")
    wanted = a * size + b
    pos = np.searchsorted(keys[order], wanted)
    return np.asarray(order[pos], dtype=np.int64)


__all__ = [
    "GOAL",
    "START",
    "Connection",
    "Cost",
    "EdgeStatus",
    "Edges",
    "JumpPath",
    "NodeSampler",
    "Roadmap",
    "RoadmapNodes",
    "RoadmapParams",
    "SteerFailure",
    "build_roadmap",
    "query_roadmap",
]
