"""Pydantic request and response models of the HTTP API (the only place pydantic is used)."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

Vector3 = tuple[float, float, float]
Quaternion = tuple[float, float, float, float]


class ErrorDetail(BaseModel):
    code: str
    message: str
    field: str | None = None


class ErrorBody(BaseModel):
    error: ErrorDetail


class Health(BaseModel):
    status: Literal["ok"] = "ok"
    version: str
    characters: int
    scenes: int


class RootPose(BaseModel):
    """Root placement: position in metres (world frame), orientation as [x, y, z, w]."""

    model_config = ConfigDict(frozen=True)

    position: Vector3
    orientation: Quaternion = (0.0, 0.0, 0.0, 1.0)


class Configuration(BaseModel):
    """A whole-body configuration: root pose plus joint values (radians or metres) by name."""

    root: RootPose
    joints: dict[str, float]


class LimbInfo(BaseModel):
    name: str
    root_joint: str
    effector_frame: str
    contact: Literal["point", "patch"]
    half_size: tuple[float, float] = Field(description="half-sizes of the contact patch, metres")
    normal: Vector3 = Field(description="contact normal in the effector frame")
    mu: float = Field(description="default friction coefficient")


class CharacterSummary(BaseModel):
    id: str
    mass: float
    joint_count: int
    limbs: list[str]


class CharacterDetail(BaseModel):
    id: str
    mass: float = Field(description="total mass, kg")
    joints: list[str] = Field(description="joint names in configuration order (root excluded)")
    reference_configuration: Configuration = Field(
        description="standing posture on flat ground at z = 0"
    )
    limbs: list[LimbInfo]
    trunk: list[dict[str, object]] = Field(description="trunk bounding shapes W0, root frame")


class SurfaceInfo(BaseModel):
    id: int
    kind: Literal["support", "lean"]
    normal: Vector3
    area: float = Field(description="square metres")
    centroid: Vector3
    polygons: list[list[Vector3]] = Field(description="boundary loops, world frame, metres")


class SceneSummary(BaseModel):
    id: str
    name: str
    builtin: bool
    triangle_count: int
    surface_count: int


class SceneDetail(BaseModel):
    id: str
    name: str
    builtin: bool
    bounds: tuple[Vector3, Vector3] = Field(description="axis-aligned bounds [min, max], metres")
    triangle_count: int
    surfaces: list[SurfaceInfo]
