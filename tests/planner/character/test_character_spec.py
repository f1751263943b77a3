"""Limb spec validation: every error names the offending field."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import pytest
import yaml

from planner.character import SpecError, character_spec_path, load_character, parse_spec


def _doc() -> dict[str, Any]:
    data = yaml.safe_load(character_spec_path("quadruped").read_text())
    assert isinstance(data, dict)
    return data


def test_builtin_specs_parse() -> None:
    spec = parse_spec(_doc())
    assert spec.id == "quadruped"
    assert len(spec.limbs) == 4
    assert spec.limbs[0].contact == "point"
    assert spec.max_pitch == pytest.approx(0.05)  # level unless the spec says otherwise


@pytest.mark.parametrize(
    ("edit", "field"),
    [
        (lambda d: d.pop("id"), "id"),
        (lambda d: d.pop("urdf"), "urdf"),
        (lambda d: d.__setitem__("trunk", []), "trunk"),
        (lambda d: d["trunk"][0].__setitem__("type", "cone"), "trunk[0].type"),
        (lambda d: d["trunk"][0].__setitem__("half_extents", [1, 2]), "trunk[0].half_extents"),
        (
            lambda d: d["trunk"][0].__setitem__("half_extents", [1, -2, 1]),
            "trunk[0].half_extents[1]",
        ),
        (lambda d: d.__setitem__("limbs", []), "limbs"),
        (lambda d: d["limbs"][1].pop("root_joint"), "limbs[1].root_joint"),
        (lambda d: d["limbs"][2].__setitem__("contact", "grip"), "limbs[2].contact"),
        (lambda d: d["limbs"][0].__setitem__("contact", "patch"), "limbs[0].half_size"),
        (lambda d: d["limbs"][0].__setitem__("normal", [0, 0, 0]), "limbs[0].normal"),
        (lambda d: d["limbs"][0].__setitem__("mu", -1), "limbs[0].mu"),
        (lambda d: d["limbs"][0].__setitem__("offset", "up"), "limbs[0].offset"),
        (lambda d: d["limbs"][3].__setitem__("name", "lf_foot"), "limbs[3].name"),
        (
            lambda d: d["reference_posture"].__setitem__("lf_kfe", "bent"),
            "reference_posture.lf_kfe",
        ),
        (lambda d: d.__setitem__("self_collision", {"mode": "voxels"}), "self_collision.mode"),
        (lambda d: d.__setitem__("root_height", 0), "root_height"),
        (lambda d: d.__setitem__("max_pitch", 1.2), "max_pitch"),
        (lambda d: d.__setitem__("max_pitch", -0.1), "max_pitch"),
    ],
)
def test_parse_errors_name_the_field(edit: Any, field: str) -> None:
    doc = copy.deepcopy(_doc())
    edit(doc)
    with pytest.raises(SpecError) as info:
        parse_spec(doc)
    assert info.value.field == field
    assert str(info.value).startswith(field + ":")


def _write(tmp_path: Path, edit: Any) -> Path:
    src = character_spec_path("quadruped")
    (tmp_path / "quadruped.urdf").write_text(src.with_name("quadruped.urdf").read_text())
    doc = _doc()
    edit(doc)
    path = tmp_path / "spec.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


@pytest.mark.parametrize(
    ("edit", "field"),
    [
        (lambda d: d["limbs"][0].__setitem__("root_joint", "nope"), "limbs[0].root_joint"),
        (lambda d: d["limbs"][0].__setitem__("effector_frame", "nope"), "limbs[0].effector_frame"),
        (lambda d: d["limbs"][0].__setitem__("root_joint", "rh_haa"), "limbs[0].root_joint"),
        (lambda d: d["reference_posture"].__setitem__("tail", 0.1), "reference_posture.tail"),
        (lambda d: d["reference_posture"].__setitem__("lf_kfe", 3.0), "reference_posture.lf_kfe"),
        (lambda d: d.__setitem__("urdf", "missing.urdf"), "urdf"),
        (
            lambda d: d["limbs"][0].__setitem__("posture_weights", {"rh_kfe": 1.0}),
            "limbs[0].posture_weights.rh_kfe",
        ),
    ],
)
def test_load_errors_name_the_field(tmp_path: Path, edit: Any, field: str) -> None:
    path = _write(tmp_path, edit)
    with pytest.raises(SpecError) as info:
        load_character(path)
    assert info.value.field == field


def test_copied_spec_loads(tmp_path: Path) -> None:
    character = load_character(_write(tmp_path, lambda d: None))
    assert character.id == "quadruped"
    assert character.n_joints == 12


def test_invalid_yaml(tmp_path: Path) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text("id: [unclosed\n")
    with pytest.raises(SpecError):
        load_character(path)
