"""Planar polygon kernels: plane frames, areas, containment, clipping and boundary loops.

Polygons are (k, 2) float arrays of plane coordinates, counter-clockwise (positive signed
area) for outer boundaries and clockwise for holes. Kernels assume valid input.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


def plane_basis(normal: FloatArray) -> FloatArray:
    """(3, 3) rows u, v, n: an orthonormal right-handed frame (u x v = n) for a unit normal."""
    nx, ny, nz = (float(c) for c in np.asarray(normal, dtype=np.float64))
    length = (nx * nx + ny * ny + nz * nz) ** 0.5
    nx, ny, nz = nx / length, ny / length, nz / length
    hx, hy, hz = (1.0, 0.0, 0.0) if abs(nx) < 0.9 else (0.0, 1.0, 0.0)
    u = np.array([hy * nz - hz * ny, hz * nx - hx * nz, hx * ny - hy * nx])
    u /= float(np.sqrt(u @ u))
    n = np.array([nx, ny, nz])
    v = np.array([n[1] * u[2] - n[2] * u[1], n[2] * u[0] - n[0] * u[2], n[0] * u[1] - n[1] * u[0]])
    return np.asarray(np.stack([u, v, n]), dtype=np.float64)


def signed_area(polygon: FloatArray) -> float:
    """Shoelace signed area of a (k, 2) polygon; positive when counter-clockwise."""
    p = np.asarray(polygon, dtype=np.float64)
    if len(p) < 3:
        return 0.0
    q = np.roll(p, -1, axis=0)
    return 0.5 * float(np.sum(p[:, 0] * q[:, 1] - q[:, 0] * p[:, 1]))


def area_moments(polygon: FloatArray) -> tuple[float, FloatArray]:
    """(signed area, signed first moment (2,)) of a (k, 2) polygon; centroid = moment / area."""
    p = np.asarray(polygon, dtype=np.float64)
    if len(p) < 3:
        return 0.0, np.zeros(2)
    # Work relative to the first vertex to limit cancellation far from the origin.
    origin = p[0]
    r = p - origin
    q = np.roll(r, -1, axis=0)
    cross = r[:, 0] * q[:, 1] - q[:, 0] * r[:, 1]
    area = 0.5 * float(np.sum(cross))
    moment = np.sum((r + q) * cross[:, None], axis=0) / 6.0
    return area, np.asarray(moment + area * origin, dtype=np.float64)


def polygon_centroid(polygon: FloatArray) -> FloatArray:
    """(2,) area centroid of a (k, 2) polygon (vertex mean if its area is zero)."""
    area, moment = area_moments(polygon)
    if abs(area) < 1e-300:
        return np.asarray(np.mean(polygon, axis=0), dtype=np.float64)
    return np.asarray(moment / area, dtype=np.float64)


def clip_halfplanes(polygon: FloatArray, a: FloatArray, b: FloatArray) -> FloatArray:
    """Sutherland-Hodgman clip of a (k, 2) polygon by the half-planes ``a x <= b``.

    a : (m, 2), b : (m,). The polygon may be concave; the result keeps its orientation and its
    signed area is the area of the intersection (bridging edges may appear for concave input).
    Returns a (j, 2) array, j == 0 when nothing is left.
    """
    out = np.asarray(polygon, dtype=np.float64)
    for row, limit in zip(
        np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64), strict=True
    ):
        if len(out) == 0:
            break
        side = out @ row - limit  # <= 0 inside
        inside = side <= 0.0
        if np.all(inside):
            continue
        if not np.any(inside):
            return np.zeros((0, 2))
        nxt = np.roll(out, -1, axis=0)
        side_next = np.roll(side, -1)
        inside_next = np.roll(inside, -1)
        crossing = inside != inside_next
        t = side[crossing] / (side[crossing] - side_next[crossing])
        points = out[crossing] + t[:, None] * (nxt[crossing] - out[crossing])
        # Each vertex emits itself if inside, then the crossing point of its outgoing edge.
        slots = np.zeros((len(out), 2, 2))
        keep = np.zeros((len(out), 2), dtype=bool)
        slots[:, 0] = out
        keep[:, 0] = inside
        slots[crossing, 1] = points
        keep[:, 1] = crossing
        out = np.asarray(slots[keep], dtype=np.float64)
    return out


_BLOCK = 1 << 20  # entries per (points x edges) block, bounding temporary memory


def winding_numbers(points: FloatArray, loops: list[FloatArray]) -> NDArray[np.int64]:
    """(p,) winding number of (p, 2) points about the union of closed (k, 2) loops."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if not loops:
        return np.zeros(len(pts), dtype=np.int64)
    a, b = loop_edges(loops)
    return edge_winding_numbers(pts, a, b)


