"""The motion's collision queries on a real robot's mesh hulls: the shortcuts that keep them
cheap (a shape's distance bounded by how far it moved since it was measured; pairs culled by
bounding capsules) never change an answer."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from planner.character import get_character, real_robot_ids
from planner.motion.checker import KeyframeChecker
from planner.motion.clearance import PairBroadPhase, SceneDistances
from tests.planner.contact.contact_helpers import scene

pytestmark = pytest.mark.skipif(not real_robot_ids(), reason="example-robot-data is not installed")


def _walk(character: object, steps: int, seed: int) -> list[np.ndarray]:
    """Configurations drifting from the reference posture, lowered toward the floor."""
    rng = np.random.default_rng(seed)
    model = character.model  # type: ignore[attr-defined]
    q = np.array(character.q_ref)  # type: ignore[attr-defined]
    out = []
    for _ in range(steps):
        v = np.zeros(model.nv)
        v[:3] = rng.normal(0.0, 0.01, 3) + np.array([0.0, 0.0, -0.004])
        v[3:6] = rng.normal(0.0, 0.01, 3)
        v[6:] = rng.normal(0.0, 0.05, model.nv - 6)
        q = pin.integrate(model, q, v)
        q[7:] = np.clip(q[7:], model.lowerPositionLimit[7:], model.upperPositionLimit[7:])
        out.append(np.array(q))
    return out


@pytest.mark.parametrize("cid", ["talos", "hyq"])
def test_settled_shapes_are_farther_than_the_threshold(cid: str) -> None:
    character = get_character(cid)
    model, geometry = character.model, character.motion_geometry
    data, gdata = model.createData(), pin.GeometryData(geometry)
    distances = SceneDistances(scene("flat").collision.bvh, (), geometry)
    skipped = 0
    for q in _walk(character, 60, 1):
        pin.forwardKinematics(model, data, q)
        pin.updateGeometryPlacements(model, data, geometry, gdata)
        settled = distances.settled(gdata, 0.05)
        for i, obj in enumerate(geometry.geometryObjects):
            d = distances.nearest(obj.geometry, gdata.oMg[i])
            if settled[i]:
                skipped += 1
                assert d > 0.05
            elif i % 2 == 0:  # half the shapes measured: the others keep older references
                distances.remember(i, d)
    assert skipped > 0


@pytest.mark.parametrize("cid", ["talos", "hyq"])
def test_the_keyframe_check_equals_the_brute_force_one(cid: str) -> None:
    character = get_character(cid)
    model, geometry = character.model, character.motion_geometry
    checker = KeyframeChecker(character, scene("flat").collision.bvh)
    data, gdata = model.createData(), pin.GeometryData(geometry)
    for request in gdata.distanceRequests:
        request.enable_signed_distance = True
    brute = SceneDistances(scene("flat").collision.bvh)
    broad = PairBroadPhase(geometry)
    for q in _walk(character, 40, 2):
        check = checker.check(q, ())
        pin.forwardKinematics(model, data, q)
        pin.updateGeometryPlacements(model, data, geometry, gdata)
        deepest = max(
            0.0,
            *(
                -brute.deepest(o.geometry, gdata.oMg[i])
                for i, o in enumerate(geometry.geometryObjects)
            ),
        )
        assert check.scene_depth == pytest.approx(deepest, abs=1e-9)
        pin.computeDistances(geometry, gdata)
        depths = [-float(r.min_distance) for r in gdata.distanceResults]
        assert check.self_depth == pytest.approx(max(0.0, *depths), abs=1e-9)
        near = set(broad.near(gdata, 0.0))
        assert all(k in near for k, d in enumerate(depths) if d >= 0.0)


@pytest.mark.parametrize("cid", ["talos", "hyq"])
def test_a_shape_inside_is_as_deep_as_its_deepest_contact(cid: str) -> None:
    """Outside the scene ``deepest`` is the signed distance; inside, the deepest of coal's
    per-triangle contacts, never shallower than the nearest triangle says (a walk sinking
    into the floor mesh)."""
    character = get_character(cid)
    model, geometry = character.model, character.motion_geometry
    data, gdata = model.createData(), pin.GeometryData(geometry)
    distances = SceneDistances(scene("flat").collision.bvh)
    inside = 0
    for q in _walk(character, 60, 3):
        pin.forwardKinematics(model, data, q)
        pin.updateGeometryPlacements(model, data, geometry, gdata)
        for i, obj in enumerate(geometry.geometryObjects):
            nearest = distances.nearest(obj.geometry, gdata.oMg[i])
            deepest = distances.deepest(obj.geometry, gdata.oMg[i])
            if nearest >= 0.0:
                assert deepest == nearest
            else:
                inside += 1
                assert deepest <= nearest
    assert inside > 0


def test_few_segment_distances_match_the_batched_ones() -> None:
    """The broad phase's plain-float capsule gaps (a handful of pairs) are the batched
    formula's, degenerate segments (points, parallel, touching) included."""
    from planner.character.collision import few_segment_distances, segment_distances

    rng = np.random.default_rng(4)
    ends = [rng.normal(size=(40, 3)) for _ in range(4)]
    ends[1][:5] = ends[0][:5]  # first segment a point
    ends[3][5:10] = ends[2][5:10]  # second segment a point
    ends[2][10:15] = ends[0][10:15] + 0.3  # parallel, shifted
    ends[3][10:15] = ends[1][10:15] + 0.3
    ends[2][15:20] = ends[1][15:20]  # touching end to end
    np.testing.assert_allclose(
        few_segment_distances(*ends), segment_distances(*ends), rtol=0.0, atol=1e-12
    )


