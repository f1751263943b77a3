"""Characters: URDF + limb spec loaded with Pinocchio (see ``planner/character/README.md``)."""

from planner.character.model import (
    Character,
    Limb,
    builtin_character_ids,
    character_spec_path,
    get_character,
    load_character,
    real_robot_ids,
)
from planner.character.spec import (
    MAX_PITCH,
    CharacterSpec,
    LimbSpec,
    SpecError,
    parse_spec,
    read_spec,
)

__all__ = [
    "MAX_PITCH",
    "Character",
    "CharacterSpec",
    "Limb",
    "LimbSpec",
    "SpecError",
    "builtin_character_ids",
    "character_spec_path",
    "get_character",
    "load_character",
    "parse_spec",
    "read_spec",
    "real_robot_ids",
]
