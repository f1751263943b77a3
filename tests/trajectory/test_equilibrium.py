"""Static equilibrium: polytope vs the reference C++ library, vs the LP, degenerate cases."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import trajectory
from tests.trajectory.helpers import patch, random_phase
from trajectory import Contact, ContactPhase, equilibrium


def _oracle():  # type: ignore[no-untyped-def]
    try:
        from bench._oracles import ReferenceEquilibrium
    except ImportError as exc:  # pragma: no cover
        pytest.skip(str(exc))
    try:
        return ReferenceEquilibrium(70.0)
    except ImportError as exc:
        pytest.skip(str(exc))


def test_friction_rays_match_reference_construction() -> None:
    n = np.array([0.0, 0.0, 1.0])
    rays = trajectory.friction_rays(n, 0.5)
    t1 = np.cross(n, [0.0, 1.0, 0.0])
    t2 = np.cross(n, t1)
    ang = np.pi / 4 + np.arange(4) * np.pi / 2
    expected = n + 0.5 * (np.sin(ang)[:, None] * t1 + np.cos(ang)[:, None] * t2)
    expected /= np.linalg.norm(expected, axis=1, keepdims=True)
    np.testing.assert_allclose(rays, expected, atol=1e-15)
    # normal parallel to e_y falls back to n x e_x
    r2 = trajectory.friction_rays(np.array([0.0, 1.0, 0.0]), 0.5)
    assert np.all(np.isfinite(r2))
    assert trajectory.friction_rays(n, 0.5, 8).shape == (8, 3)


def test_agrees_with_hpp_centroidal_dynamics() -> None:
    """Same answer as the reference PP polytope for every COM farther than 1 mm from its
    boundary. Where cdd's floating-point polytope contradicts the reference's own LP
    (computeEquilibriumRobustness), the reference LP decides; sets where the reference
    perturbed its input after a cdd failure are skipped."""
    ref = _oracle()
    from bench._oracles import ReferenceEquilibrium

    ref_lp = ReferenceEquilibrium(70.0, algorithm="LP")
    rng = np.random.default_rng(3)
    n_sets, checked, tie_breaks = 0, 0, 0
    while n_sets < 500:
        k = int(rng.integers(1, 7))
        phase = random_phase(rng, k)
        pts = np.vstack([c.points for c in phase.contacts])
        nrm = np.vstack([np.tile(c.normal, (c.points.shape[0], 1)) for c in phase.contacts])
        if not ref.set_contacts(pts, nrm, 0.5):
            continue
        n_sets += 1
        A_ref, b_ref = ref.com_polytope()
        A, _b = trajectory.equilibrium_polytope(phase)
        assert np.allclose(A[:, 2], 0.0)
        centre = pts.mean(axis=0)
        coms = np.column_stack(
            [centre[:2] + rng.uniform(-0.8, 0.8, (60, 2)), rng.uniform(0.5, 1.2, 60)]
        )
        norms = np.linalg.norm(A_ref, axis=1)
        norms[norms == 0] = 1.0
        v_ref = ((coms @ A_ref.T - b_ref) / norms).max(axis=1)
        far = np.abs(v_ref) > 1e-3
        expected = v_ref <= 0
        ours = trajectory.is_static_equilibrium(phase, coms)
        for i in np.flatnonzero(far & (ours != expected)):
            ref_lp.set_contacts_fast(pts, nrm, 0.5)
            _status, robustness = ref_lp.robustness(coms[i])
            expected[i] = robustness >= 0.0
            tie_breaks += 1
        np.testing.assert_array_equal(ours[far], expected[far])
        checked += int(far.sum())
    assert checked > 10_000
    assert tie_breaks <= checked // 1000


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), k=st.integers(1, 4))
def test_polytope_consistent_with_lp(seed: int, k: int) -> None:
    rng = np.random.default_rng(seed)
    phase = random_phase(rng, k)
    poly = trajectory.equilibrium_halfspaces(phase)
    pts = np.vstack([c.points for c in phase.contacts]).mean(axis=0)
    for _ in range(6):
        com = np.array([*(pts[:2] + rng.uniform(-0.5, 0.5, 2)), 0.9])
        viol = float(poly.violation(com))
        margin = trajectory.equilibrium_margin(phase, com)
        if viol < -1e-4:
            assert margin.feasible
        elif viol > 1e-4:
            assert not margin.feasible


def _samples(seed: int, k: int) -> tuple[ContactPhase, np.ndarray, np.ndarray]:
    """A random phase of k contacts and 12 COM samples around it, positions (12, 3) over
    and beside its contacts and accelerations (12, 3), 30 % of them still."""
    rng = np.random.default_rng(seed)
    phase = random_phase(rng, k)
    pts = np.vstack([c.points for c in phase.contacts]).mean(axis=0)
    coms = np.column_stack([pts[:2] + rng.uniform(-0.6, 0.6, (12, 2)), rng.uniform(0.5, 1.2, 12)])
    accs = rng.uniform(-4.0, 4.0, (12, 3)) * (rng.random((12, 1)) < 0.7)
    return phase, coms, accs


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), k=st.integers(1, 4))
def test_margins_at_many_samples_are_those_of_one_sample_each(seed: int, k: int) -> None:
    """margins_at answers, sample by sample, exactly what equilibrium_margin does (feasible
    and infeasible COMs, still and accelerating), and refuses mismatched shapes."""
    phase, coms, accs = _samples(seed, k)
    feasible, margins = equilibrium.margins_at(phase, coms, accs)
    for c, a, ok, m in zip(coms, accs, feasible, margins, strict=True):
        one = trajectory.equilibrium_margin(phase, c, a)
        assert one.feasible == ok and one.margin == m
    with pytest.raises(ValueError, match="accs"):
        equilibrium.margins_at(phase, coms, accs[:3])
    empty = ContactPhase([], mass=70.0)
    none_ok, none_margin = equilibrium.margins_at(empty, coms[:2], accs[:2])
    assert not none_ok.any() and np.all(none_margin == -np.inf)


def test_flat_feet_region_is_support_polygon() -> None:
    foot = patch(np.zeros(3), np.array([0.0, 0.0, 1.0]), half=0.1)
    A, b = trajectory.equilibrium_polytope(ContactPhase([foot]))
    assert trajectory.is_static_equilibrium(ContactPhase([foot]), np.array([0.09, -0.09, 1.0]))
    assert not trajectory.is_static_equilibrium(ContactPhase([foot]), np.array([0.11, 0.0, 1.0]))
    ok = trajectory.is_static_equilibrium(
        ContactPhase([foot]), np.array([[0.0, 0.0, 3.0], [0.2, 0.0, 0.0]])
    )
    assert ok.tolist() == [True, False]
    assert A.shape[1] == 3 and b.ndim == 1


def test_degenerate_cases() -> None:
    up = np.array([0.0, 0.0, 1.0])
    # empty contact set: nothing is in equilibrium
    empty = ContactPhase([])
    _A, _b = trajectory.equilibrium_polytope(empty)
    assert not trajectory.is_static_equilibrium(empty, np.zeros(3))
    # one point contact: only the vertical line above it
    point = ContactPhase([Contact(points=np.array([[0.3, 0.2, 0.0]]), normal=up)])
    assert trajectory.is_static_equilibrium(point, np.array([0.3, 0.2, 1.0]))
    assert not trajectory.is_static_equilibrium(point, np.array([0.31, 0.2, 1.0]))
    # two point contacts: the segment between them
    two = ContactPhase(
        [
            Contact(points=np.array([[0.0, 0.0, 0.0]]), normal=up),
            Contact(points=np.array([[0.4, 0.0, 0.0]]), normal=up),
        ]
    )
    assert trajectory.is_static_equilibrium(two, np.array([0.2, 0.0, 1.0]))
    assert not trajectory.is_static_equilibrium(two, np.array([0.2, 0.01, 1.0]))
    assert not trajectory.is_static_equilibrium(two, np.array([0.5, 0.0, 1.0]))
    # hands pressing opposite walls: unbounded along the walls' axis, no exception
    walls = ContactPhase(
        [
            patch(np.array([0.5, 0.0, 1.0]), np.array([-1.0, 0.0, 0.0]), mu=1.0),
            patch(np.array([-0.5, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]), mu=1.0),
        ]
    )
    assert trajectory.is_static_equilibrium(walls, np.array([0.0, 0.0, 1.0]))
    margin = trajectory.equilibrium_margin(walls, np.array([0.0, 0.0, 1.0]))
    assert margin.feasible
    # coplanar patches on flat ground behave like their joint support polygon
    feet = ContactPhase(
        [patch(np.array([0.0, 0.1, 0.0]), up, 0.05), patch(np.array([0.0, -0.1, 0.0]), up, 0.05)]
    )
    assert trajectory.is_static_equilibrium(feet, np.array([0.0, 0.0, 0.9]))
    assert not trajectory.is_static_equilibrium(feet, np.array([0.0, 0.2, 0.9]))
    # a slope too steep for the friction cone: empty
    steep = np.array([np.sin(1.2), 0.0, np.cos(1.2)])
    assert not trajectory.is_static_equilibrium(
        ContactPhase([patch(np.zeros(3), steep, mu=0.3)]), np.array([0.0, 0.0, 1.0])
    )


def test_margin_positive_inside_negative_outside() -> None:
    foot = ContactPhase([patch(np.zeros(3), np.array([0.0, 0.0, 1.0]), half=0.1)])
    inside = trajectory.equilibrium_margin(foot, np.array([0.0, 0.0, 1.0]))
    outside = trajectory.equilibrium_margin(foot, np.array([0.3, 0.0, 1.0]))
    assert inside.feasible and inside.margin > 0
    w = foot.wrench_generators.T @ inside.weights
    np.testing.assert_allclose(w[:3], [0.0, 0.0, 70.0 * 9.81], atol=1e-5)
    assert not outside.feasible and outside.margin < 0


def test_validation_errors() -> None:
    with pytest.raises(ValueError, match="normal"):
        Contact(points=np.zeros((1, 3)), normal=np.array([0.0, 0.0, 2.0]))
    with pytest.raises(ValueError, match="points"):
        Contact(points=np.zeros((2, 2)), normal=np.array([0.0, 0.0, 1.0]))
    with pytest.raises(ValueError, match="mu"):
        Contact(points=np.zeros((1, 3)), normal=np.array([0.0, 0.0, 1.0]), mu=-1.0)
    with pytest.raises(ValueError, match="mass"):
        ContactPhase([], mass=0.0)
    with pytest.raises(ValueError, match="com"):
        trajectory.is_static_equilibrium(ContactPhase([]), np.zeros(2))


def test_polygon_memory_answers_as_computed_anew() -> None:
    """Remembered polygons equal fresh projections, cold or warm, in any order; a phase
    equal in content (another object) shares the answer; any change of a contact is a new
    phase; the answer is read-only."""
    from trajectory import equilibrium

    rng = np.random.default_rng(11)
    phases = [random_phase(rng, k) for k in (1, 2, 3, 2)]
    fresh = [equilibrium.project_polygon(p) for p in phases]
    equilibrium._POLYGONS.clear()
    for order in ([0, 1, 2, 3], [3, 2, 1, 0, 2]):
        for i in order:
            got = trajectory.equilibrium_polygon(phases[i])
            assert np.array_equal(got.A, fresh[i].A) and np.array_equal(got.b, fresh[i].b)
            assert not got.A.flags.writeable and not got.b.flags.writeable
    same = ContactPhase(
        [Contact(c.points.copy(), c.normal.copy(), c.mu) for c in phases[1].contacts],
        phases[1].mass,
    )
    assert trajectory.equilibrium_polygon(same) is trajectory.equilibrium_polygon(phases[1])
    first = phases[0].contacts[0]
    moved = ContactPhase(
        [Contact(first.points + np.array([0.01, 0.0, 0.0]), first.normal, first.mu)]
    )
    slippery = ContactPhase([Contact(first.points, first.normal, 0.5 * first.mu)])
    for other in (moved, slippery):
        want = equilibrium.project_polygon(other)
        got = trajectory.equilibrium_polygon(other)
        assert np.array_equal(got.A, want.A) and np.array_equal(got.b, want.b)


def test_remembered_generators_equal_fresh_ones() -> None:
    """A phase's wrench generators, built from contacts remembered by content, equal the
    generators computed anew, whichever phases came first; a contact differing in any field
    gets its own."""
    from trajectory import contacts

    rng = np.random.default_rng(5)
    phases = [random_phase(rng, k) for k in (3, 2, 4)]
    pool = [c for p in phases for c in p.contacts]
    fresh = {id(c): contacts.contact_generators(c) for c in pool}
    contacts._GENERATORS.clear()
    for order in (pool, pool[::-1]):
        for k in range(1, len(order) + 1):
            chosen = order[max(0, k - 3) : k]
            got = ContactPhase(chosen).wrench_generators
            assert np.array_equal(got, np.vstack([fresh[id(c)] for c in chosen]))
            assert not got.flags.writeable
    base = pool[0]
    for other in (
        Contact(base.points, base.normal, base.mu * 0.9),
        Contact(base.points, base.normal, base.mu, 6),
        Contact(base.points + 0.01, base.normal, base.mu),
    ):
        want = contacts.contact_generators(other)
        assert np.array_equal(ContactPhase([other]).wrench_generators, want)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), k=st.integers(1, 4))
def test_support_point_lp_agrees_with_highs(seed: int, k: int) -> None:
    """The support LP's primal answer through daqp (used where the dual's is not certified)
    reaches HiGHS' optimum in every direction, and says the same about the force bound."""
    from trajectory._types import TOL
    from trajectory.equilibrium import _projection_data, _Support

    rng = np.random.default_rng(seed)
    E, L, _ = _projection_data(random_phase(rng, k))
    ours, reference = _Support(E, L, TOL.force_bound), _Support(E, L, TOL.force_bound)
    for angle in rng.uniform(0.0, 2.0 * np.pi, 8):
        theta = np.array([np.cos(angle), np.sin(angle)])
        want = reference._highs(theta)
        got = ours._fallback(theta)
        if want is None:
            assert got is None
            continue
        assert got is not None
        assert abs(float(theta @ got) - float(theta @ want)) <= 1e-8
        assert ours.last_bound_active == reference.last_bound_active


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), k=st.integers(1, 4))
def test_holds_at_is_the_margin_within_the_tolerance(seed: int, k: int) -> None:
    """Where weights give the wrench (a finite margin), a sample holds Eq. 1 exactly when its
    margin is at least -EQ1_TOLERANCE times the mass; with no tolerance, when it is feasible."""
    phase, coms, accs = _samples(seed, k)
    feasible, margins = equilibrium.margins_at(phase, coms, accs)
    holds, same = trajectory.holds_at(phase, coms, accs)
    np.testing.assert_array_equal(same, margins)
    finite = np.isfinite(margins)
    limit = trajectory.EQ1_TOLERANCE * phase.mass
    np.testing.assert_array_equal(holds[finite], (feasible | (margins >= -limit))[finite])
    exact, _ = trajectory.holds_at(phase, coms, accs, tolerance=0.0)
    np.testing.assert_array_equal(exact[finite], feasible[finite])


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), k=st.integers(1, 4), noise=st.sampled_from([0.0, 1e-3]))
def test_holds_without_the_lp_answers_what_the_lp_does(seed: int, k: int, noise: float) -> None:
    """The samples that generator weights settle without the LP (the least-norm weights, or
    given weights corrected to the wrench) are answered as the LP answers them, with weights
    given near those of a sample's wrench or not at all, and some samples are settled so
    (the robust ones: a COM over its contacts, still)."""
    phase, coms, accs = _samples(seed, k)
    rng = np.random.default_rng(seed + 1)
    want = trajectory.holds_at(phase, coms, accs)[0]
    np.testing.assert_array_equal(equilibrium.holds(phase, coms, accs), want)
    feasible, _ = equilibrium.margins_at(phase, coms, accs)
    weights = np.array(
        [
            equilibrium.equilibrium_margin(phase, c, a).weights / (phase.mass * equilibrium.GRAVITY)
            if f
            else rng.uniform(0.0, 1.0, phase.wrench_generators.shape[0])
            for c, a, f in zip(coms, accs, feasible, strict=True)
        ]
    )
    weights += noise * rng.standard_normal(weights.shape)
    got = equilibrium.holds(phase, coms, accs, weights=weights)
    np.testing.assert_array_equal(got, want)


