"""The independent motion auditor (``tests/motion_audit.py``) on synthetic motions and real
meshes: depths inside convex and non-convex solids, stance exemption, pops, root jumps, COM
curve errors, self-collision, coverage, and the JSON adapter."""

from __future__ import annotations

import coal
import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.motion_audit import (
    AuditCharacter,
    AuditScene,
    audit_character,
    audit_from_json,
    audit_motion,
    audit_scene,
    bezier_point,
    flights_from_contacts,
)

RATE = 30.0


def _ground_and(*parts: trimesh.Trimesh, ground_z: float = 0.0) -> AuditScene:
    """A 10 x 10 m ground sheet at ``ground_z`` plus the given solids, as one mesh."""
    ground = trimesh.Trimesh(
        [[-5, -5, ground_z], [5, -5, ground_z], [5, 5, ground_z], [-5, 5, ground_z]],
        [[0, 1, 2], [0, 2, 3]],
        process=False,
    )
    mesh = trimesh.util.concatenate([ground, *parts])
    return AuditScene(mesh.vertices, mesh.faces)


def _box(lo: tuple[float, float, float], hi: tuple[float, float, float]) -> trimesh.Trimesh:
    centre = (np.add(lo, hi)) / 2.0
    return trimesh.creation.box(
        extents=np.subtract(hi, lo), transform=trimesh.transformations.translation_matrix(centre)
    )


def _l_block(height: float = 1.0) -> trimesh.Trimesh:
    """A closed, non-convex L-shaped block: [0, 2] x [0, 0.8] and [0, 0.8] x [0, 2], z in
    [0, height]."""
    v2 = np.array([[0, 0], [2, 0], [2, 0.8], [0.8, 0.8], [0.8, 2], [0, 2], [0, 0.8]], float)
    f2 = np.array([[0, 1, 2], [0, 2, 3], [0, 3, 6], [6, 3, 4], [6, 4, 5]])
    return trimesh.creation.extrude_triangulation(v2, f2, height)


@pytest.fixture(scope="module")
def humanoid() -> AuditCharacter:
    return audit_character("humanoid")


def _standing(character: AuditCharacter, posture: np.ndarray | None = None) -> np.ndarray:
    """A posture (the reference one by default) with the lowest foot contact point at z = 0."""
    q = (character.q_reference if posture is None else posture).copy()
    character.place(q)
    low = min(
        float(character.contact_points(limb, (0.0, 0.0, 1.0))[:, 2].min())
        for limb in ("left_foot", "right_foot")
    )
    q[2] -= low
    return q


def _lowest_z(character: AuditCharacter, i: int) -> float:
    """Lowest z of a box collision object at the current placement."""
    rot, pos = character.object_pose(i)
    half = np.array(character.geometry.geometryObjects[i].geometry.halfSide)
    corners = np.array([[a, b, c] for a in (-1, 1) for b in (-1, 1) for c in (-1, 1)]) * half
    return float((corners @ rot.T + pos)[:, 2].min())


def _set(character: AuditCharacter, q: np.ndarray, **joints: float) -> np.ndarray:
    out = q.copy()
    for name, value in joints.items():
        out[7 + character.joint_names.index(name)] = value
    return out


# -- scene depths ---------------------------------------------------------------------------


def test_scene_components_classified() -> None:
    scene = _ground_and(
        _box((-0.5, -0.5, 0.0), (0.5, 0.5, 1.0)), _l_block().apply_translation((3, 0, 0))
    )
    kinds = sorted((obj.kind, obj.solid) for obj in scene.objects)
    assert kinds == [("convex", True), ("halfspace", True), ("mesh", True)]


def test_leg_sunk_into_a_box_is_penetrating(humanoid: AuditCharacter) -> None:
    q = _standing(humanoid)
    humanoid.place(q)
    feet = [i for i, name in enumerate(humanoid.link_names) if name in ("l_foot", "r_foot")]
    sole = min(_lowest_z(humanoid, i) for i in feet)
    # the box's top 3 cm above the soles; the ground far below
    scene = _ground_and(_box((-1.0, -1.0, -1.0), (1.0, 1.0, sole + 0.03)), ground_z=-2.0)
    assert sorted(o.kind for o in scene.objects) == ["convex", "halfspace"]
    free = audit_motion(humanoid, scene, [(0.0, q, ())])
    assert free.penetrating_frames == 1
    assert free.worst_penetration_m == pytest.approx(0.03, abs=1e-3)
    assert free.worst_penetration_link in ("l_foot", "r_foot")
    # the same feet in stance are exempt; nothing else reaches into the box
    held = audit_motion(humanoid, scene, [(0.0, q, ("left_foot", "right_foot"))])
    assert held.penetrating_frames == 0
    assert held.worst_penetration_m < 1e-6