def loop_edges(loops: list[FloatArray]) -> tuple[FloatArray, FloatArray]:
    """The edges of closed (k, 2) loops: their starts (e, 2) and ends (e, 2)."""
    a = np.concatenate([np.asarray(loop, dtype=np.float64) for loop in loops])
    b = np.concatenate([np.roll(np.asarray(loop, dtype=np.float64), -1, axis=0) for loop in loops])
    return a, b


Edge = tuple[float, float, float, float]


def edge_tuples(a: FloatArray, b: FloatArray) -> tuple[Edge, ...]:
    """The edges (starts ``a`` (e, 2), ends ``b`` (e, 2)) as (ax, ay, bx, by) Python floats,
    for :func:`point_winding_number`."""
    return tuple(
        zip(a[:, 0].tolist(), a[:, 1].tolist(), b[:, 0].tolist(), b[:, 1].tolist(), strict=True)
    )


def point_winding_number(x: float, y: float, edges: Sequence[Edge]) -> int:
    """:func:`edge_winding_numbers` of the one point (x, y) about ``edges``
    (:func:`edge_tuples`), in scalar arithmetic: the same operations, so the same answer, at
    a tenth of the cost for one point and a few edges (a contact point on a tread or slab)."""
    total = 0
    for ax, ay, bx, by in edges:
        cross = (bx - ax) * (y - ay) - (by - ay) * (x - ax)
        if ay <= y:
            if by > y and cross > 0.0:
                total += 1
        elif by <= y and cross < 0.0:
            total -= 1
    return total


