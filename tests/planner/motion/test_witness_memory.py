"""The scene damper's witness memory (``clearance._superseded``): a new witness replaces the
remembered ones it sees the scene locally convex with (the same convex obstacle: its plane
alone keeps the shape out), and never those of a concave corner (a tread and the riser
rising from it), where the shape needs both half-spaces."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from planner.motion.clearance import _superseded

_FACES = [(axis, side) for axis in range(3) for side in (-1.0, 1.0)]


def _witness(point: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """A witness row (9,): scene point, unit normal, a body point (unused here)."""
    return np.concatenate((point, normal, np.zeros(3)))


def _box_witness(
    centre: np.ndarray, half: np.ndarray, rotation: np.ndarray, face: int, uv: tuple[float, float]
) -> np.ndarray:
    """The witness at a point of one face of a box (centre (3,), half extents (3,), rotation
    (3, 3)), at ``uv`` in [-1, 1]^2 across the face, with the face's outward normal."""
    axis, side = _FACES[face]
    local = np.zeros(3)
    local[axis] = side * half[axis]
    others = [a for a in range(3) if a != axis]
    local[others[0]] = uv[0] * half[others[0]]
    local[others[1]] = uv[1] * half[others[1]]
    normal = np.zeros(3)
    normal[axis] = side
    return _witness(centre + rotation @ local, rotation @ normal)


unit = st.floats(-1.0, 1.0)


@settings(max_examples=200, deadline=None)
@given(
    centre=st.tuples(*[st.floats(-2.0, 2.0)] * 3),
    half=st.tuples(*[st.floats(0.02, 0.5)] * 3),
    angles=st.tuples(*[st.floats(-np.pi, np.pi)] * 3),
    faces=st.tuples(st.integers(0, 5), st.integers(0, 5)),
    uvs=st.tuples(unit, unit, unit, unit),
)
def test_witnesses_of_one_convex_obstacle_supersede_each_other(
    centre: tuple[float, ...],
    half: tuple[float, ...],
    angles: tuple[float, ...],
    faces: tuple[int, int],
    uvs: tuple[float, ...],
) -> None:
    rotation = Rotation.from_euler("xyz", angles).as_matrix()
    box = (np.array(centre), np.array(half), rotation)
    old = _box_witness(*box, faces[0], uvs[:2])
    new = _box_witness(*box, faces[1], uvs[2:])
    assert _superseded([(1, old)], new) == []


@settings(max_examples=200, deadline=None)
@given(
    tread=st.floats(0.01, 0.3),
    riser=st.floats(0.01, 0.3),
    across=st.tuples(unit, unit),
    yaw=st.floats(-np.pi, np.pi),
)
def test_a_concave_corners_faces_are_both_remembered(
    tread: float, riser: float, across: tuple[float, float], yaw: float
) -> None:
    # a tread (z = 0, up to the riser at x = 0) and the riser rising from it (facing -x);
    # witnesses ``tread`` m before the corner and ``riser`` m up it, turned about z
    turn = Rotation.from_euler("z", yaw).as_matrix()
    on_tread = _witness(turn @ [-tread, across[0], 0.0], turn @ [0.0, 0.0, 1.0])
    on_riser = _witness(turn @ [0.0, across[1], riser], turn @ [-1.0, 0.0, 0.0])
    assert len(_superseded([(1, on_tread)], on_riser)) == 1
    assert len(_superseded([(1, on_riser)], on_tread)) == 1


def test_only_the_superseded_witnesses_are_forgotten() -> None:
    up = np.array([0.0, 0.0, 1.0])
    floor = _witness(np.array([0.0, 0.0, 0.0]), up)
    shelf = _witness(np.array([0.5, 0.0, 0.3]), -up)  # a shelf's underside above the floor
    again = _witness(np.array([0.1, 0.0, 0.0]), up)  # the floor seen again
    kept = _superseded([(1, floor), (2, shelf)], again)
    assert [step for step, _ in kept] == [2]
