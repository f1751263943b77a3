"""The contact planner's scene collision test against coal, shape by shape: the shapes it
skips on their bounding balls (outside the box of the scene and its obstacles) are those coal
finds touching nothing."""

from __future__ import annotations

import coal
import numpy as np
import pinocchio as pin
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.contact.checks import scene_collisions
from planner.contact.context import make_context
from planner.shapes import Box
from tests.planner.contact.contact_helpers import character_and_data, scene


def _touching_by_coal(world_bvh, obstacles, geometry, data, model, q):  # type: ignore[no-untyped-def]
    """Names of the shapes of ``geometry`` at ``q`` that coal finds touching the mesh or an
    obstacle ((coal geometry, coal.Transform3s)), every shape tested."""
    gdata = pin.GeometryData(geometry)
    pin.updateGeometryPlacements(model, data, geometry, gdata, q)
    names = []
    for k, obj in enumerate(geometry.geometryObjects):
        placement = gdata.oMg[k]
        transform = coal.Transform3s(placement.rotation, placement.translation)
        targets = [(world_bvh, coal.Transform3s()), *obstacles]
        for target, target_tf in targets:
            result = coal.CollisionResult()
            if coal.collide(
                target, target_tf, obj.geometry, transform, coal.CollisionRequest(), result
            ):
                names.append(str(obj.name))
                break
    return names


@settings(max_examples=25, deadline=None)
@given(
    name=st.sampled_from(["flat", "rubble", "stairs"]),
    character_id=st.sampled_from(["humanoid", "hexapod"]),
    seed=st.integers(0, 2**31 - 1),
    with_box=st.booleans(),
)
def test_scene_collisions_are_coals_shape_by_shape(
    name: str, character_id: str, seed: int, with_box: bool
) -> None:
    """Random postures at random heights around the scene's surface (some above it, some
    through it, some beside it), with and without a box obstacle beside the scene: the
    shapes scene_collisions names are those coal finds touching the mesh or the box."""
    character, data = character_and_data(character_id)
    world = scene(name)
    rng = np.random.default_rng(seed)
    box_pose = np.eye(4)
    box_pose[:3, 3] = [float(rng.uniform(4.2, 4.6)), 0.0, 0.5]
    obstacles = [(Box((0.3, 0.3, 0.5)), box_pose)] if with_box else []
    ctx = make_context(world, character, data, obstacles=obstacles)
    model = character.model
    pin_data = model.createData()
    coal_obstacles = [(g, tf) for g, tf, _, _ in ctx.obstacle_geometry]
    for _ in range(6):
        q = pin.randomConfiguration(model)
        q[:2] = rng.uniform(-4.5, 4.6, 2)
        q[2] = rng.uniform(-0.2, 1.5)
        got = sorted(scene_collisions(ctx, q))
        expected = sorted(
            _touching_by_coal(
                world.collision.bvh, coal_obstacles, character.geometry, pin_data, model, q
            )
        )
        assert got == expected
