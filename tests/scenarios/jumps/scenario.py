"""Loading and running the jump scenarios (shared by the tests and ``bench/jumps.py``)."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from planner.ballistic.planner import JumpParams
from planner.ballistic.roadmap import RoadmapParams
from planner.character import Character, get_character
from planner.offline import OfflineData, load_offline_data
from planner.scene import Scene
from tests.paths import gecko_cache_dir
from tests.scenarios.jumps.scenes import load_scenario_scene

DIRECTORY = Path(__file__).resolve().parent


@dataclass(frozen=True)
class Scenario:
    """One scenario file: scene, character, start/goal (pose or stand_at), seed, params."""

    name: str
    spec: dict[str, Any]

    @property
    def seed(self) -> int:
        return int(self.spec["seed"])

    def end(self, which: str) -> np.ndarray:
        entry = self.spec[which]
        if "stand_at" in entry:
            return np.array(entry["stand_at"], dtype=np.float64)
        return np.array(entry["pose"], dtype=np.float64)

    def params(self) -> JumpParams:
        p = self.spec["params"]
        return JumpParams(
            roadmap=RoadmapParams(
                v0max=p["v0max"],
                vimpmax=p["vimpmax"],
                max_gap=p.get("max_gap", 0.1),
                neighbours=p.get("neighbours", 16),
                lazy=p.get("lazy", True),
            ),
            n_nodes=p["n_nodes"],
            min_limbs=p.get("min_limbs"),
        )

    def load(self) -> tuple[Scene, Character, OfflineData] | None:
        """Scene, character and offline data; None when the scene is not installed."""
        scene = load_scenario_scene(self.spec["scene"])
        if scene is None:
            return None
        character = get_character(self.spec["character"])
        data = load_offline_data(character, gecko_cache_dir())
        return scene, character, data


def scenarios() -> list[Scenario]:
    """Every ``*.json`` scenario of this directory, by name."""
    return [
        Scenario(path.stem, json.loads(path.read_text()))
        for path in sorted(DIRECTORY.glob("*.json"))
    ]
