"""An empty, textured, axis-aligned box room: the scene whose ground truth has a closed form.

From a camera at ``p`` inside the room ``[lo, hi]`` the ray along unit ``d`` leaves through the first wall
it meets: ``t = min_i ((hi_i - p_i) / d_i if d_i > 0 else (lo_i - p_i) / d_i)`` (see
:func:`box_interior_distance`).  The walls carry a strong noise texture so every pixel can be matched.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from scenes.model import Box, Light, Material, SceneEntry, SceneParams, SceneSpec, param


@dataclass(frozen=True)
class BoxRoomParams(SceneParams):
    """The box room's parameters (``tri360 scenes --params``)."""

    size: tuple[float, float, float] = param((6.0, 5.0, 3.0), "(sx, sy, sz) interior extents", unit="m",
                                             limits=(0.5, 100.0))
    contrast: float = param(0.9, "wall texture amplitude", limits=(0.0, 1.0))
    texture_scale: float = param(0.25, "wall texture feature size", unit="m", limits=(0.001, 10.0))
    light_power: float | None = param(None, "power of the ceiling area light (none: 5 W per m^2 of floor)",
                                      unit="W", limits=(0.0, None))
    fill_power: float = param(8.0, "power of the point light near the floor", unit="W", limits=(0.0, None))


def build(p: BoxRoomParams, seed: int) -> SceneSpec:
    """Room of ``p.size`` (x, y, z) metres, floor at z = 0, centred on x = y = 0."""
    sx, sy, sz = p.size
    spec = SceneSpec(name="box_room", bounds=((-sx / 2, -sy / 2, 0.0), (sx / 2, sy / 2, sz)),
                     rig_height=(1.0, min(1.5, sz - 0.8)))
    spec.add_material(Material("walls", kind="noise", color=(0.75, 0.55, 0.35), color2=(0.08, 0.12, 0.3),
                               scale=p.texture_scale, contrast=p.contrast, roughness=0.9))
    spec.boxes.append(Box(center=(0.0, 0.0, sz / 2), size=(sx, sy, sz), material="walls", name="shell",
                          inward=True))
    spec.lights.append(Light("area", position=(0.0, 0.0, sz - 0.05), size=(sx / 3, sy / 3),
                             power=5.0 * sx * sy if p.light_power is None else p.light_power))
    spec.lights.append(Light("point", position=(0.0, 0.0, 0.3), power=p.fill_power))
    return spec


def box_interior_distance(origin, directions, lo, hi) -> np.ndarray:
    """Distance (metres) from ``origin`` (3,) inside the axis-aligned box ``[lo, hi]`` along unit
    ``directions`` (..., 3) to the box's inner surface."""
    d = np.asarray(directions, dtype=np.float64)
    o = np.asarray(origin, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        t_hi = (np.asarray(hi, float) - o) / d
        t_lo = (np.asarray(lo, float) - o) / d
    t = np.where(d > 0, t_hi, np.where(d < 0, t_lo, np.inf))
    return t.min(axis=-1)


# version: the scene code version frames and suite ids record; change it when what build() builds changes,
# and only then (tests/scenes/test_scene_fingerprints.py; scenes/README.md)
SCENES = [SceneEntry(
    name="box_room", version="sha256:2975156264d93e1c", build=build,
    description="empty textured box room; ground truth distance has a closed form",
    presets={"default": {}, "small": {"size": (3.0, 2.5, 2.4)}, "hall": {"size": (12.0, 9.0, 4.0)}},
    default_preset="default", parameters=BoxRoomParams, renderer="cycles")]