def test_pairs_remembered_together_as_one_by_one() -> None:
    """The broad phase's ``remember_all`` leaves it as ``remember`` of each pair in turn
    does: the same pairs near at the next placements, the same bounds kept."""
    character = get_character("talos")
    model, geometry = character.model, character.motion_geometry
    data, gdata = model.createData(), pin.GeometryData(geometry)
    for request in gdata.distanceRequests:
        request.enable_signed_distance = True
    alone, together = PairBroadPhase(geometry), PairBroadPhase(geometry)
    for q in _walk(character, 40, 2):
        pin.forwardKinematics(model, data, q)
        pin.updateGeometryPlacements(model, data, geometry, gdata)
        near = alone.near(gdata, 0.05)
        assert together.near(gdata, 0.05) == near
        measured = []
        for k in near:
            pin.computeDistance(geometry, gdata, k)
            measured.append(float(gdata.distanceResults[k].min_distance))
            alone.remember(k, measured[-1])
        together.remember_all(near, measured)
        assert np.array_equal(alone.known, together.known)
        assert np.array_equal(alone.known_odometers, together.known_odometers)


@pytest.mark.parametrize("cid", ["talos", "hyq"])
def test_the_pair_broad_phase_misses_no_pair_within_its_margin(cid: str) -> None:
    """On a walk that moves the root and every joint, every declared pair within 5 cm (all
    pairs' distances computed) is among those the broad phase calls near, its odometers run
    in the trunk's frame; a body only carried along (the root moving, the joints still)
    tests no pair it once measured farther than the margin again."""
    character = get_character(cid)
    model, geometry = character.model, character.motion_geometry
    data, gdata = model.createData(), pin.GeometryData(geometry)
    for request in gdata.distanceRequests:
        request.enable_signed_distance = True
    broad = PairBroadPhase(geometry)
    assert broad.frame is not None  # a shape rides the root joint
    margin = 0.05

    def distances(q: np.ndarray) -> np.ndarray:
        pin.forwardKinematics(model, data, q)
        pin.updateGeometryPlacements(model, data, geometry, gdata)
        pin.computeDistances(geometry, gdata)
        return np.array([float(r.min_distance) for r in gdata.distanceResults])

    walk = _walk(character, 40, 3)
    for q in walk:
        d = distances(q)
        near = broad.near(gdata, margin)
        assert set(np.flatnonzero(d <= margin).tolist()) <= set(near)
        broad.remember_all(near, [float(d[k]) for k in near])
    carried = broad.near(gdata, margin)  # every pair measured at the last configuration
    broad.remember_all(carried, [float(d[k]) for k in carried])
    q = walk[-1].copy()
    for step in range(1, 11):
        q[:3] = walk[-1][:3] + step * np.array([0.03, 0.01, 0.0])
        yaw = 0.02 * step
        q[3:7] = pin.Quaternion(
            pin.Quaternion(walk[-1][3:7]).toRotationMatrix() @ pin.rpy.rpyToMatrix(0, 0, yaw)
        ).coeffs()
        d = distances(q)
        near = broad.near(gdata, margin)
        assert set(near) == set(np.flatnonzero(d <= margin).tolist()) & set(carried)
        assert set(near) <= {k for k in carried if d[k] <= margin}


@settings(max_examples=200, deadline=None)
@example(ends=[0.0, 0.0, 1.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])  # a point mid-way
@example(ends=[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.3, 0.0, 1.0, 0.3, 0.0, -1.0])  # the other way
@example(ends=[0.0, 0.0, 0.0, 5e-4, 0.0, 0.0, 6e-4, -3e-4, 5e-5, 3e-4, 3e-4, 5e-5])  # crossing, mm
@given(
    ends=st.lists(
        st.floats(-1.0, 1.0, allow_nan=False, allow_infinity=False), min_size=12, max_size=12
    )
)
def test_segment_distances_are_the_closest_points_distance(ends: list[float]) -> None:
    """The capsule gap of the broad phases is the distance between the two segments'
    closest points: no pair of their points is closer, and points found by a fine search
    along both come within the search's resolution of it. A segment may be a point (a
    sphere's capsule: the feet of the hexapod and the quadrupeds): a point beside the middle
    of a segment is measured to that middle, not to the segment's first end; two short
    segments crossing at an angle are not taken for parallel. To a micrometre, and to 1e-5
    of the lengths for segments within 1e-5 rad of parallel (measured from the first one's
    start)."""
    from planner.character.collision import segment_distances

    p1, q1, p2, q2 = (np.array(ends[3 * k : 3 * k + 3]) for k in range(4))
    distance = float(segment_distances(p1[None], q1[None], p2[None], q2[None])[0])
    u = np.linspace(0.0, 1.0, 201)
    first = p1 + u[:, None] * (q1 - p1)
    second = p2 + u[:, None] * (q2 - p2)
    closest = float(np.min(np.linalg.norm(first[:, None] - second[None], axis=2)))
    lengths = float(np.linalg.norm(q1 - p1) + np.linalg.norm(q2 - p2))
    assert distance <= closest + 1e-5 * lengths + 1e-6
    assert closest <= distance + lengths / 200.0 + 1e-12