def test_shin_pushed_into_a_block_beside_the_stance(humanoid: AuditCharacter) -> None:
    straight = _set(humanoid, humanoid.q_reference, l_hip_pitch=0.0, l_knee=0.0, l_ankle_pitch=0.0)
    q = _standing(humanoid, straight)  # the left shin vertical
    humanoid.place(q)
    shin = humanoid.link_names.index("l_shin")
    rot, pos = humanoid.object_pose(shin)
    geometry = humanoid.geometry.geometryObjects[shin].geometry
    # a block in front of the left shin, above the feet, 1 m away; then moved in by 3 cm
    y = float(pos[1])
    block = coal.Box(0.5, 0.1, 0.2)
    result = coal.DistanceResult()
    gap = coal.distance(
        geometry,
        coal.Transform3s(rot, pos),
        block,
        coal.Transform3s(np.eye(3), np.array([1.25, y, 0.25])),
        coal.DistanceRequest(),
        result,
    )
    assert 0.5 < gap < 1.0
    shift = gap + 0.03
    near = _ground_and(_box((1.0 - shift, y - 0.05, 0.15), (1.5 - shift, y + 0.05, 0.35)))
    audit = audit_motion(humanoid, near, [(0.0, q, ("left_foot", "right_foot"))])
    assert audit.penetrating_frames == 1
    assert audit.worst_penetration_link == "l_shin"
    assert audit.worst_penetration_m == pytest.approx(0.03, abs=2e-3)


@settings(max_examples=40)
@given(
    kind=st.sampled_from(["convex", "mesh"]),
    radius=st.floats(0.02, 0.1),
    depth=st.floats(0.001, 0.2),
    x=st.floats(-0.1, 0.1),
    y=st.floats(-0.1, 0.1),
)
def test_sphere_depth_inside_a_solid(
    kind: str, radius: float, depth: float, x: float, y: float
) -> None:
    """A sphere reaching ``depth`` under a block's top face, far from its sides, is ``depth``
    deep (within 1 mm): a box (convex solid) or an L block (non-convex closed mesh: coal's
    triangle depth and the inside test)."""
    scene = _scene_for(kind)
    centre = np.array([x, y, 0.0]) + (_BOX_CENTRE if kind == "convex" else _L_CENTRE)
    centre[2] = 1.0 - depth + radius
    d, which = scene.signed_distance(coal.Sphere(radius), np.eye(3), centre)
    assert scene.objects[which].kind == kind
    assert -d == pytest.approx(depth, abs=1e-3)


_BOX_CENTRE = np.array([0.0, 0.0, 0.0])
_L_CENTRE = np.array([0.4, 0.4, 0.0])
_SCENES: dict[str, AuditScene] = {}


def _scene_for(kind: str) -> AuditScene:
    if kind not in _SCENES:
        solid = _box((-0.5, -0.5, 0.0), (0.5, 0.5, 1.0)) if kind == "convex" else _l_block()
        _SCENES[kind] = _ground_and(solid)
    return _SCENES[kind]


def test_link_wholly_inside_a_non_convex_solid() -> None:
    """Deep inside, touching no triangle: still found, at its depth (lower bound)."""
    scene = _scene_for("mesh")
    d, which = scene.signed_distance(coal.Sphere(0.05), np.eye(3), np.array([0.4, 0.4, 0.5]))
    assert scene.objects[which].kind == "mesh"
    assert -d == pytest.approx(0.4 + 0.05, abs=1e-3)  # 0.4 to the nearest face, plus radius


# -- kinematic figures ------------------------------------------------------------------------


def test_joint_step_of_half_a_radian_at_30_hz_is_a_pop(humanoid: AuditCharacter) -> None:
    q0 = _standing(humanoid)
    scene = _scene_for("convex")
    q1 = _set(humanoid, q0, l_knee=float(q0[7 + humanoid.joint_names.index("l_knee")]) + 0.5)
    audit = audit_motion(humanoid, scene, [(0.0, q0, ()), (1 / RATE, q1, ())])
    assert audit.pops == 1 and audit.pairs == 1
    assert audit.max_joint_speed == pytest.approx(15.0, rel=1e-6)
    assert audit.max_speed_joint == "l_knee"
    q2 = _set(humanoid, q0, l_knee=float(q0[7 + humanoid.joint_names.index("l_knee")]) + 0.2)
    slow = audit_motion(humanoid, scene, [(0.0, q0, ()), (1 / RATE, q2, ())])
    assert slow.pops == 0
    assert slow.max_joint_speed == pytest.approx(6.0, rel=1e-6)


