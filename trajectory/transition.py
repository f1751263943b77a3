"""Transition points between consecutive contact phases (Eq. 5, 6 and 13).

The transition COM must be in static equilibrium and kinematically feasible for both
phases. The QP always answers: the equilibrium rows get a slack s >= 0 weighted by w
(w = 1000 by default), and if even the kinematic rows cannot hold together they get their
own, heavier slack. ``feasible`` tells whether a quasi-static transition exists.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from trajectory import _solvers
from trajectory._types import TOL, FloatArray
from trajectory.contacts import ContactPhase, gravity_wrench
from trajectory.polytope import Halfspaces, stack

CostKind = Literal["distance", "tired", "groovy", "to_one_side", "low"]
COST_KINDS: tuple[str, ...] = ("distance", "tired", "groovy", "to_one_side", "low")


@dataclass(frozen=True, slots=True)
class TransitionCost:
    """Cost of the transition QP (2PAC section 7.3).

    kind:
      "distance"    ||c - c_prev||^2 (default, Eq. 6);
      "tired"       ||c - c_prev||^2 + ||c - target||^2 (least travel over both legs);
      "groovy"      distance minus strength * side * lateral offset, side alternating by
                    ``index`` parity (most lateral variation);
      "to_one_side" distance minus strength * lateral offset (always the same side);
      "low"         distance plus strength * c_z (lowest COM).
    strength in metres; lateral is horizontal and orthogonal to target - c_prev (y if unknown).
    """

    kind: CostKind = "distance"
    strength: float = 0.3
    index: int = 0

    def __post_init__(self) -> None:
        if self.kind not in COST_KINDS:
            raise ValueError(f"kind: expected one of {COST_KINDS}, got {self.kind!r}")
        if not np.isfinite(self.strength) or self.strength < 0:
            raise ValueError(f"strength: must be finite and >= 0, got {self.strength}")


@dataclass(frozen=True, slots=True, eq=False)
class TransitionPoint:
    """point (3,) world COM, metres; slack >= 0 (m for Eq. 6 rows, N for Eq. 13);
    feasible: a quasi-static transition exists; kinematic_slack > 0 when even the kinematic
    constraints could not hold."""

    point: FloatArray
    slack: float
    feasible: bool
    kinematic_slack: float = 0.0


def _cost_terms(
    cost: TransitionCost, c_prev: FloatArray, target: FloatArray | None
) -> tuple[FloatArray, FloatArray]:
    """Quadratic (3, 3) and linear (3,) parts of 0.5 c'Hc + f'c."""
    H = 2.0 * np.eye(3)
    f = -2.0 * c_prev
    if cost.kind == "tired" and target is not None:
        H = H + 2.0 * np.eye(3)
        f = f - 2.0 * target
    elif cost.kind in ("groovy", "to_one_side"):
        heading = np.array([1.0, 0.0, 0.0]) if target is None else target - c_prev
        heading = heading.copy()
        heading[2] = 0.0
        if np.linalg.norm(heading) < 1e-9:
            heading = np.array([1.0, 0.0, 0.0])
        lateral = np.array([-heading[1], heading[0], 0.0]) / np.linalg.norm(heading)
        side = -1.0 if (cost.kind == "groovy" and cost.index % 2) else 1.0
        f = f - 2.0 * cost.strength * side * lateral
    elif cost.kind == "low":
        f = f + np.array([0.0, 0.0, 2.0 * cost.strength])
    return H, f


def transition_qp(
    equilibrium: Halfspaces,
    kinematic: Halfspaces,
    c_prev: FloatArray,
    *,
    w: float = 1000.0,
    cost: TransitionCost | None = None,
    target: FloatArray | None = None,
) -> TransitionPoint:
    """QP of Eq. 6 on stacked polytopes: min cost(c) + w (s + s^2), A c - s <= a, K c <= k.

    The linear w s term makes the penalty exact, so s = 0 whenever a static solution exists.

    equilibrium: A c <= a (rows scaled to unit norm so s is in metres); kinematic: K c <= k.
    """
    cost = cost or TransitionCost()
    c_prev = np.asarray(c_prev, dtype=np.float64)
    Hc, fc = _cost_terms(cost, c_prev, target)
    m_a, m_k = equilibrium.A.shape[0], kinematic.A.shape[0]
    # variables (c (3), s_eq, s_kin); s_kin only used when the kinematic rows conflict
    for kin_soft in (False, True):
        n = 5 if kin_soft else 4
        H = np.zeros((n, n))
        H[:3, :3] = Hc
        H[3, 3] = 2.0 * w
        f = np.zeros(n)
        f[:3] = fc
        f[3] = w  # exact-penalty term: s = 0 whenever a static solution exists
        A = np.zeros((m_a + m_k, n))
        A[:m_a, :3] = equilibrium.A
        A[:m_a, 3] = -1.0
        A[m_a:, :3] = kinematic.A
        if kin_soft:
            H[4, 4] = 2.0 * w * 1e3
            f[4] = w * 1e3
            A[m_a:, 4] = -1.0
        lo_b = np.concatenate([np.full(3, -_solvers.INF), np.zeros(n - 3)])
        up_b = np.full(n, _solvers.INF)
        rhs = np.concatenate([equilibrium.b, kinematic.b])
        lower = np.concatenate([lo_b, np.full(m_a + m_k, -_solvers.INF)])
        res = _solvers.solve(H, f, A, np.concatenate([up_b, rhs]), lower)
        if res.ok:
            s = max(float(res.x[3]), 0.0)
            sk = max(float(res.x[4]), 0.0) if kin_soft else 0.0
            return TransitionPoint(res.x[:3].copy(), s, s <= TOL.slack and sk <= TOL.slack, sk)
    return TransitionPoint(np.asarray(c_prev, dtype=np.float64).copy(), np.inf, False, np.inf)


def transition_qp_generators(
    phase: ContactPhase,
    kinematic: Halfspaces,
    c_prev: FloatArray,
    *,
    w: float = 1000.0,
) -> TransitionPoint:
    """Equality form (Eq. 13): min ||c - c_prev||^2 + w s^2, G beta = D c + d, beta + s >= 0.

    beta are generator weights scaled by the weight m g (dimensionless); slack in the same unit.
    """
    G = phase.wrench_generators
    m = G.shape[0]
    if m == 0:
        return TransitionPoint(np.asarray(c_prev, dtype=np.float64).copy(), np.inf, False)
    # G beta (scaled by weight) = [e_z ; c x e_z]; c x e_z = (c_y, -c_x, 0) = Dc
    D = np.zeros((6, 3))
    D[3, 1] = 1.0
    D[4, 0] = -1.0
    d = gravity_wrench(1.0 / 9.81, np.zeros(3))[0]
    n = 3 + m + 1
    H = np.zeros((n, n))
    H[:3, :3] = 2.0 * np.eye(3)
    H[3 : 3 + m, 3 : 3 + m] = 1e-6 * np.eye(m)
    H[-1, -1] = 2.0 * w
    f = np.zeros(n)
    f[:3] = -2.0 * c_prev
    f[-1] = w
    m_k = kinematic.A.shape[0]
    A = np.zeros((7 + m + m_k, n))
    A[-1, -1] = 1.0  # s >= 0
    A[:6, :3] = -D
    A[:6, 3 : 3 + m] = G.T
    A[6 : 6 + m, 3 : 3 + m] = np.eye(m)
    A[6 : 6 + m, -1] = 1.0
    A[6 + m : 6 + m + m_k, :3] = kinematic.A
    upper = np.concatenate([d, np.full(m, _solvers.INF), kinematic.b, [_solvers.INF]])
    lower = np.concatenate([d, np.zeros(m), np.full(m_k, -_solvers.INF), [0.0]])
    eq = np.zeros(upper.shape[0], dtype=bool)
    eq[:6] = True
    res = _solvers.solve(H, f, A, upper, lower, eq)
    if not res.ok:
        return TransitionPoint(np.asarray(c_prev, dtype=np.float64).copy(), np.inf, False)
    s = max(float(res.x[-1]), 0.0)
    return TransitionPoint(res.x[:3].copy(), s, s <= TOL.slack)


def transition_point(
    eq_prev: Halfspaces,
    eq_next: Halfspaces,
    c_prev: FloatArray,
    *,
    kin_prev: Halfspaces | None = None,
    kin_next: Halfspaces | None = None,
    w: float = 1000.0,
    cost: TransitionCost | None = None,
    target: FloatArray | None = None,
) -> TransitionPoint:
    """Transition COM between two phases given their equilibrium and kinematic polytopes.

    Stacks both phases' constraints, which reduces to Eq. 6 when one contact set contains
    the other. c_prev (3,) is c(j), the previous COM; target (3,) the next one if known.
    """
    c0 = _vec3(c_prev, "c_prev")
    tgt = None if target is None else _vec3(target, "target")
    if w <= 0 or not np.isfinite(w):
        raise ValueError(f"w: must be positive and finite, got {w}")
    kins = [k for k in (kin_prev, kin_next) if k is not None]
    return transition_qp(stack([eq_prev, eq_next]), stack(kins), c0, w=w, cost=cost, target=tgt)


def check_transition_point(
    point: FloatArray,
    equilibria: Sequence[Halfspaces],
    kinematics: Sequence[Halfspaces] = (),
) -> TransitionPoint:
    """Feasibility of a user-placed transition point: its slacks against both constraint sets."""
    p = _vec3(point, "point")
    s_eq = max([0.0, *(float(e.violation(p)) for e in equilibria)])
    s_k = max([0.0, *(float(k.violation(p)) for k in kinematics)])
    return TransitionPoint(p, s_eq, s_eq <= TOL.slack and s_k <= TOL.slack, s_k)


def _vec3(value: FloatArray, name: str) -> FloatArray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"{name}: expected a finite (3,) array, got shape {arr.shape}")
    return arr