def edge_winding_numbers(points: FloatArray, a: FloatArray, b: FloatArray) -> NDArray[np.int64]:
    """:func:`winding_numbers` of (p, 2) points about loops given by their edges
    (:func:`loop_edges`: starts ``a`` (e, 2), ends ``b`` (e, 2), e > 0)."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    ax, ay, bx, by = a[None, :, 0], a[None, :, 1], b[None, :, 0], b[None, :, 1]
    total = np.zeros(len(pts), dtype=np.int64)
    step = max(1, _BLOCK // max(1, len(a)))
    for begin in range(0, len(pts), step):
        px, py = pts[begin : begin + step, 0:1], pts[begin : begin + step, 1:2]
        cross = (bx - ax) * (py - ay) - (by - ay) * (px - ax)
        up = (ay <= py) & (by > py) & (cross > 0)
        down = (ay > py) & (by <= py) & (cross < 0)
        total[begin : begin + step] = np.sum(up, axis=1) - np.sum(down, axis=1)
    return total


def closest_on_segments(
    points: FloatArray, starts: FloatArray, ends: FloatArray
) -> tuple[FloatArray, NDArray[np.int64], FloatArray]:
    """For (p, d) points, the nearest of the segments (s, d) starts -> ends.

    Returns (distance (p,), segment index (p,), parameter t in [0, 1] along it (p,)).
    """
    pts = np.asarray(points, dtype=np.float64)
    if pts.shape == (1, 2) and 0 < len(starts) <= _SCALAR_SEGMENTS:  # most queries
        return _closest_on_few_segments(pts[0], starts, ends)
    d = ends - starts
    length2 = np.einsum("ij,ij->i", d, d)
    length2 = np.where(length2 > 0.0, length2, 1.0)
    distance = np.zeros(len(pts))
    index = np.zeros(len(pts), dtype=np.int64)
    param = np.zeros(len(pts))
    step = max(1, _BLOCK // max(1, len(starts)))
    for begin in range(0, len(pts), step):
        block = pts[begin : begin + step]
        rel = block[:, None, :] - starts[None, :, :]
        t = np.clip(np.einsum("psj,sj->ps", rel, d) / length2[None, :], 0.0, 1.0)
        diff = rel - t[..., None] * d[None, :, :]
        dist2 = np.einsum("psj,psj->ps", diff, diff)
        best = np.argmin(dist2, axis=1)
        rows = np.arange(len(block))
        distance[begin : begin + step] = np.sqrt(dist2[rows, best])
        index[begin : begin + step] = best
        param[begin : begin + step] = t[rows, best]
    return distance, index, param


_SCALAR_SEGMENTS = 64  # up to this many segments, one 2D point's nearest in scalar arithmetic


def _closest_on_few_segments(
    point: FloatArray, starts: FloatArray, ends: FloatArray
) -> tuple[FloatArray, NDArray[np.int64], FloatArray]:
    """:func:`closest_on_segments` of one 2D point (2,) in scalar arithmetic: the same
    operations, segment by segment, as the arrays' (a contact placement asks about one point
    at a time, where the arrays' setup costs more than the arithmetic)."""
    px, py = point.tolist()
    best, best_t, best_d2 = 0, 0.0, np.inf
    for j, ((ax, ay), (bx, by)) in enumerate(zip(starts.tolist(), ends.tolist(), strict=True)):
        dx, dy = bx - ax, by - ay
        length2 = dx * dx + dy * dy
        if not length2 > 0.0:
            length2 = 1.0
        rx, ry = px - ax, py - ay
        t = (rx * dx + ry * dy) / length2
        t = 0.0 if t < 0.0 else (1.0 if t > 1.0 else t)
        ex, ey = rx - t * dx, ry - t * dy
        d2 = ex * ex + ey * ey
        if d2 < best_d2:
            best, best_t, best_d2 = j, t, d2
    return (
        np.array([np.sqrt(best_d2)]),
        np.array([best], dtype=np.int64),
        np.array([best_t]),
    )


_SMALL = 64


def _boundary_edges_small(faces: list[list[int]]) -> tuple[list[int], list[int]]:
    """Directed boundary edges (sorted) of a small face list, in pure Python."""
    counts: dict[tuple[int, int], int] = {}
    for a, b, c in faces:
        for edge in ((a, b), (b, c), (c, a)):
            counts[edge] = counts.get(edge, 0) + 1
    edges: list[tuple[int, int]] = []
    for (a, b), count in counts.items():
        net = count - counts.get((b, a), 0)
        edges += [(a, b)] * max(net, 0)
    edges.sort()
    return [a for a, _ in edges], [b for _, b in edges]


def _boundary_edges(f: IntArray) -> tuple[list[int], list[int]]:
    """Directed boundary edges (sorted) of a (t, 3) face array, vectorised."""
    src = f.ravel()
    dst = f[:, [1, 2, 0]].ravel()
    size = int(max(src.max(), dst.max())) + 1
    key = src * size + dst
    rev = dst * size + src
    uniq, first_idx, counts = np.unique(key, return_index=True, return_counts=True)
    pos = np.minimum(np.searchsorted(uniq, rev), len(uniq) - 1)
    rev_count = np.where(uniq[pos] == rev, counts[pos], 0)
    own_pos = np.searchsorted(uniq, key)
    net = counts[own_pos] - rev_count
    first = np.zeros(len(key), dtype=bool)
    first[first_idx] = True
    keep = first & (net > 0)
    edge_src = np.repeat(src[keep], net[keep])
    edge_dst = np.repeat(dst[keep], net[keep])
    order = np.lexsort((edge_dst, edge_src))
    return edge_src[order].tolist(), edge_dst[order].tolist()


