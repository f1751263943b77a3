"""Footholds: where a contact patch fits on a surface, with free space above it."""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from planner.contact.body import body_geometry
from planner.contact.checks import lifts_clear, make_contact, scene_collisions
from planner.contact.context import ContactContext
from planner.contact.generation import (
    _HEADROOM_RADIUS,
    _patch_radius,
    _point_on,
    _uncovered,
    nearest_foothold,
)
from planner.scene.builtin import STAIRS_RISE, STAIRS_START_X, STAIRS_TREAD
from tests.planner.contact.twister_game import context, scene

STAIRS = scene("stairs")
SURFACES = [s for s in STAIRS.surfaces if s.area > 0.05]


@settings(max_examples=60, deadline=None)
@given(
    index=st.integers(0, len(SURFACES) - 1),
    offset=st.tuples(*[st.floats(-1.0, 1.0)] * 3),
    radius=st.floats(0.02, 0.13),
)
def test_point_on_leaves_room_for_the_disc(
    index: int, offset: tuple[float, float, float], radius: float
) -> None:
    surface = SURFACES[index]
    desired = surface.centroid + np.asarray(offset)
    point = _point_on(surface, desired, radius)
    if point is None:
        return
    assert abs(float(surface.height(point[None])[0])) < 1e-6  # on the surface plane
    assert surface.contains_projection(point[None], margin=radius - 1e-6)[0]
    # a point where the disc already fits is kept as it is
    again = _point_on(surface, point, radius)
    assert again is not None
    np.testing.assert_allclose(again, point, atol=1e-9)


def test_a_foot_keeps_its_place_along_a_tread() -> None:
    ctx = context("humanoid", "stairs", twister=False)
    radius = _patch_radius(ctx, "left_foot")
    tread = next(
        s
        for s in STAIRS.surfaces
        if abs(s.centroid[2] - STAIRS_RISE) < 1e-6 and abs(s.normal[2] - 1.0) < 1e-9
    )
    # 7 cm past the riser, 0.29 m to the side: pushed off the riser edge only
    point = _point_on(tread, np.array([STAIRS_START_X + 0.07, 0.29, STAIRS_RISE]), radius)
    assert point is not None
    assert abs(point[1] - 0.29) < 1e-9
    assert STAIRS_START_X + radius <= point[0] <= STAIRS_START_X + STAIRS_TREAD - radius


def test_no_foothold_under_the_stairs() -> None:
    """The ground runs on under the staircase; a foothold there would be inside it."""
    ctx = context("humanoid", "stairs", twister=False)
    inside = np.array([STAIRS_START_X + 0.5, 0.0, 0.0])
    found = nearest_foothold(ctx, "left_foot", inside, within=0.5)
    assert found is not None
    assert found[2] > STAIRS_RISE - 1e-6  # on a tread, not on the covered ground
    assert nearest_foothold(ctx, "left_foot", np.array([0.0, 0.0, 3.0]), within=0.5) is None


def test_a_point_foot_keeps_clear_of_a_riser() -> None:
    """A point foot's patch is a millimetre, its ankle and shin are not: a foothold on the
    ground hard against a step's riser would drive the shin into the step when the foot
    steps up from it (rubble_quadruped), so the free space above a foothold is at least
    ``_HEADROOM_RADIUS`` wide."""
    ctx = context("quadruped", "stairs", twister=False)
    radius = _patch_radius(ctx, "lf_foot")
    assert radius < _HEADROOM_RADIUS  # the case: the patch alone would allow it
    ground = next(
        i
        for i, s in enumerate(STAIRS.surfaces)
        if abs(s.centroid[2]) < 1e-6 and s.contains_projection(np.array([[0.0, 0.0, 0.0]]))[0]
    )
    for gap, free in ((0.01, False), (0.025, False), (0.04, True), (0.1, True)):
        point = np.array([STAIRS_START_X - gap, 0.0, 0.0])
        assert _uncovered(ctx, ground, point, radius) is free, gap


def _standing_with_right_foot_at(
    ctx: ContactContext, foot_xy: NDArray[np.float64], yaw: float
) -> Any:
    """The humanoid's reference posture turned ``yaw`` rad, moved so that its right foot's
    frame stands over ``foot_xy`` (2,) on the ground."""
    model, data = ctx.model, ctx.model.createData()
    q = np.array(ctx.character.q_ref, dtype=np.float64)
    q[3:7] = Rotation.from_euler("z", yaw).as_quat()
    pin.framesForwardKinematics(model, data, q)
    foot = data.oMf[ctx.character.limb("right_foot").frame_id].translation
    q[:2] += foot_xy - foot[:2]
    q[2] -= foot[2]
    return q


RUBBLE = scene("rubble")
RUBBLE_GROUND = max(range(len(RUBBLE.surfaces)), key=lambda i: RUBBLE.surfaces[i].area)


def test_a_sole_under_a_rock_overhang_cannot_lift_off() -> None:
    """A rubble rock tilts over the ground, its lowest edge 2 cm up. A sole whose toe stands
    under it touches nothing (as a state's checks test it) but cannot lift straight off
    without driving the toe into the rock: a humanoid walking diagonally across the rubble
    did, 44 mm; such a foothold is not taken. Beside no rock the same sole lifts clear."""
    ctx = context("humanoid", "rubble", twister=False)
    q = _standing_with_right_foot_at(ctx, np.array([1.632, 1.639]), np.radians(28.0))
    contact = make_contact(ctx, "right_foot", q, RUBBLE_GROUND)
    sole = sorted(body_geometry(ctx.character).exempt["right_foot"])
    assert not scene_collisions(ctx, q, only=sole, contacts=(contact,))
    assert not lifts_clear(ctx, q, contact, 0.1)
    away = _standing_with_right_foot_at(ctx, np.array([0.0, 0.5]), np.radians(28.0))
    assert lifts_clear(ctx, away, make_contact(ctx, "right_foot", away, RUBBLE_GROUND), 0.1)
