"""The scene kit: a renderer-agnostic description of a scene (plain dataclasses, no bpy).

A scene family (a file in ``scenes/``) is a function ``build(params, seed) -> SceneSpec``.  A backend
translates the spec: ``harness.render.cycles`` renders it with Cycles, ``harness.render.raycast`` ray-casts its boxes
analytically in numpy.  The spec knows nothing of either (the kubric pattern).

Units: metres, radians, linear RGB in [0, 1], watts.  World is right-handed, Z up, floor at z = 0.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from reconstruction.camera.rig import Rig

MATERIAL_KINDS = ("paint", "wood", "tiles", "board", "fabric", "metal", "plastic", "glass", "emission", "noise")


@dataclass(frozen=True)
class Material:
    """Surface appearance.

    Attributes:
        name: unique key within the scene.
        kind: one of ``MATERIAL_KINDS``; selects the procedural texture a backend builds.
        color: base colour, linear RGB in [0, 1].
        color2: secondary colour (wood's dark grain, tile grout, ...), linear RGB; defaults to a darker ``color``.
        scale: size of the texture's main feature, metres (tile size, grain spacing, noise blob size).
        contrast: texture amplitude in [0, 1]; 0 gives a uniform, texture-less surface.
        roughness: specular roughness in [0, 1] (1 = matte).
        emission: emission strength (Blender units, W/m^2-like) for ``kind == "emission"``.
    """

    name: str
    kind: str = "paint"
    color: tuple[float, float, float] = (0.8, 0.8, 0.8)
    color2: tuple[float, float, float] | None = None
    scale: float = 0.5
    contrast: float = 0.2
    roughness: float = 0.6
    emission: float = 0.0

    def __post_init__(self):
        if self.kind not in MATERIAL_KINDS:
            raise ValueError(f"material {self.name!r}: unknown kind {self.kind!r} (known: {MATERIAL_KINDS})")

    @property
    def secondary(self) -> tuple[float, float, float]:
        return self.color2 if self.color2 is not None else tuple(0.55 * c for c in self.color)


@dataclass(frozen=True)
class Box:
    """An oriented box.

    Attributes:
        center: (x, y, z) centre, metres.
        size: (sx, sy, sz) full extents along the box's own axes, metres.
        material: key into ``SceneSpec.materials``.
        yaw: rotation about +Z, radians.
        name: optional object name (shows in Blender).
        inward: True for a room shell seen from inside (normals point inwards).
    """

    center: tuple[float, float, float]
    size: tuple[float, float, float]
    material: str
    yaw: float = 0.0
    name: str = ""
    inward: bool = False

    def contains(self, points: np.ndarray, margin=0.0) -> np.ndarray:
        """Boolean (N,) mask of points (N, 3) inside the box grown by ``margin`` metres on every side
        (a scalar, or (3,) per box axis)."""
        c, s = np.cos(-self.yaw), np.sin(-self.yaw)
        rel = np.asarray(points, dtype=np.float64) - np.asarray(self.center)
        local = np.stack([c * rel[:, 0] - s * rel[:, 1], s * rel[:, 0] + c * rel[:, 1], rel[:, 2]], axis=1)
        half = np.asarray(self.size) / 2.0 + margin
        return np.all(np.abs(local) <= half, axis=1)


@dataclass(frozen=True)
class Light:
    """A light source.

    Attributes:
        kind: "area" (rectangle facing -Z), "point" or "sun".
        position: (x, y, z), metres (direction is straight down for "sun").
        size: (sx, sy) of an area light, metres.
        power: watts (strength in W/m^2 for "sun").
        color: linear RGB.
    """

    kind: str
    position: tuple[float, float, float]
    size: tuple[float, float] = (0.6, 0.6)
    power: float = 100.0
    color: tuple[float, float, float] = (1.0, 1.0, 1.0)


@dataclass(frozen=True)
class ModelFile:
    """An external model (``.blend``, ``.glb``/``.gltf`` or ``.obj``) placed in the scene (Blender only)."""

    path: Path
    location: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rotation_euler: tuple[float, float, float] = (0.0, 0.0, 0.0)
    scale: float = 1.0


@dataclass
class SceneSpec:
    """Everything a backend needs to build a scene.

    Attributes:
        name: scene family name.
        params: the parameters it was built from (recorded in frame provenance).
        materials: by name.
        boxes: geometry; the room shell (``inward=True``) included.
        lights: light sources.
        models: external model files (Blender backend only).
        bounds: ((xmin, ymin, zmin), (xmax, ymax, zmax)) of the free interior, metres; viewpoints are drawn here.
        rig_height: (low, high) range of camera C's height above the floor, metres.
        viewpoints: explicit rigs; if given, ``choose_viewpoints`` uses these instead of sampling.
        background: world colour seen by rays that leave the scene, linear RGB.
    """

    name: str
    params: dict = field(default_factory=dict)
    materials: dict[str, Material] = field(default_factory=dict)
    boxes: list[Box] = field(default_factory=list)
    lights: list[Light] = field(default_factory=list)
    models: list[ModelFile] = field(default_factory=list)
    bounds: tuple[tuple[float, float, float], tuple[float, float, float]] = ((-2, -2, 0), (2, 2, 3))
    rig_height: tuple[float, float] = (1.1, 1.5)
    viewpoints: list[Rig] = field(default_factory=list)
    background: tuple[float, float, float] = (0.05, 0.05, 0.05)

    def add_material(self, material: Material) -> str:
        self.materials[material.name] = material
        return material.name

    def validate(self) -> None:
        """Raise ValueError if a box names an unknown material or sizes are not positive."""
        for box in self.boxes:
            if box.material not in self.materials:
                raise ValueError(f"scene {self.name!r}: box {box.name or box.center} uses unknown material "
                                 f"{box.material!r}")
            if min(box.size) <= 0:
                raise ValueError(f"scene {self.name!r}: box {box.name or box.center} has size {box.size}")


def choose_viewpoints(spec: SceneSpec, n: int, seed: int, baseline_m: float = 0.4,
                      clearance_m: float = 0.3, floor_clearance_m: float = 0.35,
                      max_tries: int = 20000) -> list[Rig]:
    """Pick ``n`` rig placements deterministically from ``seed``, never inside or too near furniture.

    Viewpoint 0 is the free position closest to the centre of ``spec.bounds`` (a stable default); the
    others are drawn uniformly in the bounds (rig yaw uniform) until every camera centre is at least
    ``clearance_m`` from every solid box and from the room shell, and the rig stands on free floor: the
    vertical column below each camera is at least ``floor_clearance_m`` (horizontally) from every solid
    box, as for a tripod or robot standing in an aisle.  (A rig hovering over a desk sees the floor under
    it from C but not from R 0.4 m away: measured on classroom frames, such placements leave only 88 % of
    C's pixels visible from R; in aisles 95 %+.)

    Raises:
        ValueError: if fewer than ``n`` free placements are found.
    """
    if spec.viewpoints:
        if len(spec.viewpoints) < n:
            raise ValueError(f"scene {spec.name!r} defines {len(spec.viewpoints)} viewpoints, {n} requested")
        return list(spec.viewpoints[:n])
    rng = np.random.default_rng(seed)
    lo, hi = np.asarray(spec.bounds[0], float), np.asarray(spec.bounds[1], float)
    solids = [b for b in spec.boxes if not b.inward]

    def free(rig: Rig) -> bool:
        pts = np.array([p.position for p in rig.poses().values()])
        inner_lo, inner_hi = lo + clearance_m, hi - clearance_m
        if np.any(pts < inner_lo) or np.any(pts > inner_hi):
            return False
        if any(b.contains(pts, clearance_m).any() for b in solids):
            return False
        # columns under the cameras, every 0.1 m from the floor up to the camera
        heights = np.arange(0.05, pts[:, 2].max(), 0.1)
        column = np.concatenate([np.column_stack([np.full(heights.size, p[0]), np.full(heights.size, p[1]),
                                                  np.minimum(heights, p[2])]) for p in pts])
        horizontal = np.array([floor_clearance_m, floor_clearance_m, 0.0])
        return not any(b.contains(column, horizontal).any() for b in solids)

    rigs: list[Rig] = []
    centre = (lo + hi) / 2.0
    h_mid = float(np.mean(spec.rig_height))
    # viewpoint 0: nearest free spot to the room centre, on a fixed spiral (deterministic, seed-independent)
    for k in range(2000):
        r, a = 0.05 * k ** 0.5 * 3, 2.39996 * k
        cand = Rig(position=np.array([centre[0] + r * np.cos(a), centre[1] + r * np.sin(a), h_mid]),
                   yaw_rad=0.0, baseline_m=baseline_m)
        if free(cand):
            rigs.append(cand)
            break
    for _ in range(max_tries):
        if len(rigs) >= n:
            break
        pos = rng.uniform(lo, hi)
        pos[2] = rng.uniform(*spec.rig_height)
        cand = Rig(position=pos, yaw_rad=float(rng.uniform(-np.pi, np.pi)), baseline_m=baseline_m)
        if free(cand):
            rigs.append(cand)
    if len(rigs) < n:
        raise ValueError(f"scene {spec.name!r}: found only {len(rigs)} free rig placements of {n} requested")
    return rigs[:n]
