"""Limb spec files (YAML or JSON): parsing and validation.

The format is documented in ``planner/character/README.md``. Every error is a
:class:`SpecError` whose message starts with the dotted path of the offending field, e.g.
``limbs[1].half_size: expected 2 numbers``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

CONTACT_KINDS = ("point", "patch")
SELF_COLLISION_MODES = ("urdf", "capsules")


MAX_PITCH = 0.8  # rad, the largest trunk pitch a spec may allow


class SpecError(ValueError):
    """Invalid limb spec; ``field`` names the offending field (dotted path)."""

    def __init__(self, field: str, message: str) -> None:
        super().__init__(f"{field}: {message}")
        self.field = field


@dataclass(frozen=True, slots=True)
class TrunkShapeSpec:
    """One shape of the trunk W0 in the root frame: ``box`` (half_extents) or ``capsule``
    (radius, half_length along local z); pose ``position`` (3,) m and ``rpy`` (3,) rad."""

    kind: str
    half_extents: tuple[float, float, float] | None
    radius: float | None
    half_length: float | None
    position: tuple[float, float, float]
    rpy: tuple[float, float, float]


@dataclass(frozen=True, slots=True)
class LimbSpec:
    """One limb as written in the spec (names only; resolved against the model later)."""

    name: str
    root_joint: str
    effector_frame: str
    contact: str
    half_size: tuple[float, float]
    normal: tuple[float, float, float]
    offset: tuple[float, float, float]
    mu: float
    posture_weights: tuple[tuple[str, float], ...]
    on_request: bool = False


@dataclass(frozen=True, slots=True)
class CharacterSpec:
    """A parsed limb spec. ``urdf`` is the raw reference (relative path or ``package:...``)."""

    id: str
    urdf: str
    trunk: tuple[TrunkShapeSpec, ...]
    root_height: float | None
    reference_posture: tuple[tuple[str, float], ...]
    limbs: tuple[LimbSpec, ...]
    self_collision_mode: str
    self_collision_radius: float
    max_pitch: float = 0.05


def _require(mapping: dict[str, Any], key: str, where: str) -> Any:
    if key not in mapping:
        raise SpecError(f"{where}{key}", "missing required field")
    return mapping[key]


def _str(value: Any, field: str) -> str:
    if not isinstance(value, str) or not value:
        raise SpecError(field, f"expected a non-empty string, got {value!r}")
    return value


def _num(value: Any, field: str, positive: bool = False, nonneg: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise SpecError(field, f"expected a finite number, got {value!r}")
    if positive and value <= 0:
        raise SpecError(field, f"must be > 0, got {value!r}")
    if nonneg and value < 0:
        raise SpecError(field, f"must be >= 0, got {value!r}")
    return float(value)


def _vec(value: Any, n: int, field: str, positive: bool = False) -> tuple[float, ...]:
    if not isinstance(value, list | tuple) or len(value) != n:
        raise SpecError(field, f"expected {n} numbers, got {value!r}")
    return tuple(_num(v, f"{field}[{i}]", positive=positive) for i, v in enumerate(value))


def _vec3(value: Any, field: str, positive: bool = False) -> tuple[float, float, float]:
    x, y, z = _vec(value, 3, field, positive)
    return (x, y, z)


def _mapping(value: Any, field: str) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise SpecError(field, f"expected a mapping, got {type(value).__name__}")
    return value


def _trunk(value: Any) -> tuple[TrunkShapeSpec, ...]:
    if not isinstance(value, list) or not value:
        raise SpecError("trunk", "expected a non-empty list of boxes/capsules")
    out = []
    for i, raw in enumerate(value):
        where = f"trunk[{i}]"
        item = _mapping(raw, where)
        kind = _str(_require(item, "type", f"{where}."), f"{where}.type")
        position = _vec3(item.get("position", [0.0, 0.0, 0.0]), f"{where}.position")
        rpy = _vec3(item.get("rpy", [0.0, 0.0, 0.0]), f"{where}.rpy")
        if kind == "box":
            he = _vec3(_require(item, "half_extents", f"{where}."), f"{where}.half_extents", True)
            out.append(TrunkShapeSpec("box", he, None, None, position, rpy))
        elif kind == "capsule":
            radius = _num(_require(item, "radius", f"{where}."), f"{where}.radius", positive=True)
            half = _num(
                _require(item, "half_length", f"{where}."), f"{where}.half_length", nonneg=True
            )
            out.append(TrunkShapeSpec("capsule", None, radius, half, position, rpy))
        else:
            raise SpecError(f"{where}.type", f"expected 'box' or 'capsule', got {kind!r}")
    return tuple(out)


def _weights(value: Any, field: str, nonneg: bool = True) -> tuple[tuple[str, float], ...]:
    if value is None:
        return ()
    mapping = _mapping(value, field)
    return tuple(
        (_str(k, field), _num(v, f"{field}.{k}", nonneg=nonneg)) for k, v in mapping.items()
    )


def _flag(value: Any, where: str) -> bool:
    if not isinstance(value, bool):
        raise SpecError(where, f"expected true or false, got {value!r}")
    return value


def _limb(raw: Any, i: int) -> LimbSpec:
    where = f"limbs[{i}]"
    item = _mapping(raw, where)
    name = _str(_require(item, "name", f"{where}."), f"{where}.name")
    contact = _str(_require(item, "contact", f"{where}."), f"{where}.contact")
    if contact not in CONTACT_KINDS:
        raise SpecError(f"{where}.contact", f"expected 'point' or 'patch', got {contact!r}")
    if contact == "patch":
        hx, hy = _vec(_require(item, "half_size", f"{where}."), 2, f"{where}.half_size", True)
    else:
        hx, hy = _vec(item.get("half_size", [0.0, 0.0]), 2, f"{where}.half_size")
    normal = _vec3(_require(item, "normal", f"{where}."), f"{where}.normal")
    norm = math.sqrt(sum(v * v for v in normal))
    if norm < 1e-9:
        raise SpecError(f"{where}.normal", "must be a non-zero vector")
    unit = (normal[0] / norm, normal[1] / norm, normal[2] / norm)
    mu = _num(item.get("mu", 0.5), f"{where}.mu", positive=True)
    return LimbSpec(
        name=name,
        root_joint=_str(_require(item, "root_joint", f"{where}."), f"{where}.root_joint"),
        effector_frame=_str(
            _require(item, "effector_frame", f"{where}."), f"{where}.effector_frame"
        ),
        contact=contact,
        half_size=(hx, hy),
        normal=unit,
        offset=_vec3(item.get("offset", [0.0, 0.0, 0.0]), f"{where}.offset"),
        mu=mu,
        posture_weights=_weights(item.get("posture_weights"), f"{where}.posture_weights"),
        on_request=_flag(item.get("on_request", False), f"{where}.on_request"),
    )


def parse_spec(data: Any) -> CharacterSpec:
    """Validate a decoded spec document (mapping) and return a :class:`CharacterSpec`.

    Raises SpecError naming the field on any problem.
    """
    doc = _mapping(data, "<spec>")
    cid = _str(_require(doc, "id", ""), "id")
    urdf = _str(_require(doc, "urdf", ""), "urdf")
    trunk = _trunk(_require(doc, "trunk", ""))
    root_height = doc.get("root_height")
    height = None if root_height is None else _num(root_height, "root_height", positive=True)
    posture = _weights(doc.get("reference_posture"), "reference_posture", nonneg=False)
    limbs_raw = _require(doc, "limbs", "")
    if not isinstance(limbs_raw, list) or not limbs_raw:
        raise SpecError("limbs", "expected a non-empty list of limbs")
    limbs = tuple(_limb(raw, i) for i, raw in enumerate(limbs_raw))
    names = [limb.name for limb in limbs]
    for i, name in enumerate(names):
        if name in names[:i]:
            raise SpecError(f"limbs[{i}].name", f"duplicate limb name {name!r}")
    sc = _mapping(doc.get("self_collision", {}), "self_collision")
    mode = _str(sc.get("mode", "urdf"), "self_collision.mode")
    if mode not in SELF_COLLISION_MODES:
        raise SpecError("self_collision.mode", f"expected 'urdf' or 'capsules', got {mode!r}")
    radius = _num(sc.get("radius", 0.04), "self_collision.radius", positive=True)
    max_pitch = _num(doc.get("max_pitch", 0.05), "max_pitch", nonneg=True)
    if max_pitch > MAX_PITCH:
        raise SpecError("max_pitch", f"must be at most {MAX_PITCH} rad, got {max_pitch}")
    return CharacterSpec(cid, urdf, trunk, height, posture, limbs, mode, radius, max_pitch)


def read_spec(path: str | Path) -> tuple[CharacterSpec, str]:
    """Read and validate a spec file (YAML or JSON); returns the spec and its raw text."""
    text = Path(path).read_text()
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise SpecError("<spec>", f"not valid YAML/JSON: {exc}") from exc
    return parse_spec(data), text