def test_holds_settles_a_still_com_over_its_feet_without_the_lp(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Four point feet round a still COM: the least-norm weights are positive and the LP is
    not asked; a COM far outside them is asked of the LP, which refuses it."""
    up = np.array([0.0, 0.0, 1.0])
    corners = [(0.3, 0.2), (0.3, -0.2), (-0.3, 0.2), (-0.3, -0.2)]
    phase = ContactPhase(
        [Contact(points=np.array([[x, y, 0.0]]), normal=up, mu=0.7) for x, y in corners],
        mass=30.0,
    )
    asked: list[int] = []
    lp = equilibrium.holds_at

    def counted(*args, **kwargs):  # type: ignore[no-untyped-def]
        asked.append(len(args[1]))
        return lp(*args, **kwargs)

    monkeypatch.setattr(equilibrium, "holds_at", counted)
    still = np.zeros((1, 3))
    assert equilibrium.holds(phase, np.array([[0.0, 0.0, 0.5]]), still).tolist() == [True]
    assert asked == []
    assert equilibrium.holds(phase, np.array([[2.0, 0.0, 0.5]]), still).tolist() == [False]
    assert asked == [1]


def _two_point_feet() -> ContactPhase:
    """Two point feet 0.6 m apart on level ground (a trot's diagonal): a cone of rank 5, no
    torque about the line between them."""
    up = np.array([0.0, 0.0, 1.0])
    feet = [np.array([[0.3, 0.2, 0.0]]), np.array([[-0.3, -0.2, 0.0]])]
    return ContactPhase([Contact(points=p, normal=up, mu=0.7) for p in feet], mass=70.0)


@pytest.mark.parametrize("offset", [0.0, 2e-6, -2e-6])
def test_two_point_feet_hold_a_com_off_their_line_by_round_off(offset: float) -> None:
    """A still COM above the line between two point feet holds Eq. 1; off it by micrometres
    (a wrench no weights give, margin -inf) it holds within the tolerance: the torque about
    the line, m g times the offset, is within EQ1_TOLERANCE times the mass of the cone."""
    phase = _two_point_feet()
    across = np.array([-0.2, 0.3, 0.0]) / np.hypot(0.2, 0.3)
    com = np.array([0.06, 0.04, 0.5]) + offset * across
    holds, margins = trajectory.holds_at(phase, com[None], np.zeros((1, 3)))
    assert holds[0]
    assert np.isfinite(margins[0]) == (offset == 0.0)


@pytest.mark.parametrize("offset", [1e-3, -1e-3])
def test_two_point_feet_do_not_hold_a_com_a_millimetre_off_their_line(offset: float) -> None:
    """A millimetre off the line, the torque about it (0.7 N m for 70 kg) is far beyond the
    tolerance: Eq. 1 does not hold, with or without it."""
    phase = _two_point_feet()
    across = np.array([-0.2, 0.3, 0.0]) / np.hypot(0.2, 0.3)
    com = np.array([0.06, 0.04, 0.5]) + offset * across
    holds, margins = trajectory.holds_at(phase, com[None], np.zeros((1, 3)))
    assert not holds[0] and margins[0] == -np.inf