def test_root_jump_counted_outside_flights_only(humanoid: AuditCharacter) -> None:
    q0 = _standing(humanoid)
    q1 = q0.copy()
    q1[0] += 0.10
    frames = [(0.0, q0, ("left_foot",)), (1 / RATE, q1, ())]
    scene = _scene_for("convex")
    assert audit_motion(humanoid, scene, frames).root_jumps == 1
    flights = flights_from_contacts(frames)
    assert flights == [(0.0, 1 / RATE)]
    assert audit_motion(humanoid, scene, frames, flights=flights).root_jumps == 0


def test_com_curve_offset_detected(humanoid: AuditCharacter) -> None:
    q0 = _standing(humanoid)
    com0 = humanoid.place(q0)
    times = np.arange(31) / RATE
    frames = []
    for t in times:
        q = q0.copy()
        q[0] += 0.3 * t  # the whole body slides 0.3 m along x in 1 s
        frames.append((float(t), q, ("left_foot", "right_foot")))
    # a cubic Bezier of the same straight line (control points at thirds)
    exact = [(0.0, 1.0, np.array([np.add(com0, [0.1 * i, 0.0, 0.0]) for i in range(4)]))]
    scene = _scene_for("convex")
    good = audit_motion(humanoid, scene, frames, com=exact)
    assert good.com_error_max_m < 1e-9
    offset = [(0.0, 1.0, exact[0][2] + [0.0, 0.05, 0.0])]
    bad = audit_motion(humanoid, scene, frames, com=offset)
    assert bad.com_error_p99_m == pytest.approx(0.05, abs=1e-9)
    assert bad.com_error_max_m == pytest.approx(0.05, abs=1e-9)
    assert good.pace_m_per_s == pytest.approx(0.3)
    assert good.still_com_fraction == 0.0
    assert good.tilt_max_deg == pytest.approx(0.0, abs=1e-9)


def test_a_folded_chest_is_a_trunk_tilt_a_bent_hip_is_not(humanoid: AuditCharacter) -> None:
    # the trunk is where the limbs branch and the chain up to it: pelvis and chest, not a
    # thigh carrying a seat and a foot
    names = {str(humanoid.model.names[j]) for j in humanoid.trunk_joints}
    assert names == {"root_joint", "torso_yaw", "torso_pitch"}
    assert audit_character("quadruped").trunk_joints == (1,)  # the root joint alone
    q0 = _standing(humanoid)
    scene = _scene_for("convex")
    folded = _set(humanoid, q0, torso_pitch=0.7)
    audit = audit_motion(humanoid, scene, [(0.0, q0, ()), (1.0, folded, ())])
    assert audit.tilt_max_deg == pytest.approx(0.0, abs=1e-9)
    assert audit.trunk_tilt_max_deg == pytest.approx(np.degrees(0.7), abs=1e-6)
    bent = _set(humanoid, q0, l_hip_pitch=-0.7)
    assert audit_motion(humanoid, scene, [(0.0, bent, ())]).trunk_tilt_max_deg == pytest.approx(
        0.0, abs=1e-9
    )


def test_bezier_point_is_bernstein() -> None:
    rng = np.random.default_rng(0)
    pts = rng.normal(size=(5, 3))
    s = 0.3
    from math import comb

    expected = sum(comb(4, i) * (1 - s) ** (4 - i) * s**i * pts[i] for i in range(5))
    assert np.allclose(bezier_point(pts, s), expected)


def test_self_collision_of_crossed_thighs(humanoid: AuditCharacter) -> None:
    q0 = _standing(humanoid)
    crossed = _set(humanoid, q0, l_hip_roll=-0.35, r_hip_roll=0.35)
    scene = _scene_for("convex")
    audit = audit_motion(humanoid, scene, [(0.0, q0, ()), (1 / RATE, crossed, ())])
    assert audit.self_collision_frames == 1
    assert audit.self_penetration[0] == 0.0
    assert audit.worst_self_collision_pair == "l_thigh/r_thigh"


