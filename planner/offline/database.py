"""Per-limb sample database with a dict-free voxel-hash spatial index.

Samples are ranked by their weighted joint distance to the reference posture (index 0 is the
closest); every query returns indices in ascending order, i.e. best-ranked first.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

_BITS = 21
_BIAS = 1 << (_BITS - 1)
_MASK = (1 << _BITS) - 1


def _ro(array: Any, dtype: Any = np.float64) -> Any:
    out = np.array(array, dtype=dtype)
    out.flags.writeable = False
    return out


def voxel_keys(cells: NDArray[np.int64]) -> IntArray:
    """(n,) int64 keys of (n, 3) integer voxel coordinates (21 bits per axis)."""
    c = (cells + _BIAS) & _MASK
    return np.asarray((c[:, 0] << (2 * _BITS)) | (c[:, 1] << _BITS) | c[:, 2], dtype=np.int64)


@lru_cache(maxsize=16)
def _cube_cells(span: int) -> IntArray:
    """(span^3, 3) the integer offsets of a cube of ``span`` cells a side, x slowest
    (read-only)."""
    grid = np.stack(np.meshgrid(*(np.arange(span),) * 3, indexing="ij"), -1).reshape(-1, 3)
    grid.flags.writeable = False
    return grid


@dataclass(frozen=True, slots=True)
class SampleDatabase:
    """Limb samples in the root frame, ranked by distance to the reference posture.

    q : (n, k) limb joint values, rad (limb joint order). positions : (n, 3) effector frame
    origin, m; rotations : (n, 3, 3) effector orientation; jacobians : (n, 6, k) frame
    Jacobian [linear; angular] of the effector origin, axes of the root frame (Pinocchio's
    LOCAL_WORLD_ALIGNED with the root as world). cost : (n,) weighted joint distance to the
    reference posture, ascending. voxel_size : m. Index: ``keys`` (v,) sorted distinct voxel
    keys, ``starts`` (v + 1,) offsets into ``order`` (n,) sample indices grouped by voxel.
    """

    q: FloatArray
    positions: FloatArray
    rotations: FloatArray
    jacobians: FloatArray
    cost: FloatArray
    voxel_size: float
    keys: IntArray
    starts: IntArray
    order: IntArray

    def __len__(self) -> int:
        return int(self.q.shape[0])

    @staticmethod
    def build(
        q: FloatArray,
        positions: FloatArray,
        rotations: FloatArray,
        jacobians: FloatArray,
        cost: FloatArray,
        voxel_size: float,
        presorted: bool = False,
    ) -> SampleDatabase:
        """Rank the samples by ``cost`` (stable) unless ``presorted``, and index them."""
        rank = np.arange(len(cost)) if presorted else np.argsort(cost, kind="stable")
        pos = np.asarray(positions, dtype=np.float64)[rank]
        cells = np.floor(pos / voxel_size).astype(np.int64)
        keys = voxel_keys(cells)
        order = np.argsort(keys, kind="stable")
        uniq, first = np.unique(keys[order], return_index=True)
        starts = np.append(first, len(order))
        return SampleDatabase(
            _ro(np.asarray(q)[rank]),
            _ro(pos),
            _ro(np.asarray(rotations)[rank]),
            _ro(np.asarray(jacobians)[rank]),
            _ro(np.asarray(cost)[rank]),
            float(voxel_size),
            _ro(uniq, np.int64),
            _ro(starts, np.int64),
            _ro(order, np.int64),
        )

    def _gather(self, lo_cells: IntArray, hi_cells: IntArray) -> IntArray:
        """Sample indices in the voxels of the integer boxes [lo, hi] (k, 3), with repeats."""
        span = int((hi_cells - lo_cells).max()) + 1
        if span**3 * len(lo_cells) > 8 * len(self.keys) + 4096:
            return np.arange(len(self), dtype=np.int64)  # scanning everything is cheaper
        cells = lo_cells[:, None, :] + _cube_cells(span)[None, :, :]
        valid = np.all(cells <= hi_cells[:, None, :], axis=2)
        keys = voxel_keys(cells[valid])
        slot = self._match(keys)
        if len(slot) == 0:
            return np.zeros(0, dtype=np.int64)
        begin, end = self.starts[slot], self.starts[slot + 1]
        lengths = end - begin
        total = int(lengths.sum())
        offsets = np.repeat(begin - np.cumsum(lengths) + lengths, lengths)
        return np.asarray(self.order[offsets + np.arange(total)], dtype=np.int64)

    def _match(self, keys: IntArray) -> IntArray:
        """Positions in ``self.keys`` of the query keys that are present."""
        slot = np.searchsorted(self.keys, keys)
        inside = slot < len(self.keys)
        slot, keys = slot[inside], keys[inside]
        return np.asarray(slot[self.keys[slot] == keys], dtype=np.int64)

    def samples_near(self, points_root: FloatArray, radius: float) -> IntArray:
        """Sorted indices of samples within ``radius`` (m) of any of the (k, 3) points given in
        the root frame (best-ranked first)."""
        pts = np.atleast_2d(np.asarray(points_root, dtype=np.float64))
        if len(self) == 0 or len(pts) == 0:
            return np.zeros(0, dtype=np.int64)
        lo = np.floor((pts - radius) / self.voxel_size).astype(np.int64)
        hi = np.floor((pts + radius) / self.voxel_size).astype(np.int64)
        cand = self._gather(lo, hi)
        if len(cand) == 0:
            return cand
        # the distance test before the sort: np.unique then sorts the few samples kept, not
        # every sample of the voxels around (the same indices, each tested alike)
        d2 = np.min(np.sum((self.positions[cand, None, :] - pts[None]) ** 2, axis=2), axis=1)
        return np.asarray(np.unique(cand[d2 <= radius * radius]), dtype=np.int64)

    def samples_in_box(self, lower: FloatArray, upper: FloatArray) -> IntArray:
        """Sorted indices of samples whose position lies in the axis-aligned box
        [lower, upper] (3,) given in the root frame."""
        lo_p = np.asarray(lower, dtype=np.float64).reshape(3)
        hi_p = np.asarray(upper, dtype=np.float64).reshape(3)
        if len(self) == 0 or np.any(hi_p < lo_p):
            return np.zeros(0, dtype=np.int64)
        lo = np.floor(lo_p / self.voxel_size).astype(np.int64)[None]
        hi = np.floor(hi_p / self.voxel_size).astype(np.int64)[None]
        cand = np.unique(self._gather(lo, hi))
        p = self.positions[cand]
        keep = np.all((p >= lo_p) & (p <= hi_p), axis=1)
        return np.asarray(cand[keep], dtype=np.int64)
