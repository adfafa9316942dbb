"""``synthetic_box``: a textured box room with furniture-like boxes, rendered by the numpy ray-caster.

Ground truth is exact (analytic ray-box intersection, ``harness.render.raycast``), and no Blender is needed, so
this scene is what fast tests and quick experiments use.

The room is an inward shell (walls and ceiling: strong multi-scale noise), a tiled floor slab, a
texture-less board on the +X wall (a deliberately weak-texture region: flow has nothing to lock on to
there), and 3-6 solid boxes (table, cabinet, cube, bench, shelf, pillar) standing on the floor near the
walls, leaving the middle of the room free for the rig.  ``seed`` jitters box positions, sizes and yaws.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from reconstruction.camera.rig import yaw_rotation
from scenes.model import Box, Light, Material, SceneEntry, SceneParams, SceneSpec, param

# name -> (fractional centre (fx, fy) of the room half extents, size (sx, sy, sz) m, material, yaw rad)
FURNITURE = {
    "table": ((0.45, -0.45), (1.2, 0.8, 0.75), "wood", 0.0),
    "cabinet": ((-0.78, 0.72), (0.9, 0.45, 2.0), "cabinet", 0.0),
    "cube": ((-0.40, -0.55), (0.45, 0.45, 0.45), "cube", 0.35),
    "bench": ((0.15, 0.78), (1.4, 0.4, 0.45), "fabric", 0.0),
    "shelf": ((-0.85, -0.10), (0.35, 1.2, 1.4), "shelf", 0.0),
    "pillar": ((0.75, 0.30), (0.3, 0.3, 1.1), "cube", 0.6),
}


def _materials(weak_contrast: float) -> list[Material]:
    return [
        Material("walls", kind="noise", color=(0.75, 0.70, 0.62), color2=(0.45, 0.50, 0.55), scale=0.35,
                 contrast=0.55),
        Material("floor", kind="tiles", color=(0.55, 0.47, 0.38), color2=(0.12, 0.12, 0.12), scale=0.5,
                 contrast=0.5),
        Material("board", kind="board", color=(0.08, 0.12, 0.10), scale=0.5, contrast=weak_contrast),
        Material("wood", kind="wood", color=(0.50, 0.32, 0.17), color2=(0.22, 0.12, 0.05), scale=0.035,
                 contrast=0.7),
        Material("cabinet", kind="paint", color=(0.35, 0.45, 0.55), scale=0.12, contrast=0.45),
        Material("cube", kind="noise", color=(0.70, 0.25, 0.15), color2=(0.95, 0.85, 0.30), scale=0.08,
                 contrast=0.8),
        Material("fabric", kind="fabric", color=(0.20, 0.45, 0.25), scale=0.05, contrast=0.5),
        Material("shelf", kind="wood", color=(0.62, 0.50, 0.36), color2=(0.35, 0.25, 0.15), scale=0.05,
                 contrast=0.6),
    ]


@dataclass(frozen=True)
class SyntheticBoxParams(SceneParams):
    """The synthetic box room's parameters (``tri360 scenes --params``)."""

    room: tuple[float, float, float] = param((6.0, 5.0, 3.0), "(sx, sy, sz) interior size; floor at z = 0, "
                                             "centred on x = y = 0", unit="m", limits=(1.0, 100.0))
    furniture: tuple[str, ...] = param(("table", "cabinet", "cube", "bench"), "furniture boxes, in order",
                                       choices=sorted(FURNITURE))
    jitter_m: float = param(0.2, "max position jitter of each furniture box", unit="m", limits=(0.0, 10.0))
    size_jitter: float = param(0.15, "max relative size jitter of each furniture box, 0.15 = +-15 %",
                               limits=(0.0, 0.9))
    weak_contrast: float = param(0.0, "texture contrast of the board on the +X wall, 0 = texture-less",
                                 limits=(0.0, 1.0))
    light_power: float = param(80.0, "power of the ceiling area light; the point light gets half", unit="W",
                               limits=(0.0, None))


def build(p: SyntheticBoxParams, seed: int) -> SceneSpec:
    """Build the room."""
    sx, sy, sz = p.room
    jitter, size_jitter, power = p.jitter_m, p.size_jitter, p.light_power
    rng = np.random.default_rng(seed)
    hx, hy = sx / 2.0, sy / 2.0

    spec = SceneSpec(name="synthetic_box", bounds=((-hx, -hy, 0.0), (hx, hy, sz)), rig_height=(1.1, 1.5))
    for m in _materials(p.weak_contrast):
        spec.add_material(m)
    spec.boxes.append(Box(center=(0.0, 0.0, sz / 2.0), size=(sx, sy, sz), material="walls", name="room",
                          inward=True))
    # floor slab: top face 2 mm above the shell's floor (no coincident faces), reaching into the walls
    spec.boxes.append(Box(center=(0.0, 0.0, -0.009), size=(sx + 0.2, sy + 0.2, 0.022), material="floor",
                          name="floor"))
    # weak-texture board on the +X wall, 5 mm proud of it
    spec.boxes.append(Box(center=(hx - 0.015, 0.35 * hy, 1.45), size=(0.02, min(1.8, 0.6 * sy), 1.0),
                          material="board", name="board"))
    for name in p.furniture:
        (fx, fy), size, material, yaw = FURNITURE[name]
        size = np.asarray(size) * rng.uniform(1 - size_jitter, 1 + size_jitter, 3)
        size[2] = min(size[2], sz - 0.3)
        yaw = yaw + rng.uniform(-0.15, 0.15)
        foot = np.abs(yaw_rotation(yaw)[:2, :2]) @ size[:2] / 2.0  # footprint half extents (x, y)
        xy = np.array([fx * hx, fy * hy]) + rng.uniform(-jitter, jitter, 2)
        lim = np.array([hx, hy]) - foot - 0.02
        xy = np.clip(xy, -lim, lim)
        spec.boxes.append(Box(center=(float(xy[0]), float(xy[1]), 0.002 + size[2] / 2.0),
                              size=tuple(float(v) for v in size), material=material, yaw=float(yaw), name=name))
    spec.lights.append(Light("area", position=(0.3, -0.2, sz - 0.02), size=(1.2, 0.6), power=power))
    spec.lights.append(Light("point", position=(-0.4 * hx, 0.4 * hy, sz - 0.6), power=power / 2.0,
                             color=(1.0, 0.92, 0.8)))
    return spec


# version: the scene code version frames and suite ids record; change it when what build() builds changes,
# and only then (tests/scenes/test_scene_fingerprints.py; scenes/README.md)
SCENES = [
    SceneEntry(
        name="synthetic_box", version="sha256:3c562a7126a06405",
        renderer="raycast",
        build=build,
        parameters=SyntheticBoxParams,
        presets={
            "default": {"room": (6.0, 5.0, 3.0), "furniture": ("table", "cabinet", "cube", "bench")},
            "small": {"room": (4.0, 3.5, 2.6), "furniture": ("table", "cabinet", "cube"), "light_power": 50.0},
            "cluttered": {"room": (6.0, 5.0, 3.0),
                          "furniture": ("table", "cabinet", "cube", "bench", "shelf", "pillar")},
        },
        description="textured box room with furniture boxes, exact ground truth by numpy ray-casting",
    )
]