def boundary_loops(faces: IntArray, coords: FloatArray) -> list[IntArray]:
    """Closed boundary loops of a consistently wound triangle set.

    faces : (t, 3) vertex indices, counter-clockwise in the 2D ``coords`` (n, 2) they index.
    Returns vertex-index loops: outer boundaries counter-clockwise, holes clockwise. A directed
    edge is on the boundary when its reverse is not used by another face of the set (counted
    with multiplicity). At pinch vertices the loop turns to stay with the triangle it came from,
    so bow-tie regions give two loops. Deterministic: loops start at their smallest edge index.
    """
    f = np.asarray(faces, dtype=np.int64)
    if len(f) == 0:
        return []
    if len(f) <= _SMALL:
        edge_src, edge_dst = _boundary_edges_small(f.tolist())
    else:
        edge_src, edge_dst = _boundary_edges(f)
    outgoing: dict[int, list[int]] = {}
    src_list = list(edge_src)
    dst_list = list(edge_dst)
    for index, start in enumerate(src_list):
        outgoing.setdefault(start, []).append(index)
    used = [False] * len(src_list)
    loops: list[IntArray] = []
    for seed in range(len(src_list)):
        if used[seed]:
            continue
        used[seed] = True
        start = src_list[seed]
        loop = [start]
        previous, current = start, dst_list[seed]
        while current != start:
            loop.append(current)
            candidates = [e for e in outgoing.get(current, []) if not used[e]]
            if not candidates:
                break
            if len(candidates) > 1:
                back = coords[previous] - coords[current]
                back_angle = np.arctan2(back[1], back[0])
                outs = coords[[dst_list[e] for e in candidates]] - coords[current]
                ccw = np.mod(back_angle - np.arctan2(outs[:, 1], outs[:, 0]), 2.0 * np.pi)
                choice = candidates[int(np.argmin(ccw))]
            else:
                choice = candidates[0]
            used[choice] = True
            previous, current = current, dst_list[choice]
        if len(loop) >= 3:
            loops.append(np.asarray(loop, dtype=np.int64))
    return loops


def _simplify_small(p: list[list[float]], tolerance: float) -> NDArray[np.bool_]:
    k = len(p)
    keep = []
    for i in range(k):
        (x0, y0), (x1, y1), (x2, y2) = p[i - 1], p[i], p[(i + 1) % k]
        bx, by, ax, ay = x1 - x0, y1 - y0, x2 - x1, y2 - y1
        cross = bx * ay - by * ax
        dot = bx * ax + by * ay
        scale = ((bx * bx + by * by) * (ax * ax + ay * ay)) ** 0.5
        straight = abs(cross) <= tolerance * max(scale, 1e-300) and dot > 0
        duplicate = (ax * ax + ay * ay) ** 0.5 <= 1e-15
        keep.append(not (straight or duplicate))
    if sum(keep) < 3:
        return np.ones(k, dtype=bool)
    return np.asarray(keep, dtype=np.bool_)


def simplify_loop(loop: FloatArray, tolerance: float = 1e-9) -> NDArray[np.bool_]:
    """(k,) mask of the vertices of a (k, 2) loop to keep: drops straight-through vertices."""
    p = np.asarray(loop, dtype=np.float64)
    if len(p) <= 3:
        return np.ones(len(p), dtype=bool)
    if len(p) <= _SMALL:
        return _simplify_small(p.tolist(), tolerance)
    before = p - np.roll(p, 1, axis=0)
    after = np.roll(p, -1, axis=0) - p
    cross = before[:, 0] * after[:, 1] - before[:, 1] * after[:, 0]
    dot = np.einsum("ij,ij->i", before, after)
    scale = np.linalg.norm(before, axis=1) * np.linalg.norm(after, axis=1)
    straight = (np.abs(cross) <= tolerance * np.maximum(scale, 1e-300)) & (dot > 0)
    duplicate = np.linalg.norm(after, axis=1) <= 1e-15
    keep = ~(straight | duplicate)
    if np.count_nonzero(keep) < 3:
        return np.ones(len(p), dtype=bool)
    return np.asarray(keep, dtype=np.bool_)