def test_stance_error_coverage_and_spacing(humanoid: AuditCharacter) -> None:
    q0 = _standing(humanoid)
    humanoid.place(q0)
    up = (0.0, 0.0, 1.0)
    left = humanoid.contact_points("left_foot", up)
    right = humanoid.contact_points("right_foot", up)
    phases = [
        (0.0, 1.0, (("left_foot", left, up), ("right_foot", np.add(right, [0.004, 0.0, 0.0]), up))),
        (1.0, 2.0, (("left_foot", left, up),)),
        (2.0, 3.0, (("left_foot", left, up),)),
    ]
    frames = [(t, q0, ("left_foot", "right_foot")) for t in (0.0, 0.5, 1.0)]
    frames.append((1.0 + 1e-4, q0, ("left_foot",)))
    audit = audit_motion(humanoid, _scene_for("convex"), frames, phases)
    assert audit.stance_contact_error_m == pytest.approx(0.004, abs=1e-9)
    assert audit.phases_animated == 2 and audit.coverage == pytest.approx(2 / 3)
    assert audit.min_spacing_s == pytest.approx(1e-4)
    assert audit.close_pairs == 1


def test_json_answer_matches_domain(humanoid: AuditCharacter) -> None:
    q0 = _standing(humanoid)
    q1 = _set(humanoid, q0, l_knee=1.0)
    mesh = _ground_and(_box((-0.5, 1.0, 0.0), (0.5, 2.0, 1.0))).mesh
    frames = [(0.0, q0, ("left_foot",)), (1 / RATE, q1, ("left_foot",))]
    com = [(0.0, 1 / RATE, np.zeros((2, 3)))]
    response = {
        "keyframes": [
            {
                "t": t,
                "root": {"position": list(q[:3]), "orientation": list(q[3:7])},
                "joints": dict(zip(humanoid.joint_names, map(float, q[7:]), strict=True)),
                "contacts": list(c),
            }
            for t, q, c in frames
        ],
        "phases": [],
        "com": [{"t0": 0.0, "t1": 1 / RATE, "control_points": [[0, 0, 0], [0, 0, 0]]}],
    }
    direct = audit_motion(humanoid, AuditScene(mesh.vertices, mesh.faces), frames, com=com)
    answered = audit_from_json(response, "humanoid", (mesh.vertices, mesh.faces))
    assert answered.frames == 2
    assert answered.max_joint_speed == pytest.approx(direct.max_joint_speed)
    assert np.allclose(answered.com_error, direct.com_error)
    # the mesh as GET /v1/scenes/{id}/mesh serves it (binary STL)
    served = audit_from_json(response, "humanoid", mesh.export(file_type="stl"))
    assert served.worst_penetration_m == pytest.approx(direct.worst_penetration_m, abs=1e-6)
    assert sorted(o.kind for o in audit_scene(mesh.export(file_type="stl")).objects) == [
        "convex",
        "halfspace",
    ]


def _holed_ground() -> AuditScene:
    """A 10 x 10 m ground sheet at z = 0 with a 1 x 1 m square hole around the origin (debris
    set into the ground leaves such holes), and a box 4 m off so that the sheet is not the
    only component."""
    outer = [[-5, -5], [5, -5], [5, 5], [-5, 5]]
    inner = [[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]]
    vertices = [[x, y, 0.0] for x, y in outer + inner]
    faces = []
    for k in range(4):  # the ring between the squares, two triangles per side
        o0, o1, i0, i1 = k, (k + 1) % 4, 4 + k, 4 + (k + 1) % 4
        faces += [[o0, o1, i1], [o0, i1, i0]]
    sheet = trimesh.Trimesh(vertices, faces, process=False)
    mesh = trimesh.util.concatenate([sheet, _box((3.5, 3.5, 0.0), (4.0, 4.0, 0.5))])
    return AuditScene(mesh.vertices, mesh.faces)


def test_nothing_is_under_the_ground_where_its_sheet_has_a_hole() -> None:
    """A link below the ground's plane inside a hole of the sheet touches nothing; one
    crossing the hole's rim is as deep as it reaches past the rim's triangles; one under the
    sheet away from the hole is under the ground, at its true depth."""
    scene = _holed_ground()
    assert scene.objects[0].kind == "halfspace"
    sphere = coal.Sphere(0.05)
    d, _ = scene.signed_distance(sphere, np.eye(3), np.array([0.0, 0.0, -0.03]))
    assert d > 0.0  # 0.45 m from the rim, 8 cm of it below z = 0
    d, _ = scene.signed_distance(sphere, np.eye(3), np.array([0.53, 0.0, 0.0]))
    assert -d == pytest.approx(0.05, abs=2e-3)  # centred on the sheet's plane, 3 cm over it
    d, _ = scene.signed_distance(sphere, np.eye(3), np.array([2.0, 0.0, -0.03]))
    assert -d == pytest.approx(0.08, abs=1e-3)
