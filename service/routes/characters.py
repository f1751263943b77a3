"""Characters: list, details, URDF."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter
from fastapi.responses import Response

from service import convert
from service.deps import RegistryDep
from service.errors import not_found
from service.registry import CharacterEntry, Registry
from service.schemas import CharacterDetail, CharacterSummary, ErrorBody

router = APIRouter(prefix="/v1/characters", tags=["characters"])
_404: dict[int | str, dict[str, Any]] = {
    404: {"model": ErrorBody, "description": "unknown character"}
}


def _entry(registry: Registry, character_id: str) -> CharacterEntry:
    entry = registry.characters.get(character_id)
    if entry is None:
        raise not_found("character", character_id, "character_id")
    return entry


@router.get("")
async def list_characters(registry: RegistryDep) -> list[CharacterSummary]:
    """Every served character."""
    return [convert.character_summary(e.character) for e in registry.characters.values()]


@router.get("/{character_id}", responses=_404)
async def get_character(character_id: str, registry: RegistryDep) -> CharacterDetail:
    """Mass, joints in configuration order, reference standing configuration, limbs, trunk."""
    return convert.character_detail(_entry(registry, character_id).character)


@router.get("/{character_id}/urdf", responses={**_404, 200: {"content": {"application/xml": {}}}})
async def get_character_urdf(character_id: str, registry: RegistryDep) -> Response:
    """The character's URDF text (skeleton for game engines and viewers)."""
    return Response(
        _entry(registry, character_id).character.urdf_text, media_type="application/xml"
    )
